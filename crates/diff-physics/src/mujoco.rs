//! MuJoCo engine through `mujoco-rs` (safe API only), on an MJCF generated from the project model.
use crate::engine::*;
use mujoco_rs::prelude::*;
use robot_model::{MjcfOptions, RobotModel, ShapeFilter};
use serde::{Deserialize, Serialize};

/// Every MuJoCo-specific setting, written into the generated MJCF's `<option>` (nothing is left to defaults
/// that differ from these values).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MujocoSettings {
    /// `euler` | `implicitfast` | `implicit` | `RK4`. Default `implicitfast`: MuJoCo's recommendation for
    /// robots (velocity-dependent forces — damping, Coriolis — handled implicitly, stable at 2 ms).
    pub integrator: String,
    /// Physics sub-steps per `Engine::step` (each of `timestep / substeps`).
    pub substeps: u32,
    /// `pyramidal` (MuJoCo default) | `elliptic` friction cone.
    pub cone: String,
    /// `Newton` (default) | `CG` | `PGS`.
    pub solver: String,
    pub iterations: u32,
    pub ls_iterations: u32,
    pub tolerance: f64,
    /// Ratio of frictional to normal constraint impedance (1 = default).
    pub impratio: f64,
    /// Contact detection margin (m) on every geom (0: contacts only when touching; MuJoCo's default).
    pub contact_margin: f64,
    /// Contact softness (MuJoCo defaults: timeconst 0.02 s, damping ratio 1). Contacts use condim 3 (sliding
    /// friction, pyramidal/elliptic cone per `cone`); margin, solref, solimp and the model's friction are applied to
    /// every contact through MuJoCo's contact override (`<flag override="enable">`).
    pub solref: [f64; 2],
    pub solimp: [f64; 5],
    /// Parent-child contact filtering (MuJoCo's `filterparent` flag; irrelevant when self-collision is off).
    pub filter_parent: bool,
    /// Warm-start the constraint solver from the previous step's accelerations (cleared on reset).
    pub warmstart: bool,
}

impl Default for MujocoSettings {
    fn default() -> Self {
        MujocoSettings {
            integrator: "implicitfast".into(),
            substeps: 1,
            cone: "pyramidal".into(),
            solver: "Newton".into(),
            iterations: 100,
            ls_iterations: 50,
            tolerance: 1e-8,
            impratio: 1.0,
            contact_margin: 0.0,
            solref: [0.02, 1.0],
            solimp: [0.9, 0.95, 0.001, 0.5, 2.0],
            filter_parent: true,
            warmstart: true,
        }
    }
}

/// The H1-2 (or any model) in MuJoCo.
#[derive(Debug)]
pub struct MujocoEngine {
    data: MjData<Box<MjModel>>,
    common: CommonSettings,
    specific: MujocoSettings,
    mjcf: String,
    nj: usize,
    link_body: Vec<usize>,
    link_names: Vec<String>,
    jnt_id: Vec<usize>,
    qadr: Vec<usize>,
    dadr: Vec<usize>,
    /// Kinematics (xpos, xquat, ...) are stale after a step until recomputed.
    kin_stale: bool,
}

fn fmt_vec(v: &[f64]) -> String {
    v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(" ")
}

