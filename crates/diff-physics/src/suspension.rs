//! The suspension stand: the robot's pelvis held still high above the ground, as on a gantry. One definition
//! used by `ulab sim --hang` (through [`Suspended`], re-exported as `sim_bridge::suspension`) and by the gap
//! diagnosis's rig (`gap_diagnosis::plant`), so a recording of the hung simulator and the diagnosing plant are the
//! same physical system. It lives with the engines so that the diagnosis needs no simulator bridge, and it works in
//! every engine that takes an external base wrench ([`Engine::set_base_wrench`]: MuJoCo, Rapier multibody, Bullet,
//! DART), so that the gap benchmark's reference plant can be another engine than the diagnosing one.
//!
//! The stand is a stiff spring-damper on the pelvis (1e7 N/m, 1e6 N·m/rad) with weight feed-forward, applied
//! as an external wrench at the pelvis origin, on a pelvis made [`PELVIS_SCALE`] times heavier (a rigid
//! mount), so the spring can be stiff, is integrated stably, and the limbs' reactions barely move the pelvis
//! (well under a millimetre). No ground and no collisions: the feet hang in the air.
use crate::mujoco::{MujocoEngine, MujocoSettings};
use crate::{CommonSettings, Contact, Energy, Engine, EngineError, EngineKind, LinkPose, State};
use nalgebra::{Quaternion, UnitQuaternion};
use robot_model::RobotModel;

/// Pelvis position on the stand (m).
pub const BASE_POS: [f64; 3] = [0.0, 0.0, 2.0];
/// Mass and inertia multiplier of the pelvis on the stand.
pub const PELVIS_SCALE: f64 = 1000.0;
/// Linear stiffness (N/m) and damping (N·s/m) of the stand.
pub const K_LIN: f64 = 1e7;
pub const D_LIN: f64 = 1e5;
/// Rotational stiffness (N·m/rad) and damping (N·m·s/rad) of the stand.
pub const K_ROT: f64 = 1e6;
pub const D_ROT: f64 = 3e3;

/// The model as built on the stand: the pelvis (root link) [`PELVIS_SCALE`] times heavier.
pub fn suspended_model(model: &RobotModel) -> RobotModel {
    let mut m = model.clone();
    if let Some(root) = m.links.iter_mut().find(|l| l.parent_joint.is_none()) {
        root.inertial.mass *= PELVIS_SCALE;
        root.inertial.inertia *= PELVIS_SCALE;
    }
    m
}

/// Engine settings on the stand: no ground, no collisions (the rest as in the full robot).
pub fn settings(timestep: f64) -> CommonSettings {
    CommonSettings { timestep, ground: false, collisions: false, ..CommonSettings::default() }
}

/// The robot on the stand at these joint angles and speeds, pelvis at rest at [`BASE_POS`], upright.
pub fn state_on_stand(q: &[f64], dq: &[f64]) -> State {
    State {
        base_pos: BASE_POS,
        base_quat: [1.0, 0.0, 0.0, 0.0],
        q: q.to_vec(),
        base_lin_vel: [0.0; 3],
        base_ang_vel: [0.0; 3],
        dq: dq.to_vec(),
    }
}

/// Wrench of the stand on the pelvis for `state` (`[force; torque]`, world frame, at the pelvis origin: what
/// [`Engine::set_base_wrench`] takes); `weight` (N) is the suspended model's total weight, fed forward.
pub fn base_wrench(state: &State, weight: f64) -> [f64; 6] {
    let q = UnitQuaternion::from_quaternion(Quaternion::new(
        state.base_quat[0],
        state.base_quat[1],
        state.base_quat[2],
        state.base_quat[3],
    ));
    // The rotation vector of the pelvis (target: identity) is the same in the world and pelvis frames; the angular
    // velocity is reported in the pelvis frame.
    let rotvec = q.scaled_axis();
    let w_world = q * nalgebra::Vector3::from(state.base_ang_vel);
    let mut f = [0.0; 6];
    for k in 0..3 {
        f[k] = -K_LIN * (state.base_pos[k] - BASE_POS[k]) - D_LIN * state.base_lin_vel[k];
        f[3 + k] = -K_ROT * rotvec[k] - D_ROT * w_world[k];
    }
    f[2] += weight;
    f
}

