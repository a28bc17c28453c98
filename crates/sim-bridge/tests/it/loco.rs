//! The locomotion service in process (no DDS): requests as Unitree's `LocoClient` sends them (H1 API ids and
//! JSON parameters from `h1_loco_client.hpp`), the shipped unitree_rl_gym H1-2 walking policy, physics in MuJoCo
//! and Rapier multibody. The robot must walk at the commanded velocity (measured on the physics state, against
//! simulated time), turn at the commanded rate, stop, and hand over to low-level commands.
//!
//! The tolerances come from this policy's own tracking, measured here and printed: on MuJoCo, 0.5 m/s forward
//! gives 0.40-0.45 m/s over the steady window (the LSTM was trained in Isaac Gym and under-tracks), 0.5 rad/s
//! of yaw about 0.5 rad/s. The checks allow a band around that rather than around the command.
//! Skips without `$ULAB_SHARED` (the policy's weights live there).

use diff_physics::{make_engine, CommonSettings, EngineKind, State};
use lowlevel_codec::crc;
use policy_runtime::{PolicyController, PolicySpec};
use serde_json::Value;
use sim_bridge::loco::{LocoService, Mode, DEFAULT_POLICY_SPEC};
use sim_bridge::{BridgeConfig, SimRobot};
use unitree_idl::api::{self, loco, status};
use unitree_idl::hg;

struct Rig {
    robot: SimRobot,
    loco: LocoService,
    t: f64,
    next_id: i64,
}

fn shared_available() -> bool {
    let ok = std::env::var("ULAB_SHARED").is_ok_and(|v| !v.is_empty());
    if !ok {
        eprintln!("SKIPPED: ULAB_SHARED is not set (the walking policy's weights live there)");
    }
    ok
}

fn rig(kind: EngineKind) -> Rig {
    let model = robot_model::RobotModel::h1_2().expect("model");
    let engine = make_engine(kind, &model, &CommonSettings::default()).expect("engine");
    let config = BridgeConfig { hold_until_first_command: true, ..BridgeConfig::default() };
    let robot = SimRobot::new(engine, model, config, &State::standing(&robot_model::RobotModel::h1_2().expect("m")))
        .expect("bridge");
    let spec = PolicySpec::from_toml_str(DEFAULT_POLICY_SPEC, std::path::Path::new(".")).expect("spec");
    let policy = PolicyController::from_spec(spec).expect("policy");
    Rig { robot, loco: LocoService::new(vec![loco::H1, loco::G1], Ok(policy), true), t: 0.0, next_id: 1 }
}

impl Rig {
    /// One call as the SDK's client makes it: identity (id, api_id), empty lease, priority 0, reply wanted.
    fn call(&mut self, api_id: i64, parameter: &str) -> (i32, String) {
        self.call_on(&loco::H1, api_id, parameter)
    }

