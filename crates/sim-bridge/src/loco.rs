//! The locomotion service of Unitree's SDK, simulated: what `LocoClient` (`unitree::robot::h1::LocoClient`,
//! `g1::LocoClient`) talks to over RPC, answered from inside the simulator and executed by a built-in walking
//! policy. Transport-free: `ulab sim` hands it decoded [`Request_`]s and publishes the [`Response_`]s.
//!
//! # Services
//!
//! Every [`LocoApi`] variant given to [`LocoService::new`] is served with its own service name, API version and
//! ids (`unitree_idl::api::loco::H1`: `loco`, `2.0.0.0`, 8001..8203; `G1`: `sport`, `1.0.0.0`, 7001..7105); they
//! share one robot and one state. Answers use the SDK's status codes (`unitree_idl::api::status`, H1's
//! `loco::status`).
//!
//! # States (what `SetFsmId` selects) and what each one drives
//!
//! | FSM id | SDK call | here |
//! |---|---|---|
//! | 0 | `ZeroTorque()` | every motor disabled (mode 0): no torque, the robot collapses |
//! | 1 | `Damp()` | damping only: `tau = -kd dq` with the model's damping gains, no stiffness |
//! | 2 | `StandUp()` | the standing pose held stiffly ([`crate::stand_target`]); it keeps a standing robot up, it does not get a fallen one up |
//! | 204 | `Start()` | the walking policy, at its own rate (50 Hz), from the simulated robot's state: torso IMU converted to the pelvis through the waist joint (`policy_runtime::imu`), joint angles and velocities; velocity command from `SetVelocity` / `Move` |
//!
//! The simulator starts in state 2 when it holds the standing pose until the first command (`ulab sim`'s
//! default), else in state 1. Any other FSM id is answered `UT_ROBOT_LOCO_ERR_INVALID_FSM_ID` (8302).
//!
//! * `SetVelocity(vx, vy, omega, duration)` (`Move`, `StopMove` = zero velocity): only in state 204 (else 8301,
//!   `LOCOSTATE_NOT_AVAILABLE`); the velocity holds for `duration` seconds of simulated time, then zero.
//!   Components are clamped to the policy's training ranges ([`COMMAND_LIMITS`]); non-finite values, a velocity
//!   of other than 3 components or a negative duration are `UT_ROBOT_ERR_SERVER_API_PARAMETER` (3204).
//! * `SetBalanceMode` (0 = `BalanceStand`, 1 = `ContinuousGait`) is stored and reported; the built-in policy
//!   keeps stepping in place at zero velocity in both modes (it always does).
//! * `GetFsmId`, `GetFsmMode` (0: not walking or zero velocity command, 1: walking with a non-zero command; a
//!   definition of this simulator, the SDK documents none), `GetBalanceMode`.
//! * H1 odometry: `EnableOdom`, `DisableOdom`, `GetOdom` = `{"x", "y", "z": yaw}` of the pelvis in the world
//!   frame (ground truth; 8303 `ODOMSTATE_NOT_AVAILABLE` until enabled).
//! * Stand and swing heights, gait phase, target positions and leases are not simulated:
//!   `UT_ROBOT_ERR_SERVER_API_NOT_IMPL` (3203), as for every unknown id.
//!
//! # Low-level commands take over
//!
//! As on the robot put into debug mode, a command received on `rt/lowcmd` overrides the service: once one is
//! fresh (accepted within the command timeout), the service stops driving the robot (its internal command is
//! cleared) and reports `LOCOSTATE_NOT_AVAILABLE` (8301) to state queries and moves; when the low-level
//! commands stop, the bridge damps the robot (its timeout rule), and a `SetFsmId` call takes the robot back.
//! While low-level commands are fresh, `SetFsmId` is refused with 8301.
//!
//! # Released by the motion switcher
//!
//! The motion switcher ([`crate::motion_switcher`]) can release this service ([`LocoService::release`]): the robot
//! is damped (FSM 1) and every call but the API version is answered `LOCOSTATE_NOT_AVAILABLE` (8301), as from a
//! service that is not running, until the motion switcher selects it again ([`LocoService::select`]).

use crate::{stand_target, SimRobot};
use diff_physics::PdTarget;
use policy_runtime::{Controller, PolicyController, PolicyError, RobotObservation};
use serde_json::{json, Value};
use unitree_idl::api::loco::{fsm, status as loco_status, LocoApi};
use unitree_idl::api::{internal, status, Request_, Response_};
use unitree_idl::{h1_2, hg};