impl MujocoEngine {
    /// Generates the MJCF for `model` with these settings.
    pub fn mjcf(model: &RobotModel, common: &CommonSettings, s: &MujocoSettings) -> String {
        let dt = common.timestep / f64::from(s.substeps.max(1));
        // No `energy` flag: it makes every step compute the energy, which only [`Engine::energy`] reads, and that
        // calls mj_energyPos and mj_energyVel itself (a few per cent of a step on the H1-2).
        let mut flags = vec![
            ("filterparent".to_string(), if s.filter_parent { "enable" } else { "disable" }.to_string()),
            ("warmstart".to_string(), if s.warmstart { "enable" } else { "disable" }.to_string()),
        ];
        if !common.collisions {
            flags.push(("contact".into(), "disable".into()));
        }
        let opts = MjcfOptions {
            timestep: dt,
            gravity: common.gravity,
            floor: common.ground,
            shapes: if common.collisions { ShapeFilter::All } else { ShapeFilter::None },
            armature: common.armature,
            damping: common.joint_damping,
            frictionloss: common.joint_friction,
            joint_limits: common.joint_limits,
            option_attrs: vec![
                ("integrator".into(), s.integrator.clone()),
                ("cone".into(), s.cone.clone()),
                ("solver".into(), s.solver.clone()),
                ("iterations".into(), s.iterations.to_string()),
                ("ls_iterations".into(), s.ls_iterations.to_string()),
                ("tolerance".into(), format!("{:?}", s.tolerance)),
                ("impratio".into(), format!("{:?}", s.impratio)),
                ("o_margin".into(), format!("{:?}", s.contact_margin)),
                ("o_solref".into(), fmt_vec(&s.solref)),
                ("o_solimp".into(), fmt_vec(&s.solimp)),
                // Contact override friction: sliding ×2, torsional, rolling ×2 (only sliding acts with condim 3).
                ("o_friction".into(), {
                    let c = &model.contact;
                    fmt_vec(&[c.friction, c.friction, c.torsional_friction, c.rolling_friction, c.rolling_friction])
                }),
            ],
            flag_attrs: flags,
            ..MjcfOptions::default()
        };
        let mut xml = model.to_mjcf(&opts);
        // Contact parameters through the global override, so that every geom pair uses exactly these values.
        xml = xml.replacen("<flag ", r#"<flag override="enable" "#, 1);
        xml
    }

    /// Builds the engine.
    pub fn new(model: &RobotModel, common: &CommonSettings, specific: &MujocoSettings) -> Result<Self, EngineError> {
        if !(common.timestep.is_finite() && common.timestep > 0.0) {
            return Err(EngineError::Input(format!("timestep {} must be positive", common.timestep)));
        }
        let mjcf = Self::mjcf(model, common, specific);
        let m = MjModel::from_xml_string(&mjcf).map_err(|e| EngineError::Build(e.to_string()))?;
        let m = Box::new(m);
        let body = |name: &str| m.name_to_id(MjtObjBase::mjOBJ_BODY, name);
        let mut link_body = Vec::new();
        for l in &model.links {
            link_body.push(body(&l.name).ok_or_else(|| EngineError::Build(format!("body {} missing", l.name)))?);
        }
        let (mut jnt_id, mut qadr, mut dadr) = (Vec::new(), Vec::new(), Vec::new());
        for j in &model.joints {
            let id = m
                .name_to_id(MjtObjBase::mjOBJ_JOINT, &j.name)
                .ok_or_else(|| EngineError::Build(format!("joint {} missing", j.name)))?;
            jnt_id.push(id);
            qadr.push(usize::try_from(m.jnt_qposadr()[id]).map_err(|_| EngineError::Build("bad qposadr".into()))?);
            dadr.push(usize::try_from(m.jnt_dofadr()[id]).map_err(|_| EngineError::Build("bad dofadr".into()))?);
        }
        if m.nq() as usize != model.nq() || m.nv() as usize != model.nv() {
            return Err(EngineError::Build(format!(
                "MuJoCo nq/nv {}/{} differ from the model's {}/{}",
                m.nq(),
                m.nv(),
                model.nq(),
                model.nv()
            )));
        }
        let data = MjData::try_new(m).map_err(|e| EngineError::Build(e.to_string()))?;
        let mut e = MujocoEngine {
            data,
            common: common.clone(),
            specific: specific.clone(),
            mjcf,
            nj: model.nj(),
            link_body,
            link_names: model.links.iter().map(|l| l.name.clone()).collect(),
            jnt_id,
            qadr,
            dadr,
            kin_stale: true,
        };
        e.reset(&State::standing(model))?;
        Ok(e)
    }

    /// The generated MJCF this engine runs.
    pub fn mjcf_text(&self) -> &str {
        &self.mjcf
    }

    /// Raw access for benchmarks and tests (the Engine layer's overhead is measured against it).
    pub fn raw_data(&mut self) -> &mut MjData<Box<MjModel>> {
        self.kin_stale = true;
        &mut self.data
    }

    fn ensure_kinematics(&mut self) {
        if self.kin_stale {
            self.data.forward();
            self.kin_stale = false;
        }
    }

    fn check(&self, what: &str, x: &[f64], n: usize) -> Result<(), EngineError> {
        if x.len() != n || x.iter().any(|v| !v.is_finite()) {
            return Err(EngineError::Input(format!("{what}: expected {n} finite values, got {}", x.len())));
        }
        Ok(())
    }
}

impl Engine for MujocoEngine {
    fn name(&self) -> &'static str {
        EngineKind::Mujoco.name()
    }

    fn version(&self) -> String {
        format!("MuJoCo {} via mujoco-rs 7.0.0", mujoco_rs::mujoco_version())
    }

