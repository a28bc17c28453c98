//! Independent check of the project model against Unitree's published MJCF of the H1-2 (handless).
//!
//! Unitree's file is loaded in MuJoCo as published except for a test-only transform that drops its mesh
//! geoms and mesh assets (the meshes are not shipped with the reference; mesh geoms carry no mass because
//! every body has an explicit `<inertial>`). Total mass, per-body mass, body-frame FK, centre of mass and the
//! joint-space mass matrix at random configurations must equal those of our model computed by `robot-model`
//! (our URDF + TOML → our own RNEA/CRBA), and of our generated MJCF in MuJoCo.
//!
//! Armature: Unitree's `<default><joint armature="0.1" damping="1" frictionloss="0.2"/>` applies to EVERY joint,
//! including the free joint, so MuJoCo adds 0.1 to the six floating-base diagonal entries of M (and damps and
//! brakes the base against the world). Our model puts armature on the 27 hinges only (a floating base has no
//! rotor). We compare (1) Unitree's M minus its armature on the 6 base dofs with our M + diag(our hinge armature
//! from the sidecar TOML), which checks that our hinge armature equals theirs, and (2) Unitree's M minus all
//! its dof_armature with our rigid-body M, which checks the inertias alone whatever the armature.
#![cfg(feature = "mujoco")]
use mujoco_rs::prelude::*;
use nalgebra::{DMatrix, Vector3};
use rand::SeedableRng;
use robot_model::{GenCoords, RobotModel};
use std::path::PathBuf;

fn shared_dir() -> PathBuf {
    if let Ok(s) = std::env::var("ULAB_SHARED") {
        if !s.is_empty() {
            return PathBuf::from(s);
        }
    }
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared")
}

/// Removes `<asset>…</asset>` and every `<geom …/>` element with `type="mesh"` (test-only transform).
fn drop_meshes(xml: &str) -> String {
    let mut s = xml.to_string();
    if let (Some(a), Some(b)) = (s.find("<asset>"), s.find("</asset>")) {
        s.replace_range(a..b + "</asset>".len(), "");
    }
    let mut out = String::with_capacity(s.len());
    let mut rest = s.as_str();
    while let Some(i) = rest.find("<geom") {
        out.push_str(&rest[..i]);
        let tail = &rest[i..];
        let end = tail.find("/>").map(|e| e + 2).unwrap_or(tail.len());
        let elem = &tail[..end];
        if !elem.contains(r#"type="mesh""#) {
            out.push_str(elem);
        }
        rest = &tail[end..];
    }
    out.push_str(rest);
    out
}

