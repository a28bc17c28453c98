//! The bridge's gates and state synthesis, checked against physics rather than against itself:
//! a free-falling IMU measures zero specific force, a resting one +g; a bad-CRC, out-of-limit or
//! non-finite command changes nothing; mode 0 gives no torque; silence leads to damping.

use diff_physics::{make_engine, CommonSettings, EngineKind, State};
use lowlevel_codec::{cdr, crc, Encoding};
use sim_bridge::{BridgeConfig, Defect, SimRobot, Verdict};
use std::collections::BTreeSet;
use unitree_idl::hg;

fn robot(kind: EngineKind, common: CommonSettings, defects: &[Defect]) -> SimRobot {
    let model = robot_model::RobotModel::h1_2().expect("model");
    let engine = make_engine(kind, &model, &common).expect("engine");
    let initial = State::standing(&model);
    SimRobot::new(
        engine,
        model,
        BridgeConfig { defects: defects.iter().copied().collect::<BTreeSet<_>>(), ..BridgeConfig::default() },
        &initial,
    )
    .expect("bridge")
}

/// A command holding the standing pose with the model's gains, one joint moved to `target`.
fn hold(robot: &SimRobot, slot: usize, target: f32) -> hg::LowCmd_ {
    let mut cmd = hg::LowCmd_::default();
    for j in &robot.model().joints {
        let m = &mut cmd.motor_cmd[j.slot];
        m.mode = 1;
        m.q = j.default_q as f32;
        m.kp = j.kp as f32;
        m.kd = j.kd as f32;
    }
    cmd.motor_cmd[slot].q = target;
    crc::seal(&mut cmd);
    cmd
}

fn bytes(cmd: &hg::LowCmd_) -> Vec<u8> {
    cdr::encode(cmd, Encoding::UNITREE)
}

fn run(robot: &mut SimRobot, cmd: Option<&[u8]>, steps: usize, t0: f64) -> f64 {
    let dt = robot.engine().common().timestep;
    let mut t = t0;
    for _ in 0..steps {
        if let Some(b) = cmd {
            robot.handle_lowcmd(b, t);
        }
        robot.step(t).expect("step");
        t += dt;
    }
    t
}

const ELBOW: usize = 16; // left elbow

#[test]
fn free_fall_reads_zero_specific_force_and_rest_reads_g() {
    // Free flight keeps armature: without it, explicit damping (tau = -kd dq of the previous
    // step) is unstable on the light wrist links (kd dt / I > 2).
    let flight = CommonSettings { ground: false, collisions: false, ..CommonSettings::default() };
    let mut r = robot(EngineKind::Mujoco, flight, &[]);
    run(&mut r, None, 200, 0.0);
    let imu = r.imu();
    let norm = imu.accelerometer.iter().map(|a| a * a).sum::<f64>().sqrt();
    // Free fall: specific force 0 up to damping-mode joint torques (internal, they cannot
    // accelerate the centre of mass but do move the torso slightly): far below g.
    assert!(norm < 0.5, "free fall accelerometer {:?}", imu.accelerometer);

    let mut r = robot(EngineKind::Mujoco, CommonSettings::default(), &[]);
    let state = r.lowstate().expect("state");
    // Upright torso at rest on the ground: +g along the IMU z axis.
    let a = state.imu_state.accelerometer;
    assert!((a[2] - 9.81).abs() < 0.05 && a[0].abs() < 0.05 && a[1].abs() < 0.05, "{a:?}");
    let q = state.imu_state.quaternion;
    assert!((q.iter().map(|x| x * x).sum::<f32>() - 1.0).abs() < 1e-5);
    assert!(crc::verify(&state));
}

#[test]
fn valid_command_moves_the_joint_and_bad_crc_does_not() {
    let mut r = robot(EngineKind::Mujoco, CommonSettings::default(), &[]);
    let start = r.engine().state().q[ELBOW];
    let target = start as f32 + 0.4;
    let mut cmd = hold(&r, ELBOW, target);
    let mut corrupted = cmd.clone();
    corrupted.crc ^= 1;
    assert!(matches!(r.handle_command(corrupted.clone(), 0.0), Verdict::BadCrc { .. }));
    let t = run(&mut r, Some(&bytes(&corrupted)), 250, 0.0);
    // Never accepted: bit for bit the same motion as with no command at all.
    let mut silent = robot(EngineKind::Mujoco, CommonSettings::default(), &[]);
    run(&mut silent, None, 250, 0.0);
    assert_eq!(r.engine().state(), silent.engine().state(), "a bad-CRC command changed the motion");
    assert_eq!(r.counters().accepted, 0);
    assert_eq!(r.counters().bad_crc, 251);

    // From a fresh standing start, the same command with a valid CRC takes the elbow there.
    // Stiffer than the default arm gain so that gravity and joint friction leave < 0.05 rad.
    let _ = t;
    r.reset(&State::standing(r.model())).expect("reset");
    cmd.motor_cmd[ELBOW].kp = 150.0;
    cmd.motor_cmd[ELBOW].kd = 4.0;
    crc::seal(&mut cmd);
    run(&mut r, Some(&bytes(&cmd)), 500, 0.0);
    let reached = r.engine().state().q[ELBOW];
    assert!((reached - f64::from(target)).abs() < 0.05, "elbow at {reached}, target {target}");
}