    fn settings(&self) -> serde_json::Value {
        serde_json::json!({
            "engine": self.name(),
            "version": self.version(),
            "common": self.common,
            "mujoco": self.specific,
            "precision": "f64",
            "model_source": "MJCF generated by robot-model (free joint), not MuJoCo's URDF import",
            "contact_filtering": "contype/conaffinity bitmasks: robot geoms touch the floor only unless the model enables self-collision",
            "acceleration_method": "analytic: qacc_smooth = M^-1 (applied + passive - bias) from mj_forward",
            "mass_matrix": "mj_fullM",
            "energy": "mj_energyPos + mj_energyVel (kinetic includes armature)",
        })
    }

    fn common(&self) -> &CommonSettings {
        &self.common
    }

    fn reset(&mut self, s: &State) -> Result<(), EngineError> {
        let nj = self.nj;
        if s.q.len() != nj || s.dq.len() != nj {
            return Err(EngineError::Input(format!(
                "state has {} / {} joint entries, model has {nj}",
                s.q.len(),
                s.dq.len()
            )));
        }
        self.check("state", &s.qpos(), 7 + nj)?;
        self.check("state", &s.v(), 6 + nj)?;
        // mj_resetData: zeroes time, qacc_warmstart, contacts, constraint forces, ctrl, applied forces.
        self.data.reset();
        let n: f64 = s.base_quat.iter().map(|x| x * x).sum::<f64>().sqrt();
        if n.is_nan() || n <= 1e-9 {
            return Err(EngineError::Input("zero base quaternion".into()));
        }
        {
            let qpos = self.data.qpos_mut();
            qpos[0..3].copy_from_slice(&s.base_pos);
            for k in 0..4 {
                qpos[3 + k] = s.base_quat[k] / n;
            }
        }
        for i in 0..nj {
            let (qa, da) = (self.qadr[i], self.dadr[i]);
            self.data.qpos_mut()[qa] = s.q[i];
            self.data.qvel_mut()[da] = s.dq[i];
        }
        let qvel = self.data.qvel_mut();
        qvel[0..3].copy_from_slice(&s.base_lin_vel);
        qvel[3..6].copy_from_slice(&s.base_ang_vel);
        self.data.forward();
        self.kin_stale = false;
        Ok(())
    }

    fn step(&mut self, tau: &[f64]) -> Result<(), EngineError> {
        if tau.len() != self.nj {
            return Err(EngineError::Input(format!("expected {} torques, got {}", self.nj, tau.len())));
        }
        // Actuators are plain motors in slot order (gear 1, no ctrl limits): ctrl = joint torque.
        self.data.ctrl_mut().copy_from_slice(tau);
        for _ in 0..self.specific.substeps.max(1) {
            self.data.step();
        }
        self.kin_stale = true;
        if self.data.qpos().iter().chain(self.data.qvel().iter()).any(|x| !x.is_finite()) {
            return Err(EngineError::Diverged(format!("non-finite state at t = {}", self.data.time())));
        }
        Ok(())
    }

