//! Floating-base windows on the ground. Reference logs come from MuJoCo RK4 with ground contact, sensor noise and
//! command jitter, driven by Unitree's LSTM policy (walking at 0.5 m/s, standing = zero command, plus two other
//! gaits); windows are predicted by MuJoCo implicitfast from (i) the reference engine's true base state and (ii) the
//! base state estimated from the log. Then single effects are fitted on training windows and judged on held-out
//! ones. Bounds are physical scales, not measured values (docs/gap/floating-base.md has the numbers; run with
//! `--nocapture` to print them).
use crate::common;

use common::{lstm_policy, model, shared_set};
use gap_bench::{generate_walking_log, FloatingLog};
use gap_diagnosis::diagnose::{SIGMA_DQ, SIGMA_Q};
use gap_diagnosis::floating::{
    estimate_base, estimate_base_at, predict_window, predict_window_from, settled_start, window_residual, BaseState,
    Feet, FloatingPlant, WindowResidual,
};
use gap_diagnosis::log::Measurement;
use gap_diagnosis::plant::{joint_groups, Effects, EngineChoice, DT};
use robot_model::RobotModel;
use std::sync::OnceLock;

const LOG_S: f64 = 3.0;
/// Windows start after the policy's start-up transient.
const FIRST_WINDOW_S: f64 = 1.0;
const WINDOW_STATES: usize = 50; // 0.1 s at 500 Hz

fn diagnosing() -> EngineChoice {
    EngineChoice::parse("mujoco").expect("implicitfast")
}

/// Unitree's LSTM walking policy with velocity command `cmd`, fed the reference engine's true pelvis state.
/// `[0, 0, 0]` is the standing case: the policy keeps the robot upright by stepping in place (a PD hold of the
/// default pose with the model's gains does not stand in MuJoCo: it tips over within 1.5 s).
fn policy_log(fx: Effects, seed: u64, cmd: [f64; 3]) -> FloatingLog {
    generate_walking_log(&model(), fx, LOG_S, seed, &lstm_policy(cmd)).expect("reference log")
}

const WALK: [f64; 3] = [0.5, 0.0, 0.0];
const STAND: [f64; 3] = [0.0, 0.0, 0.0];

fn walking_control() -> &'static FloatingLog {
    static LOG: OnceLock<FloatingLog> = OnceLock::new();
    LOG.get_or_init(|| policy_log(Effects::none(model().nj()), 21, WALK))
}

/// Nominal window starts every 0.1 s from FIRST_WINDOW_S.
fn nominal_starts(log: &FloatingLog) -> Vec<usize> {
    let first = (FIRST_WINDOW_S / DT).round() as usize;
    (first..log.log.states.len().saturating_sub(2 * WINDOW_STATES + 1)).step_by(WINDOW_STATES).collect()
}

/// Each nominal start moved to the first settled sample within the next 0.1 s (dropped when there is none).
fn settled_starts(log: &FloatingLog) -> Vec<usize> {
    let m = model();
    let feet = Feet::of(&m).expect("feet");
    let fx = Effects::none(m.nj());
    nominal_starts(log)
        .into_iter()
        .filter_map(|s| settled_start(&m, &feet, &log.log, &fx, s, s + WINDOW_STATES).expect("estimate"))
        .collect()
}