#[test]
fn unsafe_commands_are_rejected_and_not_applied() {
    let mut r = robot(EngineKind::Mujoco, CommonSettings::default(), &[]);
    let base = hold(&r, ELBOW, 0.3);
    let mutate = |f: &dyn Fn(&mut hg::LowCmd_)| {
        let mut c = base.clone();
        f(&mut c);
        crc::seal(&mut c);
        c
    };
    let bad = [
        mutate(&|c| c.motor_cmd[ELBOW].q = f32::NAN),
        mutate(&|c| c.motor_cmd[ELBOW].kp = 1e6),
        mutate(&|c| c.motor_cmd[ELBOW].kd = -1.0),
        mutate(&|c| c.motor_cmd[ELBOW].q = 10.0),
        mutate(&|c| c.motor_cmd[3].tau = f32::INFINITY),
        mutate(&|c| c.motor_cmd[0].mode = 7),
    ];
    for (i, c) in bad.iter().enumerate() {
        assert!(matches!(r.handle_command(c.clone(), 0.0), Verdict::Rejected(_)), "case {i}");
    }
    assert_eq!(r.counters().rejected, bad.len() as u64);
    assert!(!r.command_active(0.0));
    // Malformed bytes are counted, not applied.
    assert!(matches!(r.handle_lowcmd(&bytes(&base)[..100], 0.0), Verdict::Malformed(_)));
    assert_eq!(r.counters().malformed, 1);
}

#[test]
fn mode_zero_gives_no_torque_and_silence_gives_damping() {
    let mut r = robot(EngineKind::Mujoco, CommonSettings::default(), &[]);
    let mut cmd = hold(&r, ELBOW, 0.3);
    cmd.motor_cmd[ELBOW].mode = 0;
    cmd.motor_cmd[ELBOW].tau = 5.0;
    crc::seal(&mut cmd);
    let t = run(&mut r, Some(&bytes(&cmd)), 10, 0.0);
    let elbow = r.model().joints.iter().position(|j| j.slot == ELBOW).expect("elbow");
    assert_eq!(r.applied_torques()[elbow], 0.0);
    // No command for longer than the timeout: damping only (tau = -kd dq), no stiffness.
    let timeout = r.config().command_timeout;
    let steps = (timeout / r.engine().common().timestep) as usize + 5;
    let t = run(&mut r, None, steps, t);
    // One more step: the torques are exactly tau = -kd_default dq of the state before it.
    let before = r.engine().state();
    let damping_steps = r.counters().damping_steps;
    run(&mut r, None, 1, t);
    assert_eq!(r.counters().damping_steps, damping_steps + 1);
    for (i, j) in r.model().joints.iter().enumerate() {
        let expected = (-j.kd * before.dq[i]).clamp(-j.torque_limit, j.torque_limit);
        assert_eq!(r.applied_torques()[i], expected, "{}", j.name);
    }
}

#[test]
fn state_is_fresh_unless_the_switch_is_off() {
    let mut fresh = robot(EngineKind::Mujoco, CommonSettings::default(), &[]);
    let mut stale = robot(EngineKind::Mujoco, CommonSettings::default(), &[Defect::StaleState]);
    let distinct = |r: &mut SimRobot| {
        let mut seen = Vec::new();
        let mut t = 0.0;
        for _ in 0..20 {
            t = run(r, None, 1, t);
            let mut s = r.lowstate().expect("state");
            s.tick = 0;
            s.crc = 0;
            seen.push(cdr::encode(&s, Encoding::UNITREE));
        }
        seen.windows(2).filter(|w| w[0] != w[1]).count()
    };
    assert_eq!(distinct(&mut fresh), 19, "every fresh state differs from the previous one");
    assert!(distinct(&mut stale) <= 2, "stale bridge republishes the same physics state");
}

