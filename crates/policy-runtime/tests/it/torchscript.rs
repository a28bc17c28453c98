//! The TorchScript reader against the same weights exported by PyTorch as plain arrays: every array of the
//! reference `.npz` (written with PyTorch from the module's `state_dict()` and buffers) must come out of the
//! `.pt` archive with the same name, shape and bits, and the controller built from the `.pt` must match the
//! golden sequence as the `.npz` one does.

use policy_runtime::network::read_npz;
use policy_runtime::{Controller, PolicyController, PolicyKind, PolicySpec, RobotObservation};
use std::path::PathBuf;

fn shared() -> Option<PathBuf> {
    match std::env::var("ULAB_SHARED") {
        Ok(s) if !s.is_empty() => Some(PathBuf::from(s)),
        _ => {
            eprintln!("SKIP: ULAB_SHARED is not set; the reference policies live in $ULAB_SHARED/reference/policies/");
            None
        }
    }
}

#[test]
fn pt_tensors_equal_the_npz_arrays() {
    let Some(shared) = shared() else { return };
    let dir = shared.join("reference/policies");
    let pt = policy_runtime::torchscript::read_tensors(&dir.join("h1_2_unitree_rl_gym_lstm.pt")).expect("reads .pt");
    let npz = read_npz(&dir.join("h1_2_unitree_rl_gym_lstm.npz")).expect("reads .npz");
    assert_eq!(npz.len(), 10, "{:?}", npz.keys().collect::<Vec<_>>());
    for (name, (values, shape)) in &npz {
        let (v, s) = pt.get(name).unwrap_or_else(|| panic!("`{name}` not found in the .pt; it has {:?}", pt.keys()));
        assert_eq!(s, shape, "{name}: shape");
        assert!(v.iter().zip(values).all(|(a, b)| a.to_bits() == b.to_bits()), "{name}: values differ");
        assert_eq!(v.len(), values.len());
    }
}

#[test]
fn torchscript_controller_matches_golden() {
    if shared().is_none() {
        return;
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut spec = PolicySpec::load(&root.join("robots/h1_2/policies/unitree_rl_gym_lstm.toml")).expect("spec");
    spec.kind = PolicyKind::LstmTorchScript;
    spec.model_path = spec.model_path.with_extension("pt");
    let mut ctl = PolicyController::from_spec(spec).expect("controller from the .pt");
    let text = std::fs::read_to_string(root.join("corpus/golden/policies/unitree_rl_gym_lstm.json")).expect("golden");
    let doc: serde_json::Value = serde_json::from_str(&text).expect("json");
    let steps = doc["steps"].as_array().expect("steps");
    let f = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array().expect("array").iter().map(|x| x.as_f64().expect("number")).collect()
    };
    for (k, s) in steps.iter().enumerate() {
        let a3 = |key: &str| -> [f64; 3] { f(&s[key]).try_into().expect("3 values") };
        let obs = RobotObservation {
            time: s["time"].as_f64().expect("time"),
            base_quat: f(&s["base_quat"]).try_into().expect("4 values"),
            base_ang_vel: a3("base_ang_vel"),
            q: f(&s["q"]),
            dq: f(&s["dq"]),
            command: a3("command"),
        };
        let t = ctl.act(&obs).expect("act");
        let want = f(&s["q_des"]);
        let d = t.q_des.iter().zip(&want).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(d <= 1e-5, "step {k}: q_des differs by {d:e}");
    }
}

#[test]
fn not_a_torchscript_archive() {
    let Some(shared) = shared() else { return };
    // An .npz is a zip too, but has no data.pkl.
    let e = policy_runtime::torchscript::read_tensors(&shared.join("reference/policies/h1_2_unitree_rl_gym_lstm.npz"))
        .unwrap_err();
    assert!(matches!(e, policy_runtime::PolicyError::Model { .. }), "{e}");
    let e = policy_runtime::torchscript::read_tensors(&shared.join("reference/policies/h1_2_gepetto_demo_rsl.onnx"))
        .unwrap_err();
    assert!(matches!(e, policy_runtime::PolicyError::Model { .. }), "{e}");
}

/// Damaged archives give errors, never panics or hangs: every truncation of the real `data.pkl` and
/// deterministic single-byte corruptions of it, each in a fresh zip with the original storages.
#[test]
fn damaged_pickles_are_errors_not_panics() {
    use std::io::{Read, Write};
    let Some(shared) = shared() else { return };
    let src = shared.join("reference/policies/h1_2_unitree_rl_gym_lstm.pt");
    let mut zin = zip::ZipArchive::new(std::fs::File::open(&src).expect("open")).expect("zip");
    let mut entries = Vec::new();
    for i in 0..zin.len() {
        let mut f = zin.by_index(i).expect("entry");
        let name = f.name().to_string();
        if name.contains("/data.pkl") || name.contains("/data/") || name.ends_with("byteorder") {
            let mut buf = Vec::new();
            f.read_to_end(&mut buf).expect("read");
            entries.push((name, buf));
        }
    }
    let pkl_at = entries.iter().position(|(n, _)| n.ends_with("/data.pkl")).expect("data.pkl");
    let pkl = entries[pkl_at].1.clone();
    let tmp = std::env::temp_dir().join(format!("policy-runtime-damaged-{}.pt", std::process::id()));
    let write = |bad: &[u8]| {
        let mut z = zip::ZipWriter::new(std::fs::File::create(&tmp).expect("create"));
        let opts = zip::write::FileOptions::default().compression_method(zip::CompressionMethod::Stored);
        for (k, (name, data)) in entries.iter().enumerate() {
            z.start_file(name.as_str(), opts).expect("start");
            z.write_all(if k == pkl_at { bad } else { data }).expect("write");
        }
        z.finish().expect("finish");
    };
    let mut variants: Vec<Vec<u8>> = (0..pkl.len()).step_by(7).map(|n| pkl[..n].to_vec()).collect();
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    for _ in 0..300 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let mut v = pkl.clone();
        let at = (x as usize) % v.len();
        v[at] = (x >> 32) as u8;
        variants.push(v);
    }
    let mut errors = 0;
    for v in &variants {
        write(v);
        if policy_runtime::torchscript::read_tensors(&tmp).is_err() {
            errors += 1;
        }
    }
    let _ = std::fs::remove_file(&tmp);
    assert!(errors >= (pkl.len() / 7), "every truncation must fail ({errors} errors)");
}