fn mean(x: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = x.collect();
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// Residuals of the windows at `starts` from the true and from the estimated base state, no effect in the
/// diagnosing plant.
fn residuals(log: &FloatingLog, starts: &[usize]) -> (Vec<WindowResidual>, Vec<WindowResidual>) {
    let m = model();
    let feet = Feet::of(&m).expect("feet");
    let fx = Effects::none(m.nj());
    let mut plant = FloatingPlant::new(&m, &diagnosing(), &fx).expect("plant");
    let (mut tr, mut es) = (Vec::new(), Vec::new());
    for &s in starts {
        let p = predict_window_from(&mut plant, &m, &log.log, &fx, s, WINDOW_STATES, &log.truth[s], true)
            .expect("true-base window");
        tr.push(window_residual(&m, &log.log, s, &p));
        let p = predict_window(&mut plant, &m, &feet, &log.log, &fx, s, WINDOW_STATES, true)
            .expect("estimated-base window");
        es.push(window_residual(&m, &log.log, s, &p));
    }
    (tr, es)
}

fn print_residuals(name: &str, r: &[WindowResidual]) {
    eprintln!(
        "{name}: {} windows, mean RMS q {:.2e} rad, dq {:.3} rad/s, tau {:.2} N·m, imu quat {:.2e} rad, gyro {:.3} rad/s, score {:.1}",
        r.len(),
        mean(r.iter().map(|w| w.q)),
        mean(r.iter().map(|w| w.dq)),
        mean(r.iter().map(|w| w.tau)),
        mean(r.iter().map(|w| w.quat)),
        mean(r.iter().map(|w| w.gyro)),
        mean(r.iter().map(|w| w.score))
    );
}

/// Base-estimate errors against the reference engine over the state samples from FIRST_WINDOW_S (all, or only
/// the settled ones): RMS of height (m), linear velocity (m/s, 3-D), orientation (rad), angular velocity (rad/s,
/// 3-D), and the fraction of samples used.
fn estimate_errors(log: &FloatingLog, settled_only: bool) -> [f64; 5] {
    let m = model();
    let feet = Feet::of(&m).expect("feet");
    let fx = Effects::none(m.nj());
    let first = (FIRST_WINDOW_S / DT).round() as usize;
    let (mut e, mut n) = ([0.0; 4], 0.0_f64);
    for (i, t) in log.truth.iter().enumerate().skip(first) {
        let est = estimate_base_at(&m, &feet, &log.log, i, &fx).expect("estimate");
        if settled_only && !est.settled {
            continue;
        }
        let b = est.base;
        let d = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
        e[0] += (b.pos[2] - t.pos[2]).powi(2);
        e[1] += d(b.lin_vel, t.lin_vel);
        e[2] += diff_physics::engine::quat_angle(b.quat, t.quat).powi(2);
        e[3] += d(b.ang_vel, t.ang_vel);
        n += 1.0;
    }
    let r = e.map(|x| (x / n.max(1.0)).sqrt());
    [r[0], r[1], r[2], r[3], n / (log.truth.len() - first) as f64]
}

fn print_errors(name: &str, e: [f64; 5]) {
    eprintln!(
        "{name}: base estimate RMS error over {:.0} % of samples: height {:.4} m, lin vel {:.4} m/s, orientation {:.2e} rad, ang vel {:.4} rad/s",
        100.0 * e[4],
        e[0],
        e[1],
        e[2],
        e[3]
    );
}

/// Estimate errors and window residuals of a no-effect log; the physical bounds every case must meet.
fn check_windows(name: &str, log: &FloatingLog) {
    let all = estimate_errors(log, false);
    let settled = estimate_errors(log, true);
    print_errors(&format!("{name}, all samples"), all);
    print_errors(&format!("{name}, settled samples"), settled);
    let (_, es_nominal) = residuals(log, &nominal_starts(log));
    let starts = settled_starts(log);
    let (tr, es) = residuals(log, &starts);
    print_residuals(&format!("{name}, true base, settled starts"), &tr);
    print_residuals(&format!("{name}, estimated base, settled starts"), &es);
    print_residuals(&format!("{name}, estimated base, nominal starts"), &es_nominal);
    // Most of a gait is away from touchdown transients, so most windows can start settled.
    assert!(
        settled[4] > 0.5 && starts.len() * 2 > nominal_starts(log).len(),
        "{name}: too few settled samples ({:.2})",
        settled[4]
    );
    // Settled samples: height (kinematic, rigid ground) within the soft-contact penetration scale (5 mm), velocity
    // within 10 % of the 0.5 m/s walking speed, orientation within a few IMU noise levels (5e-4 rad per axis),
    // angular velocity well below the 0.1 rad/s a policy responds to.
    assert!(settled[0] < 0.005, "{name}: height error {:.4} m", settled[0]);
    assert!(settled[1] < 0.05, "{name}: velocity error {:.4} m/s", settled[1]);
    assert!(settled[2] < 3e-3, "{name}: orientation error {:.2e} rad", settled[2]);
    assert!(settled[3] < 0.03, "{name}: angular velocity error {:.4} rad/s", settled[3]);
    // The diagnosis' units of gap are SIGMA_Q = 2e-3 rad and SIGMA_DQ = 0.1 rad/s: with no effect, neither the
    // integrator change (true base) nor the estimate may make a gap of one unit on its own.
    for (what, r) in [("true", &tr), ("estimated", &es)] {
        assert!(mean(r.iter().map(|w| w.q)) < SIGMA_Q, "{name}: {what}-base q residual");
        assert!(mean(r.iter().map(|w| w.dq)) < SIGMA_DQ, "{name}: {what}-base dq residual");
    }
}

/// The pelvis orientation and angular velocity from the torso IMU agree with policy-runtime's independent,
/// hand-derived waist formula (unitree_rl_gym's `transform_imu_data`) for random poses and speeds.
#[test]
fn imu_to_pelvis_agrees_with_the_waist_formula() {
    let m = model();
    let feet = Feet::of(&m).expect("feet");
    let fx = Effects::none(m.nj());
    let waist = policy_runtime::WAIST_SLOT;
    for k in 0..20 {
        let x = k as f64;
        let q: Vec<f64> = (0..m.nj()).map(|j| 0.3 * (x * 0.7 + j as f64).sin()).collect();
        let dq: Vec<f64> = (0..m.nj()).map(|j| 1.5 * (x * 1.3 + 2.0 * j as f64).cos()).collect();
        let axis = nalgebra::Vector3::new((x * 0.9).sin(), (x * 0.4).cos(), 0.5).normalize() * (0.2 + 0.1 * x).min(2.5);
        let r = nalgebra::UnitQuaternion::from_scaled_axis(axis);
        let quat = [r.w, r.i, r.j, r.k];
        let gyro = [0.5 * x.sin(), -0.3 * x.cos(), 0.2 * (2.0 * x).sin()];
        let meas =
            Measurement { t: 0.0, q: q.clone(), dq: dq.clone(), tau: vec![0.0; m.nj()], quat, gyro, acc: [0.0; 3] };
        let est = estimate_base(&m, &feet, &meas, &fx).expect("estimate").base;
        let want = policy_runtime::pelvis_imu_from_torso(quat, gyro, q[waist], dq[waist]);
        let ang = diff_physics::engine::quat_angle(est.quat, want.quat);
        assert!(ang < 1e-9, "pose {k}: orientation differs by {ang} rad");
        for a in 0..3 {
            // The estimate differentiates the kinematics numerically (step 1e-6 rad): 1e-5 rad/s is far below gyro noise.
            assert!(
                (est.ang_vel[a] - want.ang_vel[a]).abs() < 1e-5,
                "pose {k} axis {a}: {:?} vs {:?}",
                est.ang_vel,
                want.ang_vel
            );
        }
    }
}

#[test]
fn standing_windows() {
    if !shared_set() {
        return;
    }
    let log = policy_log(Effects::none(model().nj()), 7, STAND);
    let last = log.truth.last().expect("states");
    eprintln!("standing: pelvis at ({:.2}, {:.2}, {:.3}) m after {LOG_S} s", last.pos[0], last.pos[1], last.pos[2]);
    assert!(last.pos[2] > 0.8, "the reference robot must stay up: {last:?}");
    check_windows("standing", &log);
}

#[test]
fn walking_windows() {
    if !shared_set() {
        return;
    }
    let log = walking_control();
    let last = log.truth.last().expect("states");
    eprintln!("walking: pelvis at ({:.2}, {:.2}, {:.3}) m after {LOG_S} s", last.pos[0], last.pos[1], last.pos[2]);
    assert!(last.pos[2] > 0.8 && last.pos[0] > 0.3, "the reference robot must walk, not fall: {last:?}");
    check_windows("walking", log);
}

/// What each part of the estimate costs: windows from the true base state with one component replaced by its
/// estimate (walking, settled starts). Prints only; the bounds are in `walking_windows`.
#[test]
fn estimate_cost_by_component() {
    if !shared_set() {
        return;
    }
    let log = walking_control();
    let m = model();
    let feet = Feet::of(&m).expect("feet");
    let fx = Effects::none(m.nj());
    let mut plant = FloatingPlant::new(&m, &diagnosing(), &fx).expect("plant");
    let starts = settled_starts(log);
    type Swap = fn(&mut BaseState, &BaseState);
    let parts: [(&str, Swap); 4] = [
        ("height", |b, e| b.pos[2] = e.pos[2]), // e carries the rest sink already
        ("linear velocity", |b, e| b.lin_vel = e.lin_vel),
        ("orientation", |b, e| b.quat = e.quat),
        ("angular velocity", |b, e| b.ang_vel = e.ang_vel),
    ];
    for (name, swap) in parts {
        let r: Vec<WindowResidual> = starts
            .iter()
            .map(|&s| {
                let e = estimate_base_at(&m, &feet, &log.log, s, &fx).expect("estimate");
                let mut est = e.base;
                est.pos[2] -= plant.stance_sink(e.stance);
                let mut b = log.truth[s];
                swap(&mut b, &est);
                let p = predict_window_from(&mut plant, &m, &log.log, &fx, s, WINDOW_STATES, &b, true).expect("window");
                window_residual(&m, &log.log, s, &p)
            })
            .collect();
        print_residuals(&format!("walking, true base but estimated {name}"), &r);
    }
    eprintln!("sink of the diagnosing plant: {:.4} m on both feet", plant.rest_sink());
}

/// The smallest relative held-out reduction this test counts as identified.
const FLOOR_FRAC: f64 = 0.03;

/// The relative noise floor of a held-out reduction in this test: the larger of [`FLOOR_FRAC`] and half the relative
/// spread between the two halves (alternate windows) of the baseline held-out scores (how much the metric moves with
/// no change at all).
fn noise_floor(base: &[f64]) -> f64 {
    let even = mean(base.iter().step_by(2).copied());
    let odd = mean(base.iter().skip(1).step_by(2).copied());
    FLOOR_FRAC.max(0.5 * (even - odd).abs() / (even + odd).max(1e-300))
}

/// A single-parameter fit.
struct Fit {
    value: f64,
    /// Relative held-out reduction of the mean score.
    reduction: f64,
    floor: f64,
}

/// One held-out identifiability check: fit a single parameter (grid, `grid[0]` = no effect) on the training
/// windows (settled starts in even 0.5 s blocks) from estimated base states; the held-out windows are the odd
/// blocks.
fn held_out_fit(log: &FloatingLog, grid: &[f64], set: &dyn Fn(&mut Effects, f64)) -> Fit {
    let m = model();
    let feet = Feet::of(&m).expect("feet");
    let all = settled_starts(log);
    let block = |s: usize| ((log.log.states[s].t / 0.5).floor() as usize) % 2;
    let (train, test): (Vec<usize>, Vec<usize>) = all.iter().partition(|&&s| block(s) == 0);
    let scores = |v: f64, ws: &[usize]| -> Vec<f64> {
        let mut fx = Effects::none(m.nj());
        set(&mut fx, v);
        let pm = fx.apply_to_model(&m);
        let mut plant = FloatingPlant::new(&pm, &diagnosing(), &fx).expect("plant");
        ws.iter()
            .map(|&s| {
                let p = predict_window(&mut plant, &pm, &feet, &log.log, &fx, s, WINDOW_STATES, true).expect("window");
                window_residual(&m, &log.log, s, &p).score
            })
            .collect()
    };
    let best = grid
        .iter()
        .copied()
        .map(|v| (v, mean(scores(v, &train).into_iter())))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("grid");
    let base = scores(grid[0], &test);
    let after = mean(scores(best.0, &test).into_iter());
    Fit { value: best.0, reduction: 1.0 - after / mean(base.iter().copied()), floor: noise_floor(&base) }
}

fn left_leg(m: &RobotModel) -> Vec<usize> {
    let g = joint_groups(m);
    (0..m.nj()).filter(|&j| g[j] == 0).collect()
}

/// Fits the effect on a walking log with it injected and on the no-effect log. The injected effect must cut the
/// held-out residual by more than the noise floor; fitting it on the no-effect log must not (no false attribution).
fn identifiability(name: &str, injected: f64, grid: &[f64], set: &dyn Fn(&mut Effects, f64)) -> Option<Fit> {
    if !shared_set() {
        return None;
    }
    let m = model();
    let mut fx = Effects::none(m.nj());
    set(&mut fx, injected);
    let real = policy_log(fx, 21, WALK);
    let fit = held_out_fit(&real, grid, set);
    let control = held_out_fit(walking_control(), grid, set);
    eprintln!(
        "{name}: injected {injected}: fitted {}, held-out reduction {:.1} % (floor {:.1} %); no-effect log: fitted {}, reduction {:.1} % (floor {:.1} %)",
        fit.value,
        100.0 * fit.reduction,
        100.0 * fit.floor,
        control.value,
        100.0 * control.reduction,
        100.0 * control.floor
    );
    assert!(
        fit.reduction > fit.floor,
        "{name}: held-out reduction {:.3} does not clear the floor {:.3}",
        fit.reduction,
        fit.floor
    );
    assert!(
        control.reduction <= control.floor,
        "{name}: fitted on the no-effect log, it cuts the held-out residual by {:.3}",
        control.reduction
    );
    Some(fit)
}

/// Grid step of the fits below: the fitted value must be the injected one or a neighbour.
fn within_one_step(fit: f64, injected: f64, step: f64) -> bool {
    (fit - injected).abs() <= step + 1e-9
}

#[test]
fn identifiability_leg_damping() {
    let m = model();
    let leg = left_leg(&m);
    if let Some(f) = identifiability("left-leg damping (N·m·s/rad)", 3.0, &[0.0, 1.0, 2.0, 3.0, 4.0], &|fx, v| {
        leg.iter().for_each(|&j| fx.damping[j] = v)
    }) {
        assert!(within_one_step(f.value, 3.0, 1.0), "fitted {}", f.value);
    }
}

#[test]
fn identifiability_leg_mass() {
    let m = model();
    let leg = left_leg(&m);
    if let Some(f) = identifiability("left-leg link mass (x)", 1.5, &[1.0, 1.25, 1.5, 1.75], &|fx, v| {
        leg.iter().for_each(|&j| fx.mass_scale[j] = v)
    }) {
        assert!(within_one_step(f.value, 1.5, 0.25), "fitted {}", f.value);
    }
}

#[test]
fn identifiability_contact_friction() {
    // Less grip than modelled makes the stance foot slip; the fit must at least say "less grip".
    if let Some(f) = identifiability("contact friction (coefficient)", 0.3, &[1.0, 0.3, 0.5, 0.7], &|fx, v| {
        fx.contact_friction = Some(v)
    }) {
        assert!(f.value < 1.0, "fitted {}", f.value);
    }
}

#[test]
fn identifiability_contact_stiffness() {
    if let Some(f) = identifiability("contact time constant (s)", 0.04, &[0.02, 0.01, 0.03, 0.04, 0.05], &|fx, v| {
        fx.contact_timeconst = Some(v)
    }) {
        assert!(within_one_step(f.value, 0.04, 0.01), "fitted {}", f.value);
    }
}

/// Other gaits, other noise: turning while walking diagonally, and walking faster.
#[test]
fn other_gaits_windows() {
    if !shared_set() {
        return;
    }
    for (seed, cmd, name) in [(5u64, [0.3, 0.2, 0.3], "diagonal and turning"), (9, [0.8, 0.0, 0.0], "0.8 m/s")] {
        let log = policy_log(Effects::none(model().nj()), seed, cmd);
        let last = log.truth.last().expect("states");
        assert!(last.pos[2] > 0.8, "{name}: the reference robot must stay up: {last:?}");
        check_windows(name, &log);
    }
}
