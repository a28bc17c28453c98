//! Bad robot files (issue 19, item 5): the shipped H1-2 URDF and sidecar TOML with one value replaced by something
//! malformed (NaN, infinities, huge, negative, empty, text) or a span of text cut out or garbled must load into a
//! model that is physically valid, or fail with a typed `ModelError`: never panic, never give a model with a
//! non-finite or non-physical quantity. Shrunk cases print the mutation.
use proptest::prelude::*;
use robot_model::RobotModel;

const WEIRD: [&str; 11] = ["nan", "NaN", "inf", "-inf", "1e308", "-1e308", "-1", "0", "", "abc", "1e-300"];

/// Replaces the `k`-th quoted attribute value (URDF) with `v`.
fn replace_attr(text: &str, k: usize, v: &str) -> String {
    let quotes: Vec<usize> = text.match_indices('"').map(|(i, _)| i).collect();
    let pairs = quotes.len() / 2;
    if pairs == 0 {
        return text.to_string();
    }
    let i = k % pairs;
    let (a, b) = (quotes[2 * i], quotes[2 * i + 1]);
    format!("{}\"{v}\"{}", &text[..a], &text[b + 1..])
}

/// Replaces the value of the `k`-th `key = value` line (TOML) with `v`.
fn replace_toml_value(text: &str, k: usize, v: &str) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let with_value: Vec<usize> = (0..lines.len()).filter(|&i| lines[i].contains(" = ")).collect();
    if with_value.is_empty() {
        return text.to_string();
    }
    let i = with_value[k % with_value.len()];
    let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let key = lines[i].split(" = ").next().unwrap_or_default();
    out[i] = format!("{key} = {v}");
    out.join("\n")
}

/// Cuts `len` bytes at the fraction `at` of the text (on a char boundary) and inserts `insert` there.
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

/// Every quantity of a loaded model is finite and physical.
fn physical(m: &RobotModel) -> Result<(), String> {
    for l in &m.links {
        let i = &l.inertial;
        if !(i.mass.is_finite() && i.mass > 0.0 && i.com.iter().all(|x| x.is_finite())) {
            return Err(format!("link {}: mass {} com {:?}", l.name, i.mass, i.com));
        }
        if !i.inertia.iter().all(|x| x.is_finite()) {
            return Err(format!("link {}: inertia {:?}", l.name, i.inertia));
        }
    }
    for j in &m.joints {
        let all = [
            j.lower,
            j.upper,
            j.torque_limit,
            j.speed_limit,
            j.armature,
            j.damping,
            j.frictionloss,
            j.kp,
            j.kd,
            j.default_q,
        ];
        if !all.iter().all(|x| x.is_finite()) || j.lower > j.upper || !(j.lower..=j.upper).contains(&j.default_q) {
            return Err(format!("joint {}: {all:?}", j.name));
        }
        if j.torque_limit <= 0.0
            || j.speed_limit <= 0.0
            || j.kp < 0.0
            || j.kd < 0.0
            || j.armature < 0.0
            || j.damping < 0.0
        {
            return Err(format!("joint {}: {all:?}", j.name));
        }
        if !j.origin.translation.vector.iter().all(|x| x.is_finite()) || !j.axis.iter().all(|x| x.is_finite()) {
            return Err(format!("joint {}: origin or axis not finite", j.name));
        }
    }
    let c = &m.contact;
    if ![c.friction, c.torsional_friction, c.rolling_friction, c.restitution].iter().all(|x| x.is_finite() && *x >= 0.0)
    {
        return Err(format!("contact {c:?}"));
    }
    if !m.standing.base_pos.iter().chain(&m.standing.base_quat).all(|x| x.is_finite()) {
        return Err("standing pose not finite".into());
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn a_urdf_value_replaced(k in 0usize..4000, v in prop::sample::select(WEIRD.to_vec())) {
        let (urdf, toml) = RobotModel::h1_2_sources();
        if let Ok(m) = RobotModel::from_strs(&replace_attr(urdf, k, v), toml) {
            prop_assert!(physical(&m).is_ok(), "{:?}", physical(&m));
        }
    }

    #[test]
    fn a_sidecar_value_replaced(k in 0usize..1000, v in prop::sample::select(WEIRD.to_vec())) {
        let (urdf, toml) = RobotModel::h1_2_sources();
        if let Ok(m) = RobotModel::from_strs(urdf, &replace_toml_value(toml, k, v)) {
            prop_assert!(physical(&m).is_ok(), "{:?}", physical(&m));
        }
    }

    #[test]
    fn a_span_cut_or_garbled(urdf_side in any::<bool>(), at in 0.0f64..1.0, len in 0usize..200, insert in "[ -~]{0,12}") {
        let (urdf, toml) = RobotModel::h1_2_sources();
        let r = if urdf_side {
            RobotModel::from_strs(&splice(urdf, at, len, &insert), toml)
        } else {
            RobotModel::from_strs(urdf, &splice(toml, at, len, &insert))
        };
        if let Ok(m) = r {
            prop_assert!(physical(&m).is_ok(), "{:?}", physical(&m));
        }
    }
}