#[test]
fn initial_hold_keeps_the_robot_standing() {
    let model = robot_model::RobotModel::h1_2().expect("model");
    let engine = make_engine(EngineKind::Mujoco, &model, &CommonSettings::default()).expect("engine");
    let config = BridgeConfig { hold_until_first_command: true, ..BridgeConfig::default() };
    let mut r = SimRobot::new(engine, model.clone(), config, &State::standing(&model)).expect("bridge");
    run(&mut r, None, 1500, 0.0);
    let s = r.engine().state();
    // Still upright after 3 s: pelvis within 5 cm of its start height, torso nearly level.
    assert!((s.base_pos[2] - State::standing(&model).base_pos[2]).abs() < 0.05, "pelvis at {:?}", s.base_pos);
    let rpy = r.imu().rpy;
    assert!(rpy[0].abs() < 0.1 && rpy[1].abs() < 0.1, "torso rpy {rpy:?}");
}

/// Each test-only defect does what it says, and only that: the conformance tests rely on it.
#[test]
fn defects_break_exactly_their_protection() {
    let common = CommonSettings::default;
    // State: no CRC, tick stuck.
    let mut r = robot(EngineKind::Mujoco, common(), &[Defect::NoStateCrc, Defect::TickStuck]);
    run(&mut r, None, 10, 0.0);
    let s = r.lowstate().expect("state");
    assert_eq!((s.crc, s.tick), (0, 0));
    assert!(!crc::verify(&s));

    let elbow_index = |r: &SimRobot| r.model().joints.iter().position(|j| j.slot == ELBOW).expect("elbow");
    // Mode 0 ignored: the disabled motor still produces its PD torque.
    let mut r = robot(EngineKind::Mujoco, common(), &[Defect::IgnoreMode0]);
    let mut cmd = hold(&r, ELBOW, 0.3);
    cmd.motor_cmd[ELBOW].mode = 0;
    crc::seal(&mut cmd);
    run(&mut r, Some(&bytes(&cmd)), 2, 0.0);
    assert!(r.applied_torques()[elbow_index(&r)].abs() > 1.0);

    // Absurd gains applied; a NaN still rejected.
    let mut r = robot(EngineKind::Mujoco, common(), &[Defect::ApplyAbsurdGains]);
    let mut c = hold(&r, ELBOW, 0.3);
    c.motor_cmd[ELBOW].kp = -500.0;
    crc::seal(&mut c);
    assert_eq!(r.handle_command(c, 0.0), Verdict::Accepted);
    let mut c = hold(&r, ELBOW, 0.3);
    c.motor_cmd[ELBOW].q = f32::NAN;
    crc::seal(&mut c);
    assert!(matches!(r.handle_command(c, 0.0), Verdict::Rejected(_)));

    // Limp on a non-finite value: accepted, and every motor gives up.
    let mut r = robot(EngineKind::Mujoco, common(), &[Defect::LimpOnNonFinite]);
    let mut c = hold(&r, ELBOW, 0.3);
    c.motor_cmd[26].q = f32::NAN;
    crc::seal(&mut c);
    assert_eq!(r.handle_command(c.clone(), 0.0), Verdict::Accepted);
    run(&mut r, Some(&bytes(&c)), 1, 0.0);
    assert!(r.applied_torques().iter().all(|t| *t == 0.0));
    let mut gains = hold(&r, ELBOW, 0.3);
    gains.motor_cmd[ELBOW].kp = -500.0;
    crc::seal(&mut gains);
    assert!(matches!(r.handle_command(gains, 0.0), Verdict::Rejected(_)));

    // Undefined on a non-finite value: accepted, and the state turns non-finite while it applies; finite again (and
    // the robot still held) once a finite command returns.
    let mut r = robot(EngineKind::Mujoco, common(), &[Defect::UndefinedOnNonFinite]);
    let mut c = hold(&r, ELBOW, 0.3);
    c.motor_cmd[ELBOW].tau = f32::NAN;
    crc::seal(&mut c);
    assert_eq!(r.handle_command(c.clone(), 0.0), Verdict::Accepted);
    let t = run(&mut r, Some(&bytes(&c)), 1, 0.0);
    let s = r.lowstate().expect("state");
    assert!(!lowlevel_codec::validate::non_finite(&s).is_empty(), "the state of a NaN step is non-finite");
    assert!(s.motor_state[ELBOW].q.is_nan() && s.motor_state[0].tau_est.is_nan());
    assert!(r.engine().state().q.iter().all(|q| q.is_finite()), "the engine itself is never handed NaN");
    let good = hold(&r, ELBOW, 0.3);
    run(&mut r, Some(&bytes(&good)), 1, t);
    let s = r.lowstate().expect("state");
    assert!(lowlevel_codec::validate::non_finite(&s).is_empty(), "finite again after a finite command");
    assert!(r.applied_torques().iter().any(|t| *t != 0.0), "not limp");

    // Keep the last command: no damping step however long the silence.
    let mut r = robot(EngineKind::Mujoco, common(), &[Defect::KeepLastCommand]);
    let c = hold(&r, ELBOW, 0.3);
    let t = run(&mut r, Some(&bytes(&c)), 5, 0.0);
    run(&mut r, None, 500, t);
    assert_eq!(r.counters().damping_steps, 0);

    // Fallen and pinned: lying on its back, a braked elbow stays put while its motor reports the torque of a step.
    let model = robot_model::RobotModel::h1_2().expect("model");
    let engine = make_engine(EngineKind::Mujoco, &model, &common()).expect("engine");
    let defects = [Defect::FallenPinned].into_iter().collect::<BTreeSet<_>>();
    let initial = sim_bridge::lying_on_back(&model);
    let mut r =
        SimRobot::new(engine, model, BridgeConfig { defects, ..BridgeConfig::default() }, &initial).expect("bridge");
    let t = run(&mut r, None, 500, 0.0);
    let rpy = r.imu().rpy;
    assert!(rpy[1].abs() > 1.2, "lying: torso pitch {rpy:?}");
    let i = elbow_index(&r);
    let before = r.engine().state().q[i];
    let mut step = hold(&r, ELBOW, before as f32 + 0.3);
    for j in r.model().joints.iter() {
        // Hold where it lies rather than the standing pose.
        step.motor_cmd[j.slot].q =
            r.engine().state().q[r.model().joints.iter().position(|k| k.slot == j.slot).unwrap_or(0)] as f32;
    }
    step.motor_cmd[ELBOW].q = before as f32 + 0.3;
    step.motor_cmd[ELBOW].kp = 40.0;
    crc::seal(&mut step);
    run(&mut r, Some(&bytes(&step)), 250, t);
    let after = r.engine().state().q[i];
    assert!((after - before).abs() < 0.02, "pinned elbow moved {before} -> {after}");
    assert!(r.applied_torques()[i] > 8.0, "motor torque {}", r.applied_torques()[i]);
}