/// Velocity command limits `(vx, vy, omega)` (m/s, m/s, rad/s): the training ranges of unitree_rl_gym's walking
/// policies (`legged_gym/envs/base/legged_robot_config.py`, `commands.ranges`: `lin_vel_x`, `lin_vel_y`,
/// `ang_vel_yaw` all `[-1, 1]`; the H1-2 config does not override them).
pub const COMMAND_LIMITS: [f64; 3] = [1.0, 1.0, 1.0];

/// The shipped unitree_rl_gym H1-2 walking policy's spec (`robots/h1_2/policies/unitree_rl_gym_lstm.toml`); its
/// weights come from `${ULAB_SHARED}/reference/policies/`.
pub const DEFAULT_POLICY_SPEC: &str = include_str!("../../../robots/h1_2/policies/unitree_rl_gym_lstm.toml");

/// What the service drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Mode {
    /// FSM 0: motors disabled.
    ZeroTorque,
    /// FSM 1: damping.
    Damp,
    /// FSM 2: standing pose held.
    Stand,
    /// FSM 204: the walking policy.
    Walk,
    /// Low-level commands on `rt/lowcmd` have taken over.
    LowLevel,
}

impl Mode {
    /// The FSM id `GetFsmId` reports (none while low-level commands drive the robot).
    pub fn fsm_id(self) -> Option<i64> {
        match self {
            Mode::ZeroTorque => Some(fsm::ZERO_TORQUE),
            Mode::Damp => Some(fsm::DAMP),
            Mode::Stand => Some(fsm::STAND_UP),
            Mode::Walk => Some(fsm::START),
            Mode::LowLevel => None,
        }
    }
}

/// Counters for the status line and the summary.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct LocoCounters {
    /// Requests handled (any service, any id).
    pub requests: u64,
    /// Requests answered with a non-zero status.
    pub refused: u64,
    /// Policy steps run.
    pub policy_steps: u64,
    /// Times low-level commands took the robot over.
    pub takeovers: u64,
}

/// The walking policy and its schedule.
#[derive(Debug)]
struct Walker {
    controller: PolicyController,
    period: f64,
    /// Calls since `Start` (the deploy scripts' time is calls × period, the current call included).
    calls: u64,
    /// Simulated time of the next policy step.
    next_due: f64,
}

/// The simulated locomotion service (see the module docs).
#[derive(Debug)]
pub struct LocoService {
    apis: Vec<LocoApi>,
    mode: Mode,
    walker: Option<Walker>,
    /// Why walking is unavailable (no policy loaded), for answers and logs.
    no_walker: Option<String>,
    velocity: [f64; 3],
    /// Simulated time until which `velocity` holds.
    velocity_until: f64,
    balance_mode: i64,
    odom_enabled: bool,
    /// Released by the motion switcher: not driving the robot, refusing calls.
    released: bool,
    counters: LocoCounters,
    /// Notable events since the last [`LocoService::take_events`] (mode changes, takeovers, policy failures).
    events: Vec<String>,
}

/// Why a request was refused: an SDK status code.
type Refusal = i32;

impl LocoService {
    /// A service answering on every variant of `apis`. `policy` walks the robot in state 204 (`Err`: why there is
    /// none; `Start` and moves are then refused with 8301). `holding`: the bridge holds the standing pose until the
    /// first command (the initial state is then 2, else 1).
    pub fn new(apis: Vec<LocoApi>, policy: Result<PolicyController, String>, holding: bool) -> Self {
        let (walker, no_walker) = match policy {
            Ok(controller) => {
                let period = controller.period();
                (Some(Walker { controller, period, calls: 0, next_due: 0.0 }), None)
            }
            Err(why) => (None, Some(why)),
        };
        LocoService {
            apis,
            mode: if holding { Mode::Stand } else { Mode::Damp },
            walker,
            no_walker,
            velocity: [0.0; 3],
            velocity_until: 0.0,
            balance_mode: 0,
            odom_enabled: false,
            released: false,
            counters: LocoCounters::default(),
            events: Vec::new(),
        }
    }

    /// The served variants.
    pub fn apis(&self) -> &[LocoApi] {
        &self.apis
    }