    /// The same on another served variant (the G1 API on `rt/api/sport`).
    fn call_on(&mut self, api: &loco::LocoApi, api_id: i64, parameter: &str) -> (i32, String) {
        let mut req = api::Request_::default();
        req.header.identity.id = self.next_id;
        req.header.identity.api_id = api_id;
        req.parameter = parameter.to_owned();
        self.next_id += 1;
        let t = self.t;
        let resp = self.loco.handle(api, &req, &mut self.robot, t, t).expect("a reply");
        assert_eq!(resp.header.identity, req.header.identity, "the response echoes the request's identity");
        (resp.header.status.code, resp.data)
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

    /// Pelvis (x, y, yaw) as `GetOdom` reports it.
    fn odom(&mut self) -> [f64; 3] {
        let (code, data) = self.call(8203, "");
        assert_eq!(code, 0, "GetOdom");
        let v: Value = serde_json::from_str(&data).expect("odometry JSON");
        ["x", "y", "z"].map(|k| v[k].as_f64().expect("number"))
    }

    fn fsm_id(&mut self) -> (i32, Option<i64>) {
        let (code, data) = self.call(loco::H1.get_fsm_id, "");
        (code, serde_json::from_str::<Value>(&data).ok().and_then(|v| v["data"].as_i64()))
    }
}

fn set_velocity(v: [f64; 3], duration: f64) -> String {
    serde_json::json!({ "velocity": v, "duration": duration }).to_string()
}

fn fsm(id: i64) -> String {
    serde_json::json!({ "data": id }).to_string()
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI
}

/// Walk 0.5 m/s forward, turn at 0.5 rad/s, stop: measured speeds over the steady part of each phase.
fn walk_turn_stop(kind: EngineKind) -> [f64; 4] {
    let mut r = rig(kind);
    let h1 = loco::H1;
    assert_eq!(r.call(api::internal::API_VERSION, ""), (0, "2.0.0.0".to_owned()));
    assert_eq!(r.fsm_id(), (0, Some(2)), "starts holding the standing pose");
    assert_eq!(
        r.call(h1.set_velocity, &set_velocity([0.5, 0.0, 0.0], 1.0)).0,
        loco::status::ERR_LOCOSTATE_NOT_AVAILABLE
    );
    assert_eq!(r.call(8203, "").0, loco::status::ERR_ODOMSTATE_NOT_AVAILABLE, "odometry off until enabled");
    assert_eq!(r.call(8201, "").0, 0);
    assert_eq!(r.call(h1.set_fsm_id, &fsm(204)), (0, String::new()));
    assert_eq!(r.fsm_id(), (0, Some(204)));
    r.run(1.0);

    // Forward: 2 s to settle into the gait, then 3 s measured.
    assert_eq!(r.call(h1.set_velocity, &set_velocity([0.5, 0.0, 0.0], loco::CONTINUOUS_MOVE_DURATION)).0, 0);
    r.run(2.0);
    let (a, ta) = (r.odom(), r.t);
    r.run(3.0);
    let (b, tb) = (r.odom(), r.t);
    let heading = a[2];
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let forward = (dx * heading.cos() + dy * heading.sin()) / (tb - ta);
    let lateral = (-dx * heading.sin() + dy * heading.cos()) / (tb - ta);

    // Turn on the spot.
    assert_eq!(r.call(h1.set_velocity, &set_velocity([0.0, 0.0, 0.5], loco::CONTINUOUS_MOVE_DURATION)).0, 0);
    r.run(2.0);
    let (c, tc) = (r.odom(), r.t);
    r.run(3.0);
    let (d, td) = (r.odom(), r.t);
    let yaw_rate = wrap(d[2] - c[2]) / (td - tc);

    // StopMove = SetVelocity(0, 0, 0) with the default duration 1 s.
    assert_eq!(r.call(h1.set_velocity, &set_velocity([0.0, 0.0, 0.0], 1.0)).0, 0);
    r.run(2.0);
    let (e, te) = (r.odom(), r.t);
    r.run(2.0);
    let (f, tf) = (r.odom(), r.t);
    let drift = ((f[0] - e[0]).hypot(f[1] - e[1])) / (tf - te);
    let s = r.robot.engine().state();
    eprintln!(
        "{kind:?}: forward {forward:.3} m/s (lateral {lateral:.3}) at 0.5 commanded; yaw {yaw_rate:.3} rad/s at 0.5; \
         drift after stop {drift:.3} m/s; pelvis height {:.3} m; {} policy steps",
        s.base_pos[2],
        r.loco.counters().policy_steps
    );
    assert!(s.base_pos[2] > 0.8, "{kind:?}: the robot fell (pelvis at {:.3} m)", s.base_pos[2]);
    // Policy steps: one per 20 ms of simulated time walked (1 + 5 + 5 + 4 s).
    let steps = r.loco.counters().policy_steps as f64;
    assert!((steps - 15.0 / 0.02).abs() <= 2.0, "{kind:?}: {steps} policy steps in 15 s");

    // Damp, then an invalid FSM id.
    assert_eq!(r.call(h1.set_fsm_id, &fsm(1)).0, 0);
    assert_eq!(r.fsm_id(), (0, Some(1)));
    assert_eq!(r.call(h1.set_fsm_id, &fsm(7)).0, loco::status::ERR_INVALID_FSM_ID);
    assert_eq!(
        r.call(h1.set_velocity, "{\"velocity\": [0.5, 0.0], \"duration\": 1.0}").0,
        status::ERR_SERVER_API_PARAMETER
    );
    assert_eq!(r.call(h1.set_stand_height, &fsm(1)).0, status::ERR_SERVER_API_NOT_IMPL);
    [forward, lateral, yaw_rate, drift]
}

/// Checks against the measured tracking of this policy (module docs): forward speed 0.35-0.6 m/s for 0.5, lateral
/// drift below 0.15 m/s, yaw rate 0.35-0.65 rad/s for 0.5, after StopMove less than 0.1 m/s of travel.
fn check(kind: EngineKind) {
    if !shared_available() {
        return;
    }
    let [forward, lateral, yaw_rate, drift] = walk_turn_stop(kind);
    assert!((0.35..=0.6).contains(&forward), "{kind:?}: forward {forward:.3} m/s for 0.5 commanded");
    assert!(lateral.abs() < 0.15, "{kind:?}: lateral {lateral:.3} m/s");
    assert!((0.35..=0.65).contains(&yaw_rate), "{kind:?}: yaw rate {yaw_rate:.3} rad/s for 0.5 commanded");
    assert!(drift < 0.1, "{kind:?}: still moving at {drift:.3} m/s after StopMove");
}

#[test]
fn mujoco_walks_turns_and_stops() {
    check(EngineKind::Mujoco);
}

#[test]
fn rapier_multibody_walks_turns_and_stops() {
    check(EngineKind::RapierMultibody);
}

/// A command on `rt/lowcmd` takes the robot from the walking policy; the service refuses to take it back while
/// such commands are fresh and takes it back once they stop.
#[test]
fn low_level_commands_take_over() {
    if !shared_available() {
        return;
    }
    let mut r = rig(EngineKind::Mujoco);
    let h1 = loco::H1;
    assert_eq!(r.call(h1.set_fsm_id, &fsm(204)).0, 0);
    r.run(0.5);
    assert!(r.robot.internal_command().is_some());
    // A low-level controller holding the default pose with the model's gains.
    let mut cmd = hg::LowCmd_::default();
    for j in &r.robot.model().joints {
        let m = &mut cmd.motor_cmd[j.slot];
        m.mode = 1;
        m.q = j.default_q as f32;
        m.kp = j.kp as f32;
        m.kd = j.kd as f32;
    }
    crc::seal(&mut cmd);
    let t = r.t;
    assert_eq!(r.robot.handle_command(cmd, t), sim_bridge::Verdict::Accepted);
    r.run(0.02);
    assert_eq!(r.loco.mode(), Mode::LowLevel);
    assert!(r.robot.internal_command().is_none(), "the service no longer drives the robot");
    assert_eq!(r.fsm_id().0, loco::status::ERR_LOCOSTATE_NOT_AVAILABLE);
    assert_eq!(r.call(h1.set_fsm_id, &fsm(2)).0, loco::status::ERR_LOCOSTATE_NOT_AVAILABLE, "refused while fresh");
    assert_eq!(r.loco.counters().takeovers, 1);
    // The low-level controller goes silent: past the timeout the service may take the robot back.
    r.run(r.robot.config().command_timeout + 0.05);
    assert_eq!(r.call(h1.set_fsm_id, &fsm(2)).0, 0);
    assert_eq!(r.fsm_id(), (0, Some(2)));
    assert!(r.robot.internal_command().is_some());
}

/// The G1 variant (`g1_loco_api.hpp`: service `sport`, version 1.0.0.0, ids 7001..7105) drives the same robot and
/// state: Start through the G1 ids is seen by the H1 ids, a G1 move walks the robot forward (judged on the physics
/// state over simulated time, with the band of the H1 checks), odometry is not part of the G1 API.
#[test]
fn g1_api_drives_the_same_service() {
    if !shared_available() {
        return;
    }
    let mut r = rig(EngineKind::Mujoco);
    let g1 = loco::G1;
    assert_eq!(r.call_on(&g1, api::internal::API_VERSION, ""), (0, "1.0.0.0".to_owned()));
    assert_eq!(r.call_on(&g1, g1.set_fsm_id, &fsm(204)).0, 0);
    assert_eq!(r.fsm_id(), (0, Some(204)), "the H1 ids see the state the G1 ids set");
    assert_eq!(r.call_on(&g1, 8203, "").0, status::ERR_SERVER_API_NOT_IMPL, "no odometry in the G1 API");
    r.run(1.0);
    assert_eq!(r.call_on(&g1, g1.set_velocity, &set_velocity([0.5, 0.0, 0.0], loco::CONTINUOUS_MOVE_DURATION)).0, 0);
    r.run(2.0);
    let (a, ta) = (r.robot.engine().state().base_pos, r.t);
    r.run(3.0);
    let (b, tb) = (r.robot.engine().state().base_pos, r.t);
    let speed = (b[0] - a[0]).hypot(b[1] - a[1]) / (tb - ta);
    eprintln!("G1 API on MuJoCo: {speed:.3} m/s for 0.5 commanded");
    assert!((0.35..=0.6).contains(&speed), "G1 API: {speed:.3} m/s for 0.5 commanded");
    assert_eq!(r.call_on(&g1, g1.set_fsm_id, &fsm(1)).0, 0);
    assert_eq!(r.fsm_id(), (0, Some(1)));
}
