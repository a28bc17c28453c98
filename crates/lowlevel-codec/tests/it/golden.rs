//! Byte-for-byte agreement with bytes nobody on this project produced:
//! * `corpus/golden/`: Cyclone DDS's Python serializer (cyclonedds 11.0.1) on Unitree's own
//!   Python IDL classes, CRCs from Unitree's Python SDK (see corpus/golden/README.md);
//! * `corpus/golden/api/`: the same serializer on Unitree's Python RPC classes (`unitree_api`), with
//!   requests and responses as Unitree's Python RPC client and server code build them
//!   (see corpus/golden/api/NOTES.md);
//! * `corpus/captures/`: RTPS payloads captured on loopback while Unitree's Python SDK
//!   published, reassembled from DATA and DATA_FRAG submessages.
//!
//! For every case: decode(bytes) equals the recorded values, encode(values) equals the bytes,
//! and our CRC equals the SDK's.

use lowlevel_codec::{cdr, crc, json, Encoding, Endianness, Representation};
use serde_json::Value;
use std::path::{Path, PathBuf};
use unitree_idl::{with_message_type, IdlStruct, MessageType};

fn corpus(dir: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../corpus").join(dir)
}

/// Every `<case>.json` with a `<case>.cdr` beside it.
fn cases(dir: &str) -> Vec<(String, Value, Vec<u8>)> {
    let mut out = Vec::new();
    let mut entries: Vec<_> =
        std::fs::read_dir(corpus(dir)).expect("corpus dir").map(|e| e.expect("entry").path()).collect();
    entries.sort();
    for path in entries {
        if path.extension().and_then(|e| e.to_str()) != Some("json") {
            continue;
        }
        let cdr_path = path.with_extension("cdr");
        if !cdr_path.exists() {
            continue;
        }
        let doc: Value = serde_json::from_str(&std::fs::read_to_string(&path).expect("read json")).expect("json");
        let bytes = std::fs::read(&cdr_path).expect("read cdr");
        out.push((path.file_stem().expect("stem").to_string_lossy().into_owned(), doc, bytes));
    }
    out
}

/// Canonical bytes for comparing two values bit for bit (NaN payloads and -0.0 included).
fn canonical<T: IdlStruct>(value: &T) -> Vec<u8> {
    cdr::encode(value, Encoding::UNITREE)
}

fn check_case<T: IdlStruct>(name: &str, doc: &Value, bytes: &[u8]) -> Result<(), String> {
    let expected: T = json::value_from_json(&doc["value"]).map_err(|e| format!("{name}: recorded value: {e}"))?;
    let decoded = cdr::decode::<T>(bytes).map_err(|e| format!("{name}: decode: {e}"))?;
    if canonical(&decoded.value) != canonical(&expected) {
        return Err(format!("{name}: decoded value differs from the recorded one"));
    }
    let representation =
        doc["representation"].as_str().and_then(Representation::from_name).ok_or(format!("{name}: representation"))?;
    let endianness = doc["endianness"].as_str().and_then(Endianness::from_name).ok_or(format!("{name}: endianness"))?;
    let encoding = Encoding { representation, endianness };
    if decoded.encoding != encoding {
        return Err(format!("{name}: header says {:?}, document says {encoding:?}", decoded.encoding));
    }
    let encoded = cdr::encode(&expected, encoding);
    if encoded != bytes {
        let at = encoded.iter().zip(bytes).position(|(a, b)| a != b).unwrap_or(encoded.len().min(bytes.len()));
        return Err(format!(
            "{name}: encode differs at byte {at} (ours {} bytes, golden {})",
            encoded.len(),
            bytes.len()
        ));
    }
    let crc_ok = crc::check_any(&expected);
    let recorded = doc["crc_ok"].as_bool();
    if crc_ok != recorded {
        return Err(format!("{name}: crc_ok ours {crc_ok:?}, recorded {recorded:?}"));
    }
    Ok(())
}

fn run_dir(dir: &str, type_of: impl Fn(&str, &Value) -> Option<MessageType>) -> usize {
    let mut failures = Vec::new();
    let mut count = 0;
    for (name, doc, bytes) in cases(dir) {
        let Some(ty) = type_of(&name, &doc) else { continue };
        count += 1;
        if let Err(e) = with_message_type!(ty, T => check_case::<T>(&name, &doc, &bytes)) {
            failures.push(e);
        }
    }
    assert!(failures.is_empty(), "{} of {count} cases failed:\n{}", failures.len(), failures.join("\n"));
    count
}

fn doc_type(_: &str, doc: &Value) -> Option<MessageType> {
    doc["type"].as_str().map(|t| MessageType::from_name(t).expect("known type"))
}

#[test]
fn golden_corpus_from_cyclonedds_python() {
    let count = run_dir("golden", doc_type);
    // 21 types x 4 encodings at least: an empty directory must not pass.
    assert!(count >= 84, "only {count} golden cases found");
}

#[test]
fn golden_rpc_corpus_from_cyclonedds_python() {
    let count = run_dir("golden/api", doc_type);
    // 8 types x 3 profiles x 4 encodings, plus the SDK-built requests and responses.
    assert!(count >= 96 + 14 * 4, "only {count} golden RPC cases found");
}

#[test]
fn every_type_and_encoding_is_covered() {
    let mut seen = std::collections::BTreeSet::new();
    for (_, doc, _) in cases("golden").into_iter().chain(cases("golden/api")) {
        seen.insert((
            doc["type"].as_str().unwrap_or("").to_owned(),
            doc["representation"].to_string(),
            doc["endianness"].to_string(),
        ));
    }
    for ty in MessageType::ALL {
        for repr in ["\"xcdr1\"", "\"xcdr2\""] {
            for end in ["\"little\"", "\"big\""] {
                assert!(
                    seen.contains(&(ty.name().to_owned(), repr.to_owned(), end.to_owned())),
                    "no golden case for {ty} {repr} {end}"
                );
            }
        }
    }
}

#[test]
fn live_captures_from_unitree_python_sdk() {
    let count = run_dir("captures", doc_type);
    assert!(count >= 4, "only {count} captured samples found");
}

/// Unitree's CRC as recorded in the manifest equals ours, case by case.
#[test]
fn crc_equals_unitree_sdk() {
    let manifest: Value =
        serde_json::from_str(&std::fs::read_to_string(corpus("golden").join("manifest.json")).expect("manifest"))
            .expect("json");
    let mut checked = 0;
    for case in manifest["cases"].as_array().expect("cases") {
        let Some(sdk_crc) = case["crc"].as_u64() else { continue };
        let name = case["case"].as_str().expect("case name");
        let ty = MessageType::from_name(case["type"].as_str().expect("type")).expect("known type");
        let doc: Value =
            serde_json::from_str(&std::fs::read_to_string(corpus("golden").join(format!("{name}.json"))).expect("doc"))
                .expect("json");
        let ours = with_message_type!(ty, T => {
            let value: T = json::value_from_json(&doc["value"]).expect("value");
            crc::compute_any(&value)
        });
        assert_eq!(ours, Some(sdk_crc as u32), "{name}");
        checked += 1;
    }
    assert!(checked >= 16, "only {checked} CRC cases");
}