    /// Current state.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The velocity command in force at `sim_time`.
    pub fn velocity(&self, sim_time: f64) -> [f64; 3] {
        if self.mode == Mode::Walk && sim_time < self.velocity_until {
            self.velocity
        } else {
            [0.0; 3]
        }
    }

    pub fn counters(&self) -> &LocoCounters {
        &self.counters
    }

    /// Whether the motion switcher has released the service (see the module docs).
    pub fn released(&self) -> bool {
        self.released
    }

    /// The motion switcher's `ReleaseMode`: the service stops driving the robot, which is damped (FSM 1), and
    /// refuses calls until [`Self::select`]. Low-level commands that are fresh keep the robot (nothing to damp;
    /// when they stop the bridge damps it by its timeout rule). `Err`: an SDK status code.
    pub fn release(&mut self, robot: &mut SimRobot, now: f64) -> Result<(), i32> {
        self.observe_takeover(robot, now);
        if self.released {
            return Ok(());
        }
        if self.mode != Mode::LowLevel && self.mode != Mode::Damp {
            robot.set_internal_command(Some(damping_command(robot))).map_err(|findings| {
                self.events.push(format!("damping command refused by the limit checks: {findings:?}"));
                status::ERR_SERVER_INTERNAL
            })?;
            self.events.push(format!("released by the motion switcher: FSM {} -> 1 (Damp)", self.fsm_text()));
            self.mode = Mode::Damp;
        } else {
            self.events.push(format!("released by the motion switcher (FSM {})", self.fsm_text()));
        }
        self.velocity = [0.0; 3];
        self.velocity_until = 0.0;
        self.released = true;
        Ok(())
    }

    /// The motion switcher's `SelectMode`: a released service takes the robot back in the standing state (FSM 2;
    /// it holds a standing robot up, it does not raise a fallen one). While low-level commands are fresh it is
    /// selected but they keep the robot, as they override it anyway (a `SetFsmId` takes it back once they stop).
    /// A service that is not released is left as it is. `Err`: an SDK status code.
    pub fn select(&mut self, robot: &mut SimRobot, sim_time: f64, now: f64) -> Result<(), i32> {
        self.observe_takeover(robot, now);
        if !self.released {
            return Ok(());
        }
        if !robot.command_active(now) {
            self.set_fsm(fsm::STAND_UP, robot, sim_time, now)?;
        }
        self.events.push("selected by the motion switcher".to_owned());
        self.released = false;
        Ok(())
    }

    /// Events since the last call (for the status line).
    pub fn take_events(&mut self) -> Vec<String> {
        std::mem::take(&mut self.events)
    }

    /// Answers one request that arrived for `api` (one of [`Self::apis`]); `None` when the caller asked for no
    /// reply. `sim_time` is the simulated time, `now` the bridge's clock (for the low-level command timeout).
    pub fn handle(
        &mut self,
        api: &LocoApi,
        request: &Request_,
        robot: &mut SimRobot,
        sim_time: f64,
        now: f64,
    ) -> Option<Response_> {
        self.counters.requests += 1;
        let result = self.dispatch(api, request.header.identity.api_id, &request.parameter, robot, sim_time, now);
        crate::rpc::answer(request, result, &mut self.counters.refused)
    }

