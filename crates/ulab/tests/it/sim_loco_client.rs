//! `ulab sim`'s locomotion service driven by Unitree's Python SDK through its own RPC client machinery
//! (`unitree_sdk2py.rpc.client.Client`, the base of every SDK LocoClient; the H1 client declared with the service
//! name, API version and ids of Unitree's `h1_loco_api.hpp`, tests/clients/sdk_loco_client.py): the simulated
//! H1-2 walks forward, turns and stops on MuJoCo and on Rapier multibody, driven by the shipped unitree_rl_gym
//! walking policy inside the simulator.
//!
//! Judged on the robot's own clock: speeds are odometry differences over LowState tick differences (simulated
//! time), never wall time. The bands are those of `crates/sim-bridge/tests/it/loco.rs`, set from this policy's own
//! tracking measured in process on MuJoCo (0.5 m/s commanded: about 0.4 m/s; 0.5 rad/s: about 0.5 rad/s), and
//! the walked distance must match the commanded velocity within them. Skips without `$ULAB_SHARED` (the policy's
//! weights live there).

use crate::common;

use common::{client_beside_sim, lease_domain, sim_summary, tail, RealtimeSlot};
use serde_json::Value;
use std::time::Duration;

fn speed(report: &Value, phase: &str) -> ([f64; 3], [f64; 3], f64) {
    let p = &report[phase];
    let odom = |i: usize| -> [f64; 3] {
        let v = p["odom"][i].as_array().unwrap_or_else(|| panic!("{phase}: odometry {i}: {p}"));
        [0, 1, 2].map(|k| v[k].as_f64().expect("number"))
    };
    let ticks = (p["ticks"][0].as_f64().expect("tick"), p["ticks"][1].as_f64().expect("tick"));
    (odom(0), odom(1), (ticks.1 - ticks.0) / 1000.0)
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI
}

fn check_engine(engine: &str) {
    if std::env::var("ULAB_SHARED").map_or(true, |v| v.is_empty()) {
        eprintln!("SKIPPED: ULAB_SHARED is not set (the walking policy's weights live there)");
        return;
    }
    let _slot = RealtimeSlot::acquire();
    let domain = lease_domain();
    let run = client_beside_sim(
        &["sim", "--engine", engine, "--domain", &domain.arg(), "--loco-api", "h1"],
        "sdk_loco_client.py",
        &["--domain", &domain.arg(), "--speed", "0.5", "--yaw-rate", "0.5"],
        Duration::from_secs(600),
    );
    let report = run.report(engine);

    // Status codes as the SDK's client returned them. A call whose response was lost is sent once more by the
    // client (the SDK's best-effort response reader; `_Call` in the client); more than one such loss in a run is
    // not a lost datagram but a server that does not answer.
    let retried = report["retried_apis"].as_array().map_or(0, Vec::len);
    if retried > 0 {
        eprintln!("{engine}: calls sent again after a lost response: {}", report["retried_apis"]);
    }
    assert!(retried <= 1, "{engine}: {retried} calls without a response: {report}");
    let codes = &report["codes"];
    assert_eq!(report["api_version"], serde_json::json!([0, "2.0.0.0"]), "{engine}");
    assert_eq!(codes["fsm_initial"], serde_json::json!([0, 2]), "{engine}: starts standing (FSM 2)");
    assert_eq!(codes["move_before_start"], 8301, "{engine}: a move before Start is LOCOSTATE_NOT_AVAILABLE");
    for k in ["enable_odom", "start", "forward", "turn", "stop", "damp"] {
        assert_eq!(codes[k], 0, "{engine}: {k}: {report}");
    }
    assert_eq!(codes["fsm_walking"], serde_json::json!([0, 204]), "{engine}");
    assert_eq!(codes["fsm_mode_moving"], serde_json::json!([0, 1]), "{engine}");
    assert_eq!(codes["stand_height"], 3203, "{engine}: not simulated: API_NOT_IMPL");
    assert_eq!(codes["fsm_damped"], serde_json::json!([0, 1]), "{engine}");
    assert_eq!(codes["invalid_fsm"], 8302, "{engine}: INVALID_FSM_ID");

    // Walked distance against the commanded velocity, over simulated time.
    let (a, b, dt) = speed(&report, "forward");
    assert!(dt >= 2.9, "{engine}: forward window {dt:.2} s of simulated time");
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let forward = (dx * a[2].cos() + dy * a[2].sin()) / dt;
    let lateral = (-dx * a[2].sin() + dy * a[2].cos()) / dt;
    let (c, d, dt_turn) = speed(&report, "turn");
    let yaw_rate = wrap(d[2] - c[2]) / dt_turn;
    let (e, f, dt_stop) = speed(&report, "stop");
    let drift = (f[0] - e[0]).hypot(f[1] - e[1]) / dt_stop;
    eprintln!(
        "{engine}: forward {forward:.3} m/s ({:.2} m in {dt:.2} s simulated; lateral {lateral:.3}) for 0.5; yaw \
         {yaw_rate:.3} rad/s for 0.5; {drift:.3} m/s after StopMove",
        forward * dt
    );
    assert!((0.35..=0.6).contains(&forward), "{engine}: forward {forward:.3} m/s for 0.5 commanded");
    assert!(lateral.abs() < 0.15, "{engine}: lateral {lateral:.3} m/s");
    assert!((0.35..=0.65).contains(&yaw_rate), "{engine}: yaw rate {yaw_rate:.3} rad/s for 0.5 commanded");
    assert!(drift < 0.1, "{engine}: still moving at {drift:.3} m/s after StopMove");

    // The bridge's own account: the policy ran at 50 Hz of simulated time while walking, nothing malformed.
    let summary = sim_summary(&run.sim_err)
        .unwrap_or_else(|| panic!("{engine}: no summary from ulab sim:\n{}", tail(&run.sim_err)));
    let loco = &summary["loco"];
    assert_eq!(loco["malformed_requests"], 0, "{engine}: {summary}");
    let steps = loco["counters"]["policy_steps"].as_f64().expect("policy steps");
    // Walking from Start to Damp: at least the 1 + 5 + 5 + 4 s of the phases.
    assert!(steps >= 15.0 / 0.02, "{engine}: only {steps} policy steps: {summary}");
    assert_eq!(summary["counters"]["accepted"], 0, "{engine}: no low-level command was sent: {summary}");
}

#[test]
fn python_sdk_loco_client_walks_mujoco() {
    check_engine("mujoco");
}

#[test]
fn python_sdk_loco_client_walks_rapier_multibody() {
    check_engine("rapier-multibody");
}
