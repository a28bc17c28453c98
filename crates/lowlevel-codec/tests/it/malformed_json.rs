//! Bad JSON documents for `codec encode` (issue 19, item 5): every golden document of `corpus/golden` (written by
//! the generator of Unitree's Python types, not by this crate), with one scalar replaced by a malformed value
//! (out-of-range integers, non-numbers, floats where integers belong, wrong shapes) or a span of its text cut out or
//! garbled, must parse into a value or fail with a typed `JsonError`, never panic; and a document that parses must
//! encode and decode back to the same value.
#![cfg(feature = "json")]
use lowlevel_codec::json::{document_from_json, value_to_json};
use lowlevel_codec::{cdr, Encoding};
use proptest::prelude::*;
use serde_json::Value;
use unitree_idl::{hg, MessageType};

fn golden() -> Vec<String> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../corpus/golden");
    let mut v: Vec<String> = std::fs::read_dir(&dir)
        .expect("golden folder")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.starts_with("hg_lowcmd") && n.ends_with(".json"))
        })
        .map(|p| std::fs::read_to_string(p).expect("golden document"))
        .collect();
    v.sort();
    assert!(!v.is_empty(), "golden hg LowCmd documents");
    v
}

/// Replaces the `k`-th scalar (in document order) with `replacement`.
fn replace_scalar(v: &mut Value, k: &mut usize, replacement: &Value) -> bool {
    match v {
        Value::Array(a) => a.iter_mut().any(|x| replace_scalar(x, k, replacement)),
        Value::Object(o) => o.iter_mut().any(|(_, x)| replace_scalar(x, k, replacement)),
        _ => {
            if *k == 0 {
                *v = replacement.clone();
                true
            } else {
                *k -= 1;
                false
            }
        }
    }
}

fn weird() -> Vec<Value> {
    ["256", "-1", "4294967296", "-2147483649", "1.5", "1e400", "-0", "null", "\"1\"", "[]", "{}", "true", "1e-320"]
        .iter()
        .map(|s| serde_json::from_str(s).unwrap_or(Value::Null))
        .collect()
}

fn judge(text: &str) -> Result<(), TestCaseError> {
    if let Ok(doc) = document_from_json::<hg::LowCmd_>(MessageType::HgLowCmd, text) {
        let bytes = cdr::encode(&doc.value, Encoding::UNITREE);
        let back = cdr::decode::<hg::LowCmd_>(&bytes).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(value_to_json(&back.value), value_to_json(&doc.value));
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn a_scalar_replaced(which in 0usize..64, k in 0usize..300, r in 0usize..13) {
        let docs = golden();
        let mut v: Value = serde_json::from_str(&docs[which % docs.len()]).expect("golden JSON");
        let mut k = k;
        replace_scalar(&mut v["value"], &mut k, &weird()[r % 13]);
        judge(&v.to_string())?;
    }

    #[test]
    fn a_span_cut_or_garbled(which in 0usize..64, at in 0.0f64..1.0, len in 0usize..60, insert in "[ -~]{0,8}") {
        let docs = golden();
        let d = &docs[which % docs.len()];
        let a = ((d.len() as f64) * at) as usize;
        let b = (a + len).min(d.len());
        judge(&format!("{}{insert}{}", &d[..a], &d[b..]))?;
    }
}