/// Sets the stand's wrench on `engine` for its current state (before each step).
pub fn hold<E: Engine + ?Sized>(engine: &mut E, weight: f64) -> Result<(), EngineError> {
    let s = engine.state();
    engine.set_base_wrench(base_wrench(&s, weight))
}

/// An engine with the robot on the stand: an [`Engine`] whose every step first applies the stand's wrench. Built
/// from the unmodified model (the pelvis is made heavier inside, and reported so by `link_masses`). `E` is the
/// engine's type: MuJoCo ([`Suspended::new`], `Send`, what the diagnosis steps on worker threads), or any engine
/// chosen at run time ([`Suspended::with_engine`]).
#[derive(Debug)]
pub struct Suspended<E: Engine + ?Sized = dyn Engine> {
    engine: Box<E>,
    weight: f64,
}

/// MuJoCo on the stand (`ulab sim --hang`, the diagnosing rig).
pub type SuspendedMujoco = Suspended<MujocoEngine>;

impl Suspended<MujocoEngine> {
    /// MuJoCo on the stand with these MuJoCo settings (e.g. its integrator).
    pub fn new(model: &RobotModel, timestep: f64, specific: &MujocoSettings) -> Result<Self, EngineError> {
        let rigged = suspended_model(model);
        let engine = MujocoEngine::new(&rigged, &settings(timestep), specific)?;
        Ok(Suspended { engine: Box::new(engine), weight: rigged.total_mass() * robot_model::GRAVITY_EARTH })
    }
}

impl<E: Engine + 'static> Suspended<E> {
    /// The same stand with the engine's type erased.
    pub fn into_dyn(self) -> Suspended {
        Suspended { engine: self.engine, weight: self.weight }
    }
}

impl Suspended<dyn Engine> {
    /// Any engine on the stand, with its default specific settings; an engine that cannot take a base wrench is
    /// refused here ([`EngineError::Unsupported`]), not at its first step.
    pub fn with_engine(kind: EngineKind, model: &RobotModel, timestep: f64) -> Result<Self, EngineError> {
        let rigged = suspended_model(model);
        let mut engine = crate::make_engine(kind, &rigged, &settings(timestep))?;
        engine.set_base_wrench([0.0; 6])?;
        Ok(Suspended { engine, weight: rigged.total_mass() * robot_model::GRAVITY_EARTH })
    }
}

impl<E: Engine + ?Sized> Engine for Suspended<E> {
    fn name(&self) -> &'static str {
        self.engine.name()
    }
    fn version(&self) -> String {
        self.engine.version()
    }
    fn settings(&self) -> serde_json::Value {
        let mut s = self.engine.settings();
        s["suspension"] = serde_json::json!({
            "base_pos": BASE_POS, "pelvis_scale": PELVIS_SCALE, "k_lin": K_LIN, "d_lin": D_LIN, "k_rot": K_ROT, "d_rot": D_ROT,
        });
        s
    }
    fn common(&self) -> &CommonSettings {
        self.engine.common()
    }
    fn reset(&mut self, state: &State) -> Result<(), EngineError> {
        self.engine.reset(state)
    }
    fn step(&mut self, tau: &[f64]) -> Result<(), EngineError> {
        hold(self.engine.as_mut(), self.weight)?;
        self.engine.step(tau)
    }
    fn state(&self) -> State {
        self.engine.state()
    }
    fn time(&self) -> f64 {
        self.engine.time()
    }
    fn contacts(&self) -> Vec<Contact> {
        self.engine.contacts()
    }
    fn energy(&mut self) -> Energy {
        self.engine.energy()
    }
    fn link_masses(&self) -> Vec<f64> {
        self.engine.link_masses()
    }
    fn link_poses(&mut self) -> Vec<LinkPose> {
        self.engine.link_poses()
    }
    fn com(&mut self) -> [f64; 3] {
        self.engine.com()
    }
    fn joint_axes(&mut self) -> Vec<[f64; 3]> {
        self.engine.joint_axes()
    }
    fn joint_limits(&self) -> Vec<(f64, f64)> {
        self.engine.joint_limits()
    }
    fn generalized_acceleration(&mut self, f: &[f64]) -> Result<Vec<f64>, EngineError> {
        self.engine.generalized_acceleration(f)
    }
    fn mass_matrix(&mut self) -> Option<Vec<f64>> {
        self.engine.mass_matrix()
    }
    fn bias_forces(&mut self) -> Option<Vec<f64>> {
        self.engine.bias_forces()
    }
}