    fn dispatch(
        &mut self,
        api: &LocoApi,
        id: i64,
        parameter: &str,
        robot: &mut SimRobot,
        sim_time: f64,
        now: f64,
    ) -> Result<String, Refusal> {
        self.observe_takeover(robot, now);
        let data = |v: Value| v.to_string();
        if id == internal::API_VERSION {
            return Ok(api.version.to_owned());
        }
        if self.released {
            return Err(loco_status::ERR_LOCOSTATE_NOT_AVAILABLE);
        }
        if id == api.get_fsm_id {
            let fsm = self.mode.fsm_id().ok_or(loco_status::ERR_LOCOSTATE_NOT_AVAILABLE)?;
            return Ok(data(json!({ "data": fsm })));
        }
        if id == api.get_fsm_mode {
            if self.mode == Mode::LowLevel {
                return Err(loco_status::ERR_LOCOSTATE_NOT_AVAILABLE);
            }
            let moving = self.velocity(sim_time).iter().any(|v| *v != 0.0);
            return Ok(data(json!({ "data": i64::from(moving) })));
        }
        if id == api.get_balance_mode {
            return Ok(data(json!({ "data": self.balance_mode })));
        }
        if id == api.set_balance_mode {
            match int_data(parameter)? {
                m @ (0 | 1) => {
                    self.balance_mode = m;
                    return Ok(String::new());
                }
                _ => return Err(status::ERR_SERVER_API_PARAMETER),
            }
        }
        if id == api.set_fsm_id {
            let target = int_data(parameter)?;
            self.set_fsm(target, robot, sim_time, now)?;
            return Ok(String::new());
        }
        if id == api.set_velocity {
            let (velocity, duration) = velocity_command(parameter)?;
            if self.mode != Mode::Walk {
                return Err(loco_status::ERR_LOCOSTATE_NOT_AVAILABLE);
            }
            for (k, v) in velocity.iter().enumerate() {
                self.velocity[k] = v.clamp(-COMMAND_LIMITS[k], COMMAND_LIMITS[k]);
            }
            self.velocity_until = sim_time + duration;
            return Ok(String::new());
        }
        if let Some([enable, disable, get]) = api.odom {
            if id == enable || id == disable {
                self.odom_enabled = id == enable;
                return Ok(String::new());
            }
            if id == get {
                if !self.odom_enabled {
                    return Err(loco_status::ERR_ODOMSTATE_NOT_AVAILABLE);
                }
                let s = robot.engine().state();
                let [w, x, y, z] = s.base_quat;
                let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
                return Ok(data(json!({ "x": s.base_pos[0], "y": s.base_pos[1], "z": yaw })));
            }
        }
        Err(status::ERR_SERVER_API_NOT_IMPL)
    }

    /// Switches state on `SetFsmId(target)`.
    fn set_fsm(&mut self, target: i64, robot: &mut SimRobot, sim_time: f64, now: f64) -> Result<(), Refusal> {
        let mode = match target {
            fsm::ZERO_TORQUE => Mode::ZeroTorque,
            fsm::DAMP => Mode::Damp,
            fsm::STAND_UP => Mode::Stand,
            fsm::START => Mode::Walk,
            _ => return Err(loco_status::ERR_INVALID_FSM_ID),
        };
        if robot.command_active(now) {
            // Low-level commands own the robot until they stop.
            return Err(loco_status::ERR_LOCOSTATE_NOT_AVAILABLE);
        }
        if mode == Mode::Walk && self.walker.is_none() {
            self.events.push(format!(
                "Start refused: no walking policy ({})",
                self.no_walker.as_deref().unwrap_or("not loaded")
            ));
            return Err(loco_status::ERR_LOCOSTATE_NOT_AVAILABLE);
        }
        if mode == self.mode {
            return Ok(());
        }
        let command = match mode {
            Mode::ZeroTorque => Some(hg::LowCmd_::default()),
            Mode::Damp => Some(damping_command(robot)),
            Mode::Stand => Some(target_command(robot, &stand_target(robot.model()))),
            Mode::Walk => {
                if let Some(w) = self.walker.as_mut() {
                    w.controller.reset();
                    w.calls = 0;
                    w.next_due = sim_time;
                    // Until its first step (before the next physics step), hold the policy's default pose.
                    Some(target_command(robot, &w.controller.default_target()))
                } else {
                    None
                }
            }
            Mode::LowLevel => None,
        };
        robot.set_internal_command(command).map_err(|findings| {
            self.events.push(format!("internal command refused by the limit checks: {findings:?}"));
            status::ERR_SERVER_INTERNAL
        })?;
        self.velocity = [0.0; 3];
        self.velocity_until = 0.0;
        self.events.push(format!("FSM {} -> {target} ({mode:?})", self.fsm_text()));
        self.mode = mode;
        Ok(())
    }

    fn fsm_text(&self) -> String {
        self.mode.fsm_id().map_or("low-level".to_owned(), |f| f.to_string())
    }

    /// A fresh low-level command takes the robot over.
    fn observe_takeover(&mut self, robot: &mut SimRobot, now: f64) {
        if self.mode != Mode::LowLevel && robot.command_active(now) {
            // Clearing cannot fail (nothing to check).
            let _ = robot.set_internal_command(None);
            self.counters.takeovers += 1;
            self.events.push(format!("low-level commands on rt/lowcmd took over from FSM {}", self.fsm_text()));
            self.mode = Mode::LowLevel;
            self.velocity = [0.0; 3];
            self.velocity_until = 0.0;
        }
    }

