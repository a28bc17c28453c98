//! The motion-switcher service of Unitree's SDK, simulated: what `MotionSwitcherClient`
//! (`unitree::robot::b2::MotionSwitcherClient`, unitree_sdk2py `comm.motion_switcher`) talks to over RPC. Unitree's
//! low-level examples for the G1 and H1-2 ask it which motion service holds the motors (`CheckMode`) and release
//! that service (`ReleaseMode`) until none does, before they send their first LowCmd. Transport-free: `ulab sim`
//! hands it decoded [`Request_`]s with the locomotion service it switches ([`LocoService`]) and publishes the
//! [`Response_`]s.
//!
//! Service `motion_switcher`, API version `1.0.0.1`, ids 1001..1005 (`unitree_idl::api::motion_switcher`, from
//! Unitree's `motion_switcher_api.hpp`). The simulator has one motion service, its locomotion service; while that
//! is selected `CheckMode` names it [`ACTIVE_NAME`] (`"ai"`), the name a G1 answers in Unitree's own issue tracker
//! (unitreerobotics/unitree_sdk2_python issue 156: `{'form': '0', 'name': 'ai'}` at API version 1.0.0.1) and the
//! one H1 programs select; no public source gives the H1-2's own answer.
//!
//! | id | SDK call | here |
//! |---|---|---|
//! | 1001 | `CheckMode(form, name)` | `{"form": "0", "name": N}`: `N` = `"ai"` while the locomotion service is selected, `""` once released |
//! | 1002 | `SelectMode(name)` | parameter `{"name": N}`; `N` must be `"ai"` (else 7004, unsupported mode name). A released locomotion service takes the robot back standing (FSM 2, the standing pose held; it does not raise a fallen robot); one not released is left as it is |
//! | 1003 | `ReleaseMode()` | the locomotion service stops driving the robot: the robot is **damped** (FSM 1) and every locomotion call but the API version is answered 8301 until `SelectMode`; `CheckMode` then answers an empty name |
//! | 1004 | `SetSilent(flag)` | parameter `{"silent": bool}`, stored; on the robot it keeps the motion services off from the next boot, which a simulator run never reaches, so it changes nothing else |
//! | 1005 | `GetSilent()` | `{"silent": bool}`, the stored flag (false at start) |
//!
//! Any other id is answered `UT_ROBOT_ERR_SERVER_API_NOT_IMPL` (3203), as by the locomotion service; a parameter
//! that is not the JSON the call takes is `UT_ROBOT_ERR_SERVER_API_PARAMETER` (3204), the SDK's generic code (the
//! G1 documentation also lists a service code 7001, "request parameter error", without saying when it is used).
//!
//! # Why a released robot is damped
//!
//! Releasing leaves no motion service commanding the motors; the simulated robot then does what it does without any
//! command: the bridge's damping (`tau = -kd dq`, its command-timeout rule, what Unitree's damp mode does), the
//! state the robot is in when a low-level controller's commands stop. It is the safe state for a controller to take
//! over from: no stiffness fights its first command. A standing robot therefore sinks to the ground once released,
//! as on the real robot, which the SDK's examples have hung on a gantry first.
//!
//! # Low-level commands
//!
//! As before, a fresh `rt/lowcmd` command overrides the locomotion service whether it is released or not (see
//! [`crate::loco`]); `CheckMode` reports which service is *selected*, not who drives the motors at this instant.

use crate::loco::LocoService;
use crate::SimRobot;
use serde_json::{json, Value};
use unitree_idl::api::motion_switcher::{self as api, status as ms_status};
use unitree_idl::api::{internal, status, Request_, Response_};

/// The name `CheckMode` reports while the locomotion service is selected (see the module docs).
pub const ACTIVE_NAME: &str = "ai";

/// The robot's form `CheckMode` reports: `"0"`, the standard form (Unitree's documentation: `"1"` is the Go2's
/// wheel-foot form).
pub const FORM: &str = "0";

/// Counters for the summary.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct SwitcherCounters {
    /// Requests handled (any id).
    pub requests: u64,
    /// Requests answered with a non-zero status.
    pub refused: u64,
    /// `ReleaseMode` calls that released the locomotion service.
    pub releases: u64,
    /// `SelectMode` calls that took a released locomotion service back.
    pub selections: u64,
}

/// The simulated motion switcher (see the module docs).
#[derive(Debug, Default)]
pub struct MotionSwitcherService {
    silent: bool,
    counters: SwitcherCounters,
}

/// Why a request was refused: an SDK status code.
type Refusal = i32;

impl MotionSwitcherService {
    pub fn new() -> Self {
        Self::default()
    }

