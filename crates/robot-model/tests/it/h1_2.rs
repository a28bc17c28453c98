//! Tests of the built-in H1-2 model and of the rigid-body reference against independent formulations
//! (numerical differentiation of forward kinematics and energy), plus validation errors.
use nalgebra::{DMatrix, DVector, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use robot_model::{GenCoords, ModelError, RobotModel};

fn model() -> RobotModel {
    RobotModel::h1_2().expect("built-in H1-2 loads")
}

fn random_coords(m: &RobotModel, rng: &mut impl Rng) -> GenCoords {
    let q = m.joints.iter().map(|j| rng.gen_range(j.lower..j.upper)).collect();
    let axis = Vector3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
    let r = UnitQuaternion::from_scaled_axis(axis * 2.0);
    GenCoords {
        base_pos: [rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(0.5..1.5)],
        base_quat: [r.w, r.i, r.j, r.k],
        q,
    }
}

/// q ⊕ v·h with the crate's velocity coordinates (linear world, angular body frame).
fn integrate(c: &GenCoords, v: &[f64], h: f64) -> GenCoords {
    let [w, x, y, z] = c.base_quat;
    let r = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
    let r2 = r * UnitQuaternion::from_scaled_axis(Vector3::new(v[3], v[4], v[5]) * h);
    GenCoords {
        base_pos: [c.base_pos[0] + v[0] * h, c.base_pos[1] + v[1] * h, c.base_pos[2] + v[2] * h],
        base_quat: [r2.w, r2.i, r2.j, r2.k],
        q: c.q.iter().zip(&v[6..]).map(|(q, d)| q + d * h).collect(),
    }
}

#[test]
fn slot_map_matches_unitree_hg_layout() {
    // The public unitree_hg H1-2 slot map (reference README), written out independently of our TOML.
    let side = |s: &str, names: &[&str]| names.iter().map(|n| format!("{s}_{n}")).collect::<Vec<_>>();
    let legs = ["hip_yaw", "hip_pitch", "hip_roll", "knee", "ankle_pitch", "ankle_roll"];
    let arms = ["shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll", "wrist_pitch", "wrist_yaw"];
    let mut expected = side("left", &legs);
    expected.extend(side("right", &legs));
    expected.push("torso".into());
    expected.extend(side("left", &arms));
    expected.extend(side("right", &arms));
    let m = model();
    assert_eq!(m.nj(), 27);
    assert_eq!(m.links.len(), 28);
    assert_eq!(m.slot_count, 35);
    for (i, j) in m.joints.iter().enumerate() {
        assert_eq!(j.slot, i);
        assert_eq!(j.motor_name, expected[i], "slot {i}");
    }
    // Torque / speed limits (N·m, rad/s) per the public H1-2 motor figures.
    let lim = |n: &str| -> (f64, f64) {
        let k = n.trim_start_matches("left_").trim_start_matches("right_");
        match k {
            "hip_yaw" | "hip_pitch" | "hip_roll" | "torso" => (200.0, 23.0),
            "knee" => (300.0, 14.0),
            "ankle_pitch" => (60.0, 9.0),
            "ankle_roll" => (40.0, 9.0),
            "shoulder_pitch" | "shoulder_roll" => (40.0, 9.0),
            "shoulder_yaw" | "elbow" => (18.0, 20.0),
            _ => (19.0, 31.4),
        }
    };
    for j in &m.joints {
        assert_eq!((j.torque_limit, j.speed_limit), lim(&j.motor_name), "{}", j.motor_name);
    }
}

#[test]
fn standing_pose_puts_flat_soles_on_the_ground() {
    let m = model();
    let c = GenCoords::standing(&m);
    let low = m.lowest_point_z(&c).expect("fk");
    assert!(low.abs() < 1e-4, "lowest point at standing is {low} m, expected 0 ± 0.1 mm");
    let fk = m.fk(&c).expect("fk");
    for foot in ["left_ankle_roll_link", "right_ankle_roll_link"] {
        let i = m.link_index(foot).expect("foot link");
        let z = fk.link_poses[i].rotation * Vector3::z();
        assert!((z - Vector3::z()).norm() < 1e-9, "{foot} not flat: z axis {z:?}");
    }
    // COM above the support polygon (between the feet in x).
    let com = m.com(&c).expect("com");
    let lf = fk.link_poses[m.link_index("left_ankle_roll_link").expect("l")].translation.vector;
    assert!(com.x > lf.x - 0.086 && com.x < lf.x + 0.174, "COM x {} outside the sole", com.x);
}

#[test]
fn mass_matrix_equals_jacobian_form_from_numerical_fk() {
    // M = Σ m Jcᵀ Jc + Jωᵀ I Jω with Jacobians from central differences of FK: independent of the RNEA.
    let m = model();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let nv = m.nv();
    for _ in 0..3 {
        let c = random_coords(&m, &mut rng);
        let h = 1e-6;
        let coms0 = m.link_coms(&c).expect("coms");
        let fk0 = m.fk(&c).expect("fk");
        let mut jc = vec![DMatrix::<f64>::zeros(3, nv); m.links.len()];
        let mut jw = vec![DMatrix::<f64>::zeros(3, nv); m.links.len()];
        for k in 0..nv {
            let mut e = vec![0.0; nv];
            e[k] = 1.0;
            let (cp, cm) = (integrate(&c, &e, h), integrate(&c, &e, -h));
            let (pp, pm) = (m.link_coms(&cp).expect("c"), m.link_coms(&cm).expect("c"));
            let (fp, fm) = (m.fk(&cp).expect("f"), m.fk(&cm).expect("f"));
            for l in 0..m.links.len() {
                jc[l].set_column(k, &((pp[l] - pm[l]) / (2.0 * h)));
                let dr = fp.link_poses[l].rotation * fm.link_poses[l].rotation.inverse();
                jw[l].set_column(k, &(dr.scaled_axis() / (2.0 * h)));
            }
        }
        let mut mj = DMatrix::zeros(nv, nv);
        for (l, link) in m.links.iter().enumerate() {
            let r = fk0.link_poses[l].rotation.to_rotation_matrix();
            let iw = r.matrix() * link.inertial.inertia * r.matrix().transpose();
            mj += jc[l].transpose() * &jc[l] * link.inertial.mass + jw[l].transpose() * iw * &jw[l];
        }
        let _ = coms0;
        let mr = m.mass_matrix(&c, false).expect("M");
        let err = (&mr - &mj).norm() / mr.norm();
        // Central differences: truncation O(h²) ≈ 1e-12, roundoff eps/h ≈ 1e-10 relative.
        assert!(err < 1e-7, "RNEA mass matrix vs numerical Jacobians: {err}");
        // Armature adds exactly to the joint diagonal.
        let ma = m.mass_matrix(&c, true).expect("M");
        for (i, j) in m.joints.iter().enumerate() {
            assert!((ma[(6 + i, 6 + i)] - mr[(6 + i, 6 + i)] - j.armature).abs() < 1e-12);
        }
    }
}

#[test]
fn gravity_forces_are_the_gradient_of_potential_energy() {
    let m = model();
    let g = [0.0, 0.0, -9.81];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let nv = m.nv();
    for _ in 0..3 {
        let c = random_coords(&m, &mut rng);
        let gq = m.bias_forces(&c, &vec![0.0; nv], g).expect("g(q)");
        let h = 1e-6;
        for k in 0..nv {
            let mut e = vec![0.0; nv];
            e[k] = 1.0;
            let d = (m.potential_energy(&integrate(&c, &e, h), g).expect("pe")
                - m.potential_energy(&integrate(&c, &e, -h), g).expect("pe"))
                / (2.0 * h);
            assert!((d - gq[k]).abs() < 1e-5 * (1.0 + gq[k].abs()), "dof {k}: dV/dq {d} vs g(q) {}", gq[k]);
        }
    }
}

#[test]
fn coriolis_terms_satisfy_the_energy_identity() {
    // With c(q,v) = b(q,v) − g(q): vᵀ Ṁ v = 2 vᵀ c (skew-symmetry of Ṁ − 2C), Ṁ by central differences along v.
    let m = model();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let nv = m.nv();
    let g = [0.0, 0.0, -9.81];
    for _ in 0..3 {
        let c = random_coords(&m, &mut rng);
        let v: Vec<f64> = (0..nv).map(|_| rng.gen_range(-2.0..2.0)).collect();
        let h = 1e-6;
        let mdot = (m.mass_matrix(&integrate(&c, &v, h), false).expect("M")
            - m.mass_matrix(&integrate(&c, &v, -h), false).expect("M"))
            / (2.0 * h);
        let vv = DVector::from_vec(v.clone());
        let lhs = vv.dot(&(&mdot * &vv));
        let cvec = m.bias_forces(&c, &v, g).expect("b") - m.bias_forces(&c, &vec![0.0; nv], g).expect("g");
        let rhs = 2.0 * vv.dot(&cvec);
        assert!((lhs - rhs).abs() < 1e-5 * (1.0 + lhs.abs()), "vᵀṀv {lhs} vs 2vᵀc {rhs}");
    }
}

#[test]
fn free_body_momentum_rate_is_zero_in_zero_gravity() {
    // With no external force, the accelerations from forward dynamics keep linear momentum constant:
    // d/dt (Σ m v_com) = Σ m a_com = 0 → checked through the COM acceleration by differentiating momentum.
    let m = model();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
    let nv = m.nv();
    let c = random_coords(&m, &mut rng);
    let v: Vec<f64> = (0..nv).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let a = m.forward_dynamics(&c, &v, &vec![0.0; nv], [0.0; 3], false).expect("fd");
    let h = 1e-6;
    let vp: Vec<f64> = v.iter().zip(a.iter()).map(|(v, a)| v + a * h).collect();
    let vm: Vec<f64> = v.iter().zip(a.iter()).map(|(v, a)| v - a * h).collect();
    let (_, pp) = m.momentum(&integrate(&c, &v, h), &vp).expect("p");
    let (_, pm) = m.momentum(&integrate(&c, &v, -h), &vm).expect("p");
    let (_, p0) = m.momentum(&c, &v).expect("p");
    let rate = (Vector3::from(pp) - Vector3::from(pm)).norm() / (2.0 * h);
    assert!(rate < 1e-4 * (1.0 + Vector3::from(p0).norm()), "dp/dt = {rate}");
}

fn sources() -> (String, String) {
    let (u, t) = RobotModel::h1_2_sources();
    (u.to_string(), t.to_string())
}

#[test]
fn validation_rejects_broken_files() {
    let (urdf, toml) = sources();
    // Missing motor for a joint.
    let t = toml.replacen("joint = \"right_wrist_yaw_joint\"", "joint = \"no_such_joint\"", 1);
    assert!(matches!(RobotModel::from_strs(&urdf, &t), Err(ModelError::MotorJointMissing { .. })));
    // Duplicate slot.
    let t = toml.replacen("slot = 26", "slot = 25", 1);
    assert!(matches!(RobotModel::from_strs(&urdf, &t), Err(ModelError::BadMotor { .. })));
    // Slot beyond the message.
    let t = toml.replacen("slot = 26", "slot = 35", 1);
    assert!(matches!(RobotModel::from_strs(&urdf, &t), Err(ModelError::BadMotor { .. })));
    // Non-positive mass.
    let u = urdf.replacen("<mass value=\"5.983\"/>", "<mass value=\"0\"/>", 1);
    assert!(matches!(RobotModel::from_strs(&u, &toml), Err(ModelError::BadInertial { .. })));
    // Non-revolute joint.
    let u = urdf.replacen("type=\"revolute\"", "type=\"prismatic\"", 1);
    assert!(matches!(RobotModel::from_strs(&u, &toml), Err(ModelError::UnsupportedJoint { .. })));
    // Non-unit axis.
    let u = urdf.replacen("<axis xyz=\"0 0 1\"/>", "<axis xyz=\"0 0 2\"/>", 1);
    assert!(matches!(RobotModel::from_strs(&u, &toml), Err(ModelError::BadJoint { .. })));
    // Effort in the URDF disagreeing with the sidecar.
    let u = urdf.replacen("effort=\"300\"", "effort=\"301\"", 1);
    assert!(matches!(RobotModel::from_strs(&u, &toml), Err(ModelError::BadJoint { .. })));
    // Mesh collision geometry.
    let u = urdf.replacen(
        "<geometry><box size=\"0.14 0.24 0.14\"/></geometry>",
        "<geometry><mesh filename=\"pelvis.stl\"/></geometry>",
        1,
    );
    assert!(matches!(RobotModel::from_strs(&u, &toml), Err(ModelError::UnsupportedGeometry { .. })));
    // Unknown key in the sidecar.
    let t = toml.replacen("[contact]", "[contact]\nbogus = 1", 1);
    assert!(matches!(RobotModel::from_strs(&urdf, &t), Err(ModelError::Toml(_))));
    // Default angle outside the range.
    let t = toml.replacen("default_q = 0.36", "default_q = 3.0", 1);
    assert!(matches!(RobotModel::from_strs(&urdf, &t), Err(ModelError::BadJoint { .. })));
    // The unmodified files load.
    assert!(RobotModel::from_strs(&urdf, &toml).is_ok());
}

#[test]
fn loads_from_files_on_disk_too() {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots/h1_2/h1_2.toml");
    let a = RobotModel::load(&p).expect("load from disk");
    assert_eq!(a, model());
    assert!(matches!(RobotModel::load(std::path::Path::new("/nonexistent/x.toml")), Err(ModelError::Io { .. })));
}
