//! `ulab sim`'s motion switcher called by Unitree's Python SDK through its own RPC client machinery
//! (`unitree_sdk2py.rpc.client.Client`; the client declared with the service name, API version and ids of Unitree's
//! `motion_switcher_api.hpp`, tests/clients/sdk_motion_switcher_client.py), as Unitree's low-level examples call it
//! before they take the motors: CheckMode names the locomotion service, ReleaseMode stops it and the standing robot
//! is damped (it sinks: its pelvis height from `rt/sportmodestate` drops, over simulated time), SelectMode stands
//! the locomotion service back up. Needs no walking policy (the robot only stands and is damped).

use crate::common;

use common::{client_beside_sim, lease_domain, sim_summary, tail, RealtimeSlot};
use serde_json::{json, Value};
use std::time::Duration;

/// Seconds of simulated time the client watches the released robot.
const RELEASED_SECONDS: f64 = 3.0;

#[test]
fn python_sdk_motion_switcher_releases_and_selects() {
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let released = RELEASED_SECONDS.to_string();
    let run = client_beside_sim(
        &["sim", "--engine", "mujoco", "--domain", &domain.arg(), "--loco-api", "h1"],
        "sdk_motion_switcher_client.py",
        &["--domain", &domain.arg(), "--released-seconds", &released],
        Duration::from_secs(300),
    );
    let report = run.report("motion switcher");
    // A call whose response was lost is sent again by the client (the SDK's best-effort response reader drops
    // responses on a loaded machine); a server that does not answer fails the answers below (3104, timeout).
    let retried = report["retried_apis"].as_array().map_or(0, Vec::len);
    if retried > 0 {
        eprintln!("calls sent again after a lost response: {}", report["retried_apis"]);
    }

    // The answers, as the SDK's client returned them (after waiting for the services to be discovered).
    let version = |k: &str| (report[k][0].clone(), report[k][1].clone());
    assert_eq!(version("api_version"), (json!(0), json!("1.0.0.1")), "{report}");
    assert_eq!(version("loco_api_version"), (json!(0), json!("2.0.0.0")), "{report}");
    assert_eq!(report["check_initial"], json!([0, {"form": "0", "name": "ai"}]), "{report}");
    assert_eq!(report["fsm_initial"], json!([0, 2]), "the locomotion service holds the standing pose");
    assert_eq!(report["release"], 0, "{report}");
    assert_eq!(report["check_released"], json!([0, {"form": "0", "name": ""}]), "{report}");
    assert_eq!(report["fsm_released"][0], 8301, "a released locomotion service answers nothing else: {report}");
    assert_eq!(report["silent_initial"], json!([0, {"silent": false}]));
    assert_eq!(report["set_silent_true"], 0);
    assert_eq!(report["silent_true"], json!([0, {"silent": true}]));
    assert_eq!(report["set_silent_false"], 0);
    assert_eq!(report["silent_false"], json!([0, {"silent": false}]));
    assert_eq!(report["select_unsupported"], 7004, "unsupported mode name: {report}");
    assert_eq!(report["check_after_unsupported"], json!([0, {"form": "0", "name": ""}]));
    assert_eq!(report["select"], 0, "{report}");
    assert_eq!(report["check_selected"], json!([0, {"form": "0", "name": "ai"}]), "{report}");
    assert_eq!(report["fsm_selected"], json!([0, 2]), "SelectMode takes the robot back standing: {report}");
    assert_eq!(report["unknown"], 3203, "UT_ROBOT_ERR_SERVER_API_NOT_IMPL: {report}");

    // The behaviour: released, the robot is damped (no stiffness) and sinks. A held stand keeps the pelvis within
    // millimetres of its height; a damped robot ends on the ground, most of its standing height lower. A drop of a
    // quarter of the standing height in the watched span tells the two apart with wide margins on both sides.
    let h0 = report["height_initial"].as_f64().expect("initial pelvis height");
    let h1 = report["height_released"].as_f64().expect("pelvis height after release");
    eprintln!("pelvis {h0:.3} m standing, {h1:.3} m after {RELEASED_SECONDS} s released");
    assert!(h0 > 0.8, "not standing at the start: pelvis at {h0:.3} m");
    assert!(h1 < 0.75 * h0, "released but not damped: pelvis at {h1:.3} m from {h0:.3} m");

    // The bridge's own account.
    let summary =
        sim_summary(&run.sim_err).unwrap_or_else(|| panic!("no summary from ulab sim:\n{}", tail(&run.sim_err)));
    let loco = &summary["loco"];
    assert_eq!(loco["malformed_requests"], 0, "{summary}");
    assert_eq!(loco["mode"], "Stand", "{summary}");
    assert_eq!(loco["released"], false, "{summary}");
    let switcher = &loco["motion_switcher"];
    assert_eq!(switcher["name"], "ai", "{summary}");
    assert_eq!(switcher["counters"]["releases"], 1, "{summary}");
    assert_eq!(switcher["counters"]["selections"], 1, "{summary}");
    assert_eq!(summary["counters"]["accepted"], 0, "no low-level command was sent: {summary}");
    assert!(run.sim_err.contains("released by the motion switcher"), "{}", tail(&run.sim_err));
}

/// `--no-motion-switcher`: nothing answers the SDK's motion-switcher client on the wire, while the locomotion service
/// of the same simulator does (the positive control: the participant is discovered and serves RPC), and the
/// simulator's summary has no motion switcher. The SDK's CheckMode finds no reader of `rt/api/motion_switcher/request`
/// within its timeout and does not send (3102, RPC_ERR_CLIENT_SEND); a served switcher whose response was lost
/// would give 3104 instead.
#[test]
fn sim_motion_switcher_can_be_turned_off() {
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let run = client_beside_sim(
        &["sim", "--engine", "mujoco", "--domain", &domain.arg(), "--loco-api", "h1", "--no-motion-switcher"],
        "sdk_motion_switcher_client.py",
        &["--domain", &domain.arg(), "--absent"],
        Duration::from_secs(300),
    );
    let report = run.report("motion switcher");
    assert_eq!(report["loco_api_version"][0], json!(0), "the locomotion service answers: {report}");
    assert_eq!(report["check_absent"], json!([3102, null]), "RPC_ERR_CLIENT_SEND, no reader: {report}");
    let summary = sim_summary(&run.sim_err).unwrap_or_else(|| panic!("no summary:\n{}", tail(&run.sim_err)));
    assert_eq!(summary["loco"]["motion_switcher"], Value::Null, "{summary}");
    assert!(!run.sim_err.contains("released by the motion switcher"), "{}", tail(&run.sim_err));
}