    /// The stored `SetSilent` flag.
    pub fn silent(&self) -> bool {
        self.silent
    }

    pub fn counters(&self) -> &SwitcherCounters {
        &self.counters
    }

    /// The name `CheckMode` answers: [`ACTIVE_NAME`] while `loco` is selected, empty once released.
    pub fn active_name(loco: &LocoService) -> &'static str {
        if loco.released() {
            ""
        } else {
            ACTIVE_NAME
        }
    }

    /// Answers one request on `rt/api/motion_switcher/request`, switching `loco`; `None` when the caller asked for
    /// no reply. `sim_time` is the simulated time, `now` the bridge's clock (for the low-level command timeout).
    pub fn handle(
        &mut self,
        request: &Request_,
        loco: &mut LocoService,
        robot: &mut SimRobot,
        sim_time: f64,
        now: f64,
    ) -> Option<Response_> {
        self.counters.requests += 1;
        let result = self.dispatch(request.header.identity.api_id, &request.parameter, loco, robot, sim_time, now);
        crate::rpc::answer(request, result, &mut self.counters.refused)
    }

    fn dispatch(
        &mut self,
        id: i64,
        parameter: &str,
        loco: &mut LocoService,
        robot: &mut SimRobot,
        sim_time: f64,
        now: f64,
    ) -> Result<String, Refusal> {
        match id {
            internal::API_VERSION => Ok(api::VERSION.to_owned()),
            api::CHECK_MODE => Ok(json!({ "form": FORM, "name": Self::active_name(loco) }).to_string()),
            api::SELECT_MODE => {
                let name = string_field(parameter, "name")?;
                if name != ACTIVE_NAME {
                    return Err(ms_status::ERR_UNSUPPORTED_MODE_NAME);
                }
                let was_released = loco.released();
                loco.select(robot, sim_time, now)?;
                if was_released {
                    self.counters.selections += 1;
                }
                Ok(String::new())
            }
            api::RELEASE_MODE => {
                let was_released = loco.released();
                loco.release(robot, now)?;
                if !was_released {
                    self.counters.releases += 1;
                }
                Ok(String::new())
            }
            api::SET_SILENT => {
                self.silent = bool_field(parameter, "silent")?;
                Ok(String::new())
            }
            api::GET_SILENT => Ok(json!({ "silent": self.silent }).to_string()),
            _ => Err(status::ERR_SERVER_API_NOT_IMPL),
        }
    }
}

/// `parameter` as a JSON object.
fn object(parameter: &str) -> Result<serde_json::Map<String, Value>, Refusal> {
    match serde_json::from_str(parameter) {
        Ok(Value::Object(map)) => Ok(map),
        _ => Err(status::ERR_SERVER_API_PARAMETER),
    }
}

/// The string member `key` of the JSON object `parameter` (`JsonizeModeName::name`).
fn string_field(parameter: &str, key: &str) -> Result<String, Refusal> {
    match object(parameter)?.remove(key) {
        Some(Value::String(s)) => Ok(s),
        _ => Err(status::ERR_SERVER_API_PARAMETER),
    }
}