    /// Runs before every physics step at simulated time `sim_time` (bridge clock `now`): notices a low-level
    /// takeover, and in state 204 runs the policy when its period has come and sets its targets as the internal
    /// command. A policy failure damps the robot.
    pub fn control(&mut self, robot: &mut SimRobot, sim_time: f64, now: f64) {
        self.observe_takeover(robot, now);
        if self.mode != Mode::Walk {
            return;
        }
        let command = self.velocity(sim_time);
        let Some(w) = self.walker.as_mut() else { return };
        if sim_time + 1e-9 < w.next_due {
            return;
        }
        w.calls += 1;
        w.next_due += w.period;
        let result = policy_step(w, robot, command);
        self.counters.policy_steps += 1;
        let failure = match result {
            Ok(cmd) => robot.set_internal_command(Some(cmd)).err().map(|f| format!("limit checks refused {f:?}")),
            Err(e) => Some(e.to_string()),
        };
        if let Some(why) = failure {
            self.events.push(format!("walking policy failed ({why}): damping"));
            let _ = robot.set_internal_command(Some(damping_command(robot)));
            self.mode = Mode::Damp;
        }
    }
}

/// One policy step from the robot's current state.
fn policy_step(w: &mut Walker, robot: &SimRobot, command: [f64; 3]) -> Result<hg::LowCmd_, PolicyError> {
    let state = robot.engine().state();
    let imu = robot.imu();
    let time = w.calls as f64 * w.period;
    let obs = RobotObservation::from_torso_imu(time, imu.quaternion, imu.gyroscope, state.q, state.dq, command)?;
    let target = w.controller.act(&obs)?;
    Ok(target_command(robot, &target))
}

/// An hg LowCmd carrying PD targets for every joint of the model (mode 1), position targets clamped into the
/// joint ranges the limit checks use.
fn target_command(robot: &SimRobot, target: &PdTarget) -> hg::LowCmd_ {
    let mut cmd = hg::LowCmd_::default();
    for (i, joint) in robot.model().joints.iter().enumerate() {
        let Some(limits) = h1_2::JOINTS.get(joint.slot) else { continue };
        let m = &mut cmd.motor_cmd[joint.slot];
        m.mode = 1;
        m.q = (target.q_des[i] as f32).clamp(limits.lower, limits.upper);
        m.dq = (target.dq_des[i] as f32).clamp(-limits.speed_limit, limits.speed_limit);
        m.tau = (target.tau_ff[i] as f32).clamp(-limits.torque_limit, limits.torque_limit);
        m.kp = (target.kp[i] as f32).clamp(0.0, h1_2::KP_MAX);
        m.kd = (target.kd[i] as f32).clamp(0.0, h1_2::KD_MAX);
    }
    cmd
}

/// Damping on every joint: no stiffness, the model's damping gains (what the bridge's timeout damping applies).
fn damping_command(robot: &SimRobot) -> hg::LowCmd_ {
    let model = robot.model();
    let mut target = PdTarget::hold_standing(model);
    target.kp.iter_mut().for_each(|k| *k = 0.0);
    target_command(robot, &target)
}

/// `{"data": <integer>}`, the parameter of `SetFsmId` / `SetBalanceMode` (`go2::JsonizeDataInt`).
fn int_data(parameter: &str) -> Result<i64, Refusal> {
    let v: Value = serde_json::from_str(parameter).map_err(|_| status::ERR_SERVER_API_PARAMETER)?;
    v.get("data").and_then(Value::as_i64).ok_or(status::ERR_SERVER_API_PARAMETER)
}

/// `{"velocity": [vx, vy, omega], "duration": d}`, the parameter of `SetVelocity` (`JsonizeVelocityCommand`).
fn velocity_command(parameter: &str) -> Result<([f64; 3], f64), Refusal> {
    let bad = status::ERR_SERVER_API_PARAMETER;
    let v: Value = serde_json::from_str(parameter).map_err(|_| bad)?;
    let list = v.get("velocity").and_then(Value::as_array).ok_or(bad)?;
    let numbers: Vec<f64> = list.iter().map(Value::as_f64).collect::<Option<_>>().ok_or(bad)?;
    let velocity: [f64; 3] = numbers.try_into().map_err(|_| bad)?;
    let duration = v.get("duration").and_then(Value::as_f64).ok_or(bad)?;
    if velocity.iter().all(|x| x.is_finite()) && duration.is_finite() && duration >= 0.0 {
        Ok((velocity, duration))
    } else {
        Err(bad)
    }
}
