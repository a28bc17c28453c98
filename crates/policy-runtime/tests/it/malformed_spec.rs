//! Bad policy specs (issue 19, item 5): the shipped spec files with one value replaced by something malformed, or a
//! span cut out or garbled, must parse into a spec that `check_robot` accepts or refuses with a typed error, or fail
//! to parse with a typed `SpecError`: never a panic. Loading the network is not part of this (its weights live in the
//! shared reference folder; `tests/it/spec.rs` covers a missing or wrong model file).
use policy_runtime::PolicySpec;
use proptest::prelude::*;
use robot_model::RobotModel;
use std::path::Path;

const WEIRD: [&str; 12] = ["nan", "inf", "-inf", "1e308", "-1", "0", "\"\"", "\"x\"", "[]", "[1.0]", "true", "{}"];

fn specs() -> Vec<String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots/h1_2/policies");
    let mut v: Vec<String> = std::fs::read_dir(&dir)
        .expect("policies folder")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| std::fs::read_to_string(p).expect("spec"))
        .collect();
    v.sort();
    assert!(v.len() >= 2, "both shipped specs");
    v
}

fn replace_value(text: &str, k: usize, v: &str) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let with_value: Vec<usize> = (0..lines.len()).filter(|&i| lines[i].contains(" = ")).collect();
    if with_value.is_empty() {
        return text.to_string();
    }
    let i = with_value[k % with_value.len()];
    let key = lines[i].split(" = ").next().unwrap_or_default();
    let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    out[i] = format!("{key} = {v}");
    out.join("\n")
}

fn splice(text: &str, at: f64, len: usize, insert: &str) -> String {
    let mut a = ((text.len() as f64) * at) as usize;
    while !text.is_char_boundary(a) {
        a -= 1;
    }
    let mut b = (a + len).min(text.len());
    while !text.is_char_boundary(b) {
        b += 1;
    }
    format!("{}{insert}{}", &text[..a], &text[b..])
}

fn judge(text: &str) {
    if let Ok(spec) = PolicySpec::from_toml_str(text, Path::new(".")) {
        let model = RobotModel::h1_2().expect("model");
        let _ = spec.check_robot(&model);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn a_spec_value_replaced(which in 0usize..2, k in 0usize..500, v in prop::sample::select(WEIRD.to_vec())) {
        let specs = specs();
        judge(&replace_value(&specs[which % specs.len()], k, v));
    }

    #[test]
    fn a_spec_span_cut_or_garbled(which in 0usize..2, at in 0.0f64..1.0, len in 0usize..120, insert in "[ -~]{0,12}") {
        let specs = specs();
        judge(&splice(&specs[which % specs.len()], at, len, &insert));
    }
}