/// The boolean member `key` of the JSON object `parameter` (`JsonizeSilent::silent`).
fn bool_field(parameter: &str, key: &str) -> Result<bool, Refusal> {
    object(parameter)?.get(key).and_then(Value::as_bool).ok_or(status::ERR_SERVER_API_PARAMETER)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::loco::Mode;
    use crate::BridgeConfig;
    use diff_physics::{make_engine, CommonSettings, EngineKind, State};
    use unitree_idl::api::loco;

    struct Rig {
        robot: SimRobot,
        loco: LocoService,
        switcher: MotionSwitcherService,
        t: f64,
        next_id: i64,
    }

    /// A standing H1-2 on MuJoCo holding the standing pose, both locomotion APIs served without a walking policy.
    fn rig() -> Rig {
        let model = robot_model::RobotModel::h1_2().expect("model");
        let initial = State::standing(&model);
        let engine = make_engine(EngineKind::Mujoco, &model, &CommonSettings::default()).expect("engine");
        let config = BridgeConfig { hold_until_first_command: true, ..BridgeConfig::default() };
        let robot = SimRobot::new(engine, model, config, &initial).expect("bridge");
        let loco = LocoService::new(vec![loco::H1, loco::G1], Err("no policy in this test".to_owned()), true);
        Rig { robot, loco, switcher: MotionSwitcherService::new(), t: 0.0, next_id: 1 }
    }

    fn request(id: i64, api_id: i64, parameter: &str) -> Request_ {
        let mut req = Request_::default();
        req.header.identity.id = id;
        req.header.identity.api_id = api_id;
        req.parameter = parameter.to_owned();
        req
    }

    impl Rig {
        /// One motion-switcher call as the SDK's client makes it; (status, data).
        fn call(&mut self, api_id: i64, parameter: &str) -> (i32, String) {
            let req = request(self.next_id, api_id, parameter);
            self.next_id += 1;
            let t = self.t;
            let resp = self.switcher.handle(&req, &mut self.loco, &mut self.robot, t, t).expect("a reply");
            assert_eq!(resp.header.identity, req.header.identity, "the response echoes the request's identity");
            (resp.header.status.code, resp.data)
        }

        /// One call to the H1 locomotion API.
        fn loco_call(&mut self, api_id: i64, parameter: &str) -> (i32, String) {
            let req = request(self.next_id, api_id, parameter);
            self.next_id += 1;
            let t = self.t;
            let resp = self.loco.handle(&loco::H1, &req, &mut self.robot, t, t).expect("a reply");
            (resp.header.status.code, resp.data)
        }

        fn check_mode(&mut self) -> Value {
            let (code, data) = self.call(api::CHECK_MODE, "{}");
            assert_eq!(code, 0, "CheckMode");
            serde_json::from_str(&data).expect("CheckMode answers JSON")
        }

        fn run(&mut self, seconds: f64) {
            let dt = self.robot.engine().common().timestep;
            for _ in 0..(seconds / dt).round() as usize {
                let t = self.t;
                self.loco.control(&mut self.robot, t, t);
                self.robot.step(t).expect("physics step");
                self.t += dt;
            }
        }

        /// Whether the robot is driven by pure damping: an internal command with no stiffness and the model's
        /// damping gains on every joint.
        fn damped(&self) -> bool {
            let Some(cmd) = self.robot.internal_command() else { return false };
            self.robot.model().joints.iter().all(|j| {
                let m = &cmd.motor_cmd[j.slot];
                m.mode == 1 && m.kp == 0.0 && m.kd > 0.0
            })
        }
    }

    #[test]
    fn check_mode_names_the_locomotion_service_until_released() {
        let mut r = rig();
        assert_eq!(r.call(internal::API_VERSION, ""), (0, "1.0.0.1".to_owned()));
        assert_eq!(r.check_mode(), json!({ "form": "0", "name": "ai" }));
        assert_eq!(r.call(api::RELEASE_MODE, "{}"), (0, String::new()));
        assert_eq!(r.check_mode(), json!({ "form": "0", "name": "" }));
        // Released again: still released, still answered.
        assert_eq!(r.call(api::RELEASE_MODE, ""), (0, String::new()));
        assert_eq!(r.check_mode()["name"], "");
        assert_eq!(r.switcher.counters().releases, 1);
    }

    #[test]
    fn release_damps_the_robot_and_refuses_locomotion_calls() {
        let mut r = rig();
        assert_eq!(r.loco.mode(), Mode::Stand);
        let standing = r.robot.engine().state().base_pos[2];
        assert_eq!(r.call(api::RELEASE_MODE, "{}").0, 0);
        assert_eq!(r.loco.mode(), Mode::Damp);
        assert!(r.damped(), "released: damping only, {:?}", r.robot.internal_command().map(|c| &c.motor_cmd[3]));
        assert_eq!(r.loco_call(loco::H1.get_fsm_id, "").0, loco::status::ERR_LOCOSTATE_NOT_AVAILABLE);
        assert_eq!(
            r.loco_call(loco::H1.set_fsm_id, &json!({ "data": 2 }).to_string()).0,
            loco::status::ERR_LOCOSTATE_NOT_AVAILABLE,
            "a released service does not stand the robot up"
        );
        assert_eq!(r.loco_call(internal::API_VERSION, ""), (0, "2.0.0.0".to_owned()));
        // Without stiffness the robot sinks: over 2 s the pelvis falls by more than a quarter of its standing
        // height (a held stand keeps it within millimetres; a fall takes it most of the way to the ground).
        r.run(2.0);
        let after = r.robot.engine().state().base_pos[2];
        eprintln!("released: pelvis {standing:.3} m -> {after:.3} m in 2 s");
        assert!(after < 0.75 * standing, "pelvis at {after:.3} m after release (standing {standing:.3} m)");
    }

    #[test]
    fn select_takes_the_robot_back_standing() {
        let mut r = rig();
        let standing = r.robot.engine().state().base_pos[2];
        // Selecting the active service changes nothing.
        assert_eq!(r.call(api::SELECT_MODE, r#"{"name": "ai"}"#), (0, String::new()));
        assert_eq!(r.loco.mode(), Mode::Stand);
        assert_eq!(r.switcher.counters().selections, 0);
        assert_eq!(r.call(api::RELEASE_MODE, "{}").0, 0);
        assert_eq!(r.call(api::SELECT_MODE, r#"{"name": "normal"}"#).0, ms_status::ERR_UNSUPPORTED_MODE_NAME);
        assert_eq!(r.check_mode()["name"], "", "an unsupported name selects nothing");
        assert_eq!(r.call(api::SELECT_MODE, r#"{"name": "ai"}"#), (0, String::new()));
        assert_eq!(r.check_mode()["name"], "ai");
        assert_eq!(r.loco.mode(), Mode::Stand);
        assert!(!r.damped(), "standing: the pose is held stiffly");
        assert_eq!(r.loco_call(loco::H1.get_fsm_id, ""), (0, json!({ "data": 2 }).to_string()));
        assert_eq!(r.switcher.counters().selections, 1);
        // Selected straight after the release, the robot is still up and the held pose keeps it there.
        r.run(1.0);
        let after = r.robot.engine().state().base_pos[2];
        eprintln!("selected: pelvis {standing:.3} m -> {after:.3} m in 1 s");
        assert!((after - standing).abs() < 0.05, "pelvis at {after:.3} m after select (standing {standing:.3} m)");
    }

    #[test]
    fn silent_flag_is_stored() {
        let mut r = rig();
        assert_eq!(r.call(api::GET_SILENT, "{}"), (0, json!({ "silent": false }).to_string()));
        assert_eq!(r.call(api::SET_SILENT, r#"{"silent": true}"#), (0, String::new()));
        assert!(r.switcher.silent());
        assert_eq!(r.call(api::GET_SILENT, "{}"), (0, json!({ "silent": true }).to_string()));
        assert_eq!(r.call(api::SET_SILENT, r#"{"silent": false}"#).0, 0);
        assert_eq!(r.call(api::GET_SILENT, ""), (0, json!({ "silent": false }).to_string()));
        assert_eq!(r.check_mode()["name"], "ai", "silence takes effect at boot only");
    }

    #[test]
    fn unknown_ids_and_bad_parameters_are_refused() {
        let mut r = rig();
        assert_eq!(r.call(1006, "{}").0, status::ERR_SERVER_API_NOT_IMPL);
        assert_eq!(r.call(loco::H1.get_fsm_id, "").0, status::ERR_SERVER_API_NOT_IMPL);
        for bad in ["", "{}", "[]", r#"{"silent": "yes"}"#, r#"{"silent": 1}"#, "{"] {
            assert_eq!(r.call(api::SET_SILENT, bad).0, status::ERR_SERVER_API_PARAMETER, "SetSilent({bad})");
        }
        for bad in ["", "{}", r#"{"name": 1}"#, r#"["ai"]"#] {
            assert_eq!(r.call(api::SELECT_MODE, bad).0, status::ERR_SERVER_API_PARAMETER, "SelectMode({bad})");
        }
        assert!(!r.switcher.silent(), "a refused SetSilent stores nothing");
        assert_eq!(r.switcher.counters().refused, 12);
        assert_eq!(r.switcher.counters().requests, 12);
    }

    #[test]
    fn noreply_requests_get_no_answer_but_act() {
        let mut r = rig();
        let mut req = request(1, api::RELEASE_MODE, "{}");
        req.header.policy.noreply = true;
        assert!(r.switcher.handle(&req, &mut r.loco, &mut r.robot, 0.0, 0.0).is_none());
        assert!(r.loco.released());
    }

    #[test]
    fn low_level_commands_keep_the_robot_across_release_and_select() {
        let mut r = rig();
        // Damping about the current pose (a command well inside every limit).
        let q = r.robot.engine().state().q;
        let mut cmd = unitree_idl::hg::LowCmd_::default();
        for (i, j) in r.robot.model().joints.iter().enumerate() {
            let m = &mut cmd.motor_cmd[j.slot];
            m.mode = 1;
            m.q = q[i] as f32;
            m.kd = 1.0;
        }
        lowlevel_codec::crc::seal(&mut cmd);
        assert_eq!(r.robot.handle_command(cmd, 0.0), crate::Verdict::Accepted);
        assert_eq!(r.call(api::RELEASE_MODE, "{}").0, 0);
        assert_eq!(r.loco.mode(), Mode::LowLevel, "low-level commands override the service");
        assert!(r.robot.internal_command().is_none());
        assert_eq!(r.call(api::SELECT_MODE, r#"{"name": "ai"}"#).0, 0);
        assert_eq!(r.check_mode()["name"], "ai");
        assert_eq!(r.loco.mode(), Mode::LowLevel, "fresh low-level commands keep the robot after SelectMode");
        assert!(r.robot.internal_command().is_none());
    }
}