    /// Through `qfrc_applied` on the free joint: the force as it is (MuJoCo's free-joint translation is the
    /// body origin's), the torque turned into the pelvis frame (the free joint's rotational DoFs) at the current
    /// orientation.
    fn set_base_wrench(&mut self, wrench: [f64; 6]) -> Result<(), EngineError> {
        if wrench.iter().any(|x| !x.is_finite()) {
            return Err(EngineError::Input(format!("non-finite base wrench {wrench:?}")));
        }
        let qpos = self.data.qpos();
        let r =
            nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(qpos[3], qpos[4], qpos[5], qpos[6]));
        let t_local = r.inverse() * nalgebra::Vector3::new(wrench[3], wrench[4], wrench[5]);
        let qa = self.data.qfrc_applied_mut();
        qa[..3].copy_from_slice(&wrench[..3]);
        qa[3..6].copy_from_slice(t_local.as_slice());
        Ok(())
    }

    fn state(&self) -> State {
        let qpos = self.data.qpos();
        let qvel = self.data.qvel();
        State {
            base_pos: [qpos[0], qpos[1], qpos[2]],
            base_quat: [qpos[3], qpos[4], qpos[5], qpos[6]],
            q: self.qadr.iter().map(|&a| qpos[a]).collect(),
            base_lin_vel: [qvel[0], qvel[1], qvel[2]],
            base_ang_vel: [qvel[3], qvel[4], qvel[5]],
            dq: self.dadr.iter().map(|&a| qvel[a]).collect(),
        }
    }

    fn time(&self) -> f64 {
        self.data.time()
    }

    fn contacts(&self) -> Vec<Contact> {
        let m = self.data.model();
        let geom_body = m.geom_bodyid();
        let name_of = |g: i32| -> String {
            let b =
                usize::try_from(g).ok().and_then(|g| geom_body.get(g).copied()).and_then(|b| usize::try_from(b).ok());
            match b {
                Some(0) | None => "ground".to_string(),
                Some(b) => m.id_to_name(MjtObjBase::mjOBJ_BODY, b).unwrap_or("?").to_string(),
            }
        };
        let mut out = Vec::new();
        for (i, c) in self.data.contact().iter().enumerate() {
            let f = self.data.try_contact_force(i).map(|f| f[0]).unwrap_or(f64::NAN);
            let (mut a, mut b) = (name_of(c.geom1), name_of(c.geom2));
            // MuJoCo's frame[0..3] is the normal pointing from geom1 to geom2.
            let mut n = [c.frame[0], c.frame[1], c.frame[2]];
            if b == "ground" && a != "ground" {
                std::mem::swap(&mut a, &mut b);
                n = [-n[0], -n[1], -n[2]];
            }
            out.push(Contact { body_a: a, body_b: b, point: c.pos, normal: n, normal_force: f, depth: -c.dist });
        }
        out
    }

    fn energy(&mut self) -> Energy {
        self.ensure_kinematics();
        self.data.energy_pos();
        self.data.energy_vel();
        let e = self.data.energy();
        Energy { potential: e[0], kinetic: e[1] }
    }

    fn link_masses(&self) -> Vec<f64> {
        let m = self.data.model().body_mass();
        self.link_body.iter().map(|&b| m[b]).collect()
    }

    fn link_poses(&mut self) -> Vec<LinkPose> {
        self.ensure_kinematics();
        let (xp, xq) = (self.data.xpos(), self.data.xquat());
        self.link_body.iter().map(|&b| LinkPose { pos: xp[b], quat: xq[b] }).collect()
    }

    fn com(&mut self) -> [f64; 3] {
        self.ensure_kinematics();
        // subtree_com of the robot's root body = whole-robot COM.
        self.data.subtree_com()[self.link_body[0]]
    }

    fn joint_axes(&mut self) -> Vec<[f64; 3]> {
        self.ensure_kinematics();
        let ax = self.data.xaxis();
        self.jnt_id.iter().map(|&j| ax[j]).collect()
    }

    fn joint_limits(&self) -> Vec<(f64, f64)> {
        let r = self.data.model().jnt_range();
        self.jnt_id.iter().map(|&j| (r[j][0], r[j][1])).collect()
    }

    fn generalized_acceleration(&mut self, f: &[f64]) -> Result<Vec<f64>, EngineError> {
        let nv = 6 + self.nj;
        self.check("generalized force", f, nv)?;
        let saved_ctrl = self.data.ctrl().to_vec();
        let saved_applied = self.data.qfrc_applied().to_vec();
        self.data.ctrl_mut().iter_mut().for_each(|c| *c = 0.0);
        {
            let qa = self.data.qfrc_applied_mut();
            qa[0..6].copy_from_slice(&f[0..6]);
        }
        for i in 0..self.nj {
            let d = self.dadr[i];
            self.data.qfrc_applied_mut()[d] = f[6 + i];
        }
        self.data.forward();
        let acc = self.data.qacc_smooth().to_vec();
        self.data.ctrl_mut().copy_from_slice(&saved_ctrl);
        self.data.qfrc_applied_mut().copy_from_slice(&saved_applied);
        self.data.forward();
        self.kin_stale = false;
        Ok(self.to_slot_order(&acc))
    }

    fn mass_matrix(&mut self) -> Option<Vec<f64>> {
        self.ensure_kinematics();
        let nv = 6 + self.nj;
        let mut full = vec![0.0; nv * nv];
        self.data.full_m(&mut full).ok()?;
        let map = self.dof_map();
        let mut out = vec![0.0; nv * nv];
        for r in 0..nv {
            for c in 0..nv {
                out[r * nv + c] = full[map[r] * nv + map[c]];
            }
        }
        Some(out)
    }

    fn bias_forces(&mut self) -> Option<Vec<f64>> {
        self.ensure_kinematics();
        let b = self.data.qfrc_bias().to_vec();
        Some(self.to_slot_order(&b))
    }
}

impl MujocoEngine {
    /// Our dof index -> MuJoCo dof index.
    fn dof_map(&self) -> Vec<usize> {
        (0..6).chain(self.dadr.iter().copied()).collect()
    }
    fn to_slot_order(&self, x: &[f64]) -> Vec<f64> {
        self.dof_map().into_iter().map(|d| x[d]).collect()
    }
    /// Body names of the model's links, `model.links` order.
    pub fn link_names(&self) -> &[String] {
        &self.link_names
    }
}