fn unitree_model() -> MjModel {
    let path = shared_dir().join("reference/h1_2/unitree_mujoco_h1_2_handless.xml");
    let xml = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("Unitree's MJCF must be at {} (set ULAB_SHARED): {e}", path.display()));
    let stripped = drop_meshes(&xml);
    assert!(!stripped.contains(r#"type="mesh""#) && stripped.contains("<inertial"), "transform broke the file");
    MjModel::from_xml_string(&stripped).expect("Unitree's MJCF (without meshes) loads in MuJoCo")
}

struct Map {
    body: Vec<usize>,
    qadr: Vec<usize>,
    dadr: Vec<usize>,
    free_q: usize,
    free_d: usize,
}

fn map(m: &MjModel, model: &RobotModel) -> Map {
    let body = model
        .links
        .iter()
        .map(|l| {
            m.name_to_id(MjtObjBase::mjOBJ_BODY, &l.name)
                .unwrap_or_else(|| panic!("Unitree model lacks body {}", l.name))
        })
        .collect();
    let jid: Vec<usize> = model
        .joints
        .iter()
        .map(|j| {
            m.name_to_id(MjtObjBase::mjOBJ_JOINT, &j.name)
                .unwrap_or_else(|| panic!("Unitree model lacks joint {}", j.name))
        })
        .collect();
    let free = m.name_to_id(MjtObjBase::mjOBJ_JOINT, "floating_base_joint").expect("free joint");
    let qa = |j: usize| m.jnt_qposadr()[j] as usize;
    let da = |j: usize| m.jnt_dofadr()[j] as usize;
    Map {
        body,
        qadr: jid.iter().map(|&j| qa(j)).collect(),
        dadr: jid.iter().map(|&j| da(j)).collect(),
        free_q: qa(free),
        free_d: da(free),
    }
}

fn set_config(d: &mut MjData<&MjModel>, mp: &Map, c: &GenCoords) {
    let qpos = d.qpos_mut();
    qpos[mp.free_q..mp.free_q + 3].copy_from_slice(&c.base_pos);
    qpos[mp.free_q + 3..mp.free_q + 7].copy_from_slice(&c.base_quat);
    for (i, &a) in mp.qadr.iter().enumerate() {
        qpos[a] = c.q[i];
    }
    d.forward();
}

#[test]
fn masses_match_unitree() {
    let model = RobotModel::h1_2().expect("model");
    let m = unitree_model();
    let mp = map(&m, &model);
    let bm = m.body_mass();
    // Masses are decimal figures copied by the generator: equal to ~1e-12 kg (f64 printing round trip).
    let total_unitree: f64 = bm.iter().sum();
    assert!(
        (total_unitree - model.total_mass()).abs() < 1e-9,
        "total mass: Unitree {total_unitree}, ours {}",
        model.total_mass()
    );
    assert_eq!(bm.len(), model.links.len() + 1, "Unitree's model has bodies we do not (or vice versa)");
    for (l, &b) in model.links.iter().zip(&mp.body) {
        assert!((bm[b] - l.inertial.mass).abs() < 1e-12, "{}: Unitree {} ours {}", l.name, bm[b], l.inertial.mass);
    }
    println!("total mass {total_unitree:.6} kg (Unitree) = {:.6} kg (ours)", model.total_mass());
}

#[test]
fn com_fk_and_mass_matrix_match_unitree_at_random_configurations() {
    let model = RobotModel::h1_2().expect("model");
    let m = unitree_model();
    let mp = map(&m, &model);
    let mut d = m.make_data();
    let nv = model.nv();
    assert_eq!(m.nv() as usize, nv);
    let arm_unitree: Vec<f64> = m.dof_armature().to_vec();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(20261122);
    let (mut worst_com, mut worst_fk, mut worst_m_arm, mut worst_m_rigid) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut configs = vec![GenCoords::zero(&model), GenCoords::standing(&model)];
    configs.extend((0..8).map(|_| diff_physics::oracle::random_coords(&model, &mut rng)));
    for c in &configs {
        set_config(&mut d, &mp, c);
        // COM: Unitree's subtree COM of the pelvis vs our model.
        let com_u = Vector3::from(d.subtree_com()[mp.body[0]]);
        let com = model.com(c).expect("com");
        worst_com = worst_com.max((com_u - com).norm());
        // Body frames.
        let fk = model.fk(c).expect("fk");
        for (li, &b) in mp.body.iter().enumerate() {
            worst_fk = worst_fk.max((Vector3::from(d.xpos()[b]) - fk.link_poses[li].translation.vector).norm());
        }
        // Mass matrix in our coordinate order (base 6, then joints in slot order).
        let mut full = vec![0.0; nv * nv];
        d.full_m(&mut full).expect("fullM");
        let dof: Vec<usize> = (mp.free_d..mp.free_d + 6).chain(mp.dadr.iter().copied()).collect();
        let mu = DMatrix::from_fn(nv, nv, |r, k| full[dof[r] * nv + dof[k]]);
        let ours_arm = model.mass_matrix(c, true).expect("M");
        let ours_rigid = model.mass_matrix(c, false).expect("M");
        let mut mu_rigid = mu.clone();
        let mut mu_hinge_arm = mu.clone();
        for (r, &dr) in dof.iter().enumerate() {
            mu_rigid[(r, r)] -= arm_unitree[dr];
            if r < 6 {
                mu_hinge_arm[(r, r)] -= arm_unitree[dr];
            }
        }
        worst_m_arm = worst_m_arm.max((&mu_hinge_arm - &ours_arm).norm() / mu_hinge_arm.norm());
        worst_m_rigid = worst_m_rigid.max((&mu_rigid - &ours_rigid).norm() / mu_rigid.norm());
    }
    println!("COM {worst_com:.3e} m, FK {worst_fk:.3e} m, M(with armature) {worst_m_arm:.3e} rel, M(rigid) {worst_m_rigid:.3e} rel");
    // Tolerances: our inertias are Unitree's quat+diaginertia rotated into a full tensor and printed with
    // 10 significant digits by the generator, then re-diagonalised by MuJoCo for our MJCF; positions are
    // copied decimals. Relative rounding ~1e-10 on each inertia entry; the mass matrix sums O(100) such terms.
    // Body rotations: Unitree's shoulder quats (6 digits, norm 0.999998) are normalised by MuJoCo and turned
    // into URDF rpy printed with 15 digits → ≤1e-14 rad; COM/FK compose copied decimals in f64 → 1e-12 m.
    // M: 1e-8 relative (100× the printing rounding of the inertia entries).
    assert!(worst_com < 1e-12, "COM differs from Unitree's by {worst_com} m");
    assert!(worst_fk < 1e-12, "body FK differs from Unitree's by {worst_fk} m");
    assert!(worst_m_rigid < 1e-8, "rigid-body mass matrix differs from Unitree's by {worst_m_rigid} (relative)");
    assert!(worst_m_arm < 1e-8, "mass matrix with armature differs from Unitree's by {worst_m_arm} (relative)");
}

#[test]
fn our_generated_mjcf_matches_unitree_in_mujoco() {
    // Same comparison, MuJoCo on both sides: catches anything our MJCF writer loses (inertial frames, quats).
    use diff_physics::mujoco::{MujocoEngine, MujocoSettings};
    use diff_physics::{CommonSettings, Engine, State};
    let model = RobotModel::h1_2().expect("model");
    let m = unitree_model();
    let mp = map(&m, &model);
    let mut d = m.make_data();
    let common = CommonSettings { ground: false, joint_limits: false, ..CommonSettings::default() };
    let mut ours = MujocoEngine::new(&model, &common, &MujocoSettings::default()).expect("engine");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let nv = model.nv();
    let mut worst = 0.0f64;
    for _ in 0..5 {
        let c = diff_physics::oracle::random_coords(&model, &mut rng);
        set_config(&mut d, &mp, &c);
        ours.reset(&State::at_rest(c)).expect("reset");
        let mut full = vec![0.0; nv * nv];
        d.full_m(&mut full).expect("fullM");
        let dof: Vec<usize> = (mp.free_d..mp.free_d + 6).chain(mp.dadr.iter().copied()).collect();
        let mu = DMatrix::from_fn(nv, nv, |r, k| full[dof[r] * nv + dof[k]]);
        let mut mu = mu;
        for r in 0..6 {
            // Unitree's free joint inherits armature 0.1 (see the module docs); ours has none.
            mu[(r, r)] -= m.dof_armature()[dof[r]];
        }
        let mo = DMatrix::from_row_slice(nv, nv, &ours.mass_matrix().expect("M"));
        worst = worst.max((&mu - &mo).norm() / mu.norm());
    }
    println!("MuJoCo M, Unitree MJCF vs our MJCF: {worst:.3e} rel");
    assert!(worst < 1e-8, "{worst}");
}

#[test]
fn joint_axes_ranges_and_torque_limits_match_unitree() {
    let model = RobotModel::h1_2().expect("model");
    let m = unitree_model();
    for j in &model.joints {
        let id = m.name_to_id(MjtObjBase::mjOBJ_JOINT, &j.name).expect("joint");
        let r = m.jnt_range()[id];
        assert_eq!((r[0], r[1]), (j.lower, j.upper), "{} range", j.name);
        let a = m.jnt_axis()[id];
        assert!((Vector3::from(a) - j.axis.into_inner()).norm() < 1e-15, "{} axis {a:?} vs {:?}", j.name, j.axis);
        let f = m.jnt_actfrcrange()[id];
        assert_eq!((f[0], f[1]), (-j.torque_limit, j.torque_limit), "{} torque limit", j.name);
        let act = m.name_to_id(MjtObjBase::mjOBJ_ACTUATOR, &j.name).expect("actuator named after the joint");
        let c = m.actuator_ctrlrange()[act];
        assert_eq!((c[0], c[1]), (-j.torque_limit, j.torque_limit), "{} ctrlrange", j.name);
        assert_eq!(m.dof_armature()[m.jnt_dofadr()[id] as usize], j.armature, "{} armature", j.name);
        assert_eq!(m.dof_damping()[m.jnt_dofadr()[id] as usize], j.damping, "{} damping", j.name);
        assert_eq!(m.dof_frictionloss()[m.jnt_dofadr()[id] as usize], j.frictionloss, "{} frictionloss", j.name);
    }
}
