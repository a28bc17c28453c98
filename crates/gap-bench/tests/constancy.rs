//! The constancy check (`diagnose/constancy.rs`) against plants whose effect the test knows and the diagnosis does
//! not, both simulated by Rapier's multibody (another engine than the diagnosing MuJoCo) and read back from MCAP as
//! the benchmark does:
//! - trial 1 of the benchmark's seed 1 out-of-library run (`ulab gap bench --reference-engine rapier_multibody
//!   --trials 0 --out-of-library 6 --seed 1`): a friction proportional to the torque the left leg's transmissions
//!   carry, a law outside the library, acting as a torque the logged motor torque does not include. Before the
//!   check, its report named damping (the damping that fits its strongest windows); now the damping must be found
//!   inconsistent and nothing named;
//! - the counterpart that must stay named: the same leg with a viscous damping through Rapier's own joint damping.
use gap_bench::{generate_log, run_trial, BenchOptions, RealConfig};
use gap_diagnosis::plant::{joint_groups, EngineChoice, GROUPS};
use gap_diagnosis::{diagnose, DiagnoseOptions, EffectKind, Report, RobotLog};

fn show(what: &str, r: &Report) {
    for c in &r.constancy {
        eprintln!(
            "{what}: {} scale {:.2}, windows' median {:.2}, {} windows cut, misfit share {:.3} [{:.3}, {:.3}], \
             inconsistent {}",
            c.kind.name(),
            c.scale_all,
            c.scale_median,
            c.windows_cut,
            c.misfit_share.value,
            c.misfit_share.lo,
            c.misfit_share.hi,
            c.inconsistent
        );
    }
    eprintln!("{what}: ranked {:?}", r.ranked);
}

fn rapier() -> EngineChoice {
    EngineChoice::parse("rapier_multibody").expect("rapier")
}

#[test]
fn a_friction_that_grows_with_the_load_is_not_named_and_a_damping_is() {
    let m = robot_model::builtin("h1_2").expect("built-in model");
    let opts = BenchOptions { reference: rapier(), out_of_library: 2, ..BenchOptions::new(0, 1, 15.0) };
    let mut via_mcap = |_: usize, log: &RobotLog| -> Result<RobotLog, gap_diagnosis::GapError> {
        let mut file = std::io::Cursor::new(Vec::new());
        log.write_mcap(&mut file, &m)?;
        RobotLog::from_mcap(file.get_ref(), &m)
    };
    let (_, score, load) = run_trial(&m, 1, &opts, &mut via_mcap).expect("trial");
    show("load friction", &load);
    let label = score.out_of_library.as_ref().map(|o| (o.kind.as_str(), o.unit.as_str()));
    assert_eq!(label, Some(("load_friction", "left_leg")), "the trial's hidden effect changed");
    assert!(load.constancy.iter().any(|c| c.inconsistent), "no named effect was found inconsistent");
    assert!(load.ranked.is_empty(), "a library effect named on a load-proportional friction: {:?}", load.ranked);

    let leg = GROUPS.iter().position(|g| *g == "left_leg").expect("left leg group");
    let groups = joint_groups(&m);
    let mut cfg = RealConfig { engine: rapier(), ..RealConfig::new(&m, 15.0, 3) };
    for (j, &g) in groups.iter().enumerate() {
        if g == leg {
            cfg.effects.damping[j] = 0.8;
        }
    }
    let log = generate_log(&m, &cfg).expect("generate");
    let kinds = Some(vec![EffectKind::Damping, EffectKind::Friction, EffectKind::GainScale]);
    let damped = diagnose(&m, &log, &DiagnoseOptions { kinds, ..Default::default() }).expect("diagnose");
    show("damping", &damped);
    assert_eq!(damped.ranked.first(), Some(&EffectKind::Damping), "{:?}", damped.ranked);
    assert!(damped.constancy.iter().all(|c| !c.inconsistent), "a true damping was found inconsistent");
}