/// The sport state (`rt/sportmodestate`) against free-fall kinematics: after t seconds without ground the pelvis has
/// dropped g t²/2 and moves down at g t, its IMU reads no specific force; at rest it reads +g and the pelvis
/// orientation; the bytes decode to the same message.
#[test]
fn sport_state_is_the_pelvis_pose_by_free_fall_and_rest() {
    let flight = CommonSettings { ground: false, collisions: false, ..CommonSettings::default() };
    let g = -flight.gravity[2];
    let mut r = robot(EngineKind::Mujoco, flight, &[]);
    let s0 = r.sport_mode_state();
    let t = run(&mut r, None, 100, 0.0);
    let s = r.sport_mode_state();
    let drop = f64::from(s0.position[2] - s.position[2]);
    assert!((drop - 0.5 * g * t * t).abs() < 0.01, "dropped {drop} m in {t} s");
    assert!((f64::from(s.velocity[2]) + g * t).abs() < 0.05, "vz {}", s.velocity[2]);
    assert!((f64::from(s.body_height) - f64::from(s.position[2])).abs() < 1e-6);
    let stamp = f64::from(s.stamp.sec) + 1e-9 * f64::from(s.stamp.nanosec);
    assert!((stamp - r.engine().time()).abs() < 1e-6, "stamp {stamp}");
    let a = s.imu_state.accelerometer;
    assert!(a.iter().map(|x| x * x).sum::<f32>().sqrt() < 0.5, "free-fall accelerometer {a:?}");

    let r = robot(EngineKind::Mujoco, CommonSettings::default(), &[]);
    let s = r.sport_mode_state();
    let a = s.imu_state.accelerometer;
    assert!((f64::from(a[2]) - g).abs() < 0.05 && a[0].abs() < 0.05 && a[1].abs() < 0.05, "{a:?}");
    let pelvis = r.engine().state().base_quat;
    for (q, p) in s.imu_state.quaternion.iter().zip(pelvis) {
        assert!((f64::from(*q) - p).abs() < 1e-6, "{:?} vs {pelvis:?}", s.imu_state.quaternion);
    }
    let back = lowlevel_codec::decode::<unitree_idl::go::SportModeState_>(&r.sport_mode_state_bytes()).expect("decode");
    assert_eq!(back.value.position, s.position);
}
