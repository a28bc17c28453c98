//! `ulab model`: the robot model in every engine, with oracles.
//!
//! - `ulab model check --robot h1_2 [--engine E]... [--format table|json]`: model equivalence, contact-free
//!   dynamics, standing contact, one step across engines, invariants; exit 1 when a check fails.
//! - `ulab model inspect --robot h1_2 --engine E --q zero|default|random:SEED [--format json|table]`: nq, nv,
//!   total mass, COM and the joint-space mass matrix (6 base rows/columns, then joints in slot order).
//! - `ulab model mjcf --robot h1_2`: the MJCF generated for MuJoCo (free joint, floor).
use crate::exit::Exit;
use anyhow::{bail, Context, Result};
use diff_physics::oracle::{mass_matrix_from_accelerations, random_coords, run_checks, CheckOptions};
use diff_physics::{make_engine, CommonSettings, Engine, EngineKind, State};
use rand::SeedableRng;
use robot_model::{GenCoords, RobotModel};

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Sub,
}

#[derive(Debug, clap::Subcommand)]
enum Sub {
    /// Run the oracles on every engine (or the ones given); exit 1 when a check fails.
    Check(CheckArgs),
    /// Print nq, nv, total mass, COM and the mass matrix of the robot in one engine at one configuration.
    Inspect(InspectArgs),
    /// Print the MJCF generated from the model (free joint, floor, default settings).
    Mjcf(MjcfArgs),
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Format {
    Table,
    Json,
}

#[derive(Debug, clap::Args)]
struct CheckArgs {
    /// Built-in robot name, or a path to a sidecar TOML (the URDF it names is read beside it).
    #[arg(long, default_value = "h1_2")]
    robot: String,
    #[arg(long = "engine", help = super::engines_help("Engines to check (repeat the flag); default: all of"))]
    engines: Vec<String>,
    #[arg(long, value_enum, default_value = "table")]
    format: Format,
    /// Seed of the random configurations.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Number of random configurations per check.
    #[arg(long, default_value_t = 5)]
    samples: usize,
    /// Physics timestep (s).
    #[arg(long, default_value_t = 0.002)]
    dt: f64,
}

#[derive(Debug, clap::Args)]
struct InspectArgs {
    #[arg(long, default_value = "h1_2")]
    robot: String,
    #[arg(long, default_value = "mujoco", help = super::engines_help("Engine, or `reference` (robot-model's own RNEA/CRBA); one of"))]
    engine: String,
    /// zero | default | random:SEED
    #[arg(long, default_value = "default")]
    q: String,
    /// Include joint armature in the mass matrix (as the engines simulate it by default).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    armature: bool,
    #[arg(long, value_enum, default_value = "json")]
    format: Format,
}

#[derive(Debug, clap::Args)]
struct MjcfArgs {
    #[arg(long, default_value = "h1_2")]
    robot: String,
}

pub fn run(args: Args) -> Result<Exit> {
    match args.command {
        Sub::Check(a) => check(a),
        Sub::Inspect(a) => inspect(a),
        Sub::Mjcf(a) => {
            let model = load(&a.robot)?;
            let e = diff_physics::mujoco::MujocoEngine::mjcf(&model, &CommonSettings::default(), &Default::default());
            print!("{e}");
            Ok(Exit::Success)
        }
    }
}

fn load(robot: &str) -> Result<RobotModel> {
    if robot_model::BUILTIN_ROBOTS.contains(&robot) {
        robot_model::builtin(robot).with_context(|| format!("loading built-in robot {robot}"))
    } else {
        RobotModel::load(std::path::Path::new(robot)).with_context(|| format!("loading robot model {robot}"))
    }
}

fn parse_engine(s: &str) -> Result<EngineKind> {
    Ok(EngineKind::parse_available(s)?)
}

fn check(a: CheckArgs) -> Result<Exit> {
    let model = load(&a.robot)?;
    let kinds = if a.engines.is_empty() {
        EngineKind::available()
    } else {
        a.engines.iter().map(|s| parse_engine(s)).collect::<Result<Vec<_>>>()?
    };
    if !(a.dt.is_finite() && a.dt > 0.0) || a.samples == 0 {
        bail!("--dt must be positive and --samples at least 1");
    }
    let report = run_checks(&model, &kinds, &CheckOptions { seed: a.seed, samples: a.samples, timestep: a.dt });
    match a.format {
        Format::Table => print!("{}", report.table()),
        Format::Json => println!("{}", serde_json::to_string_pretty(&report).context("serialising the report")?),
    }
    if report.engines.is_empty() {
        eprintln!("no engine available in this build");
        return Ok(Exit::Failed);
    }
    Ok(Exit::failed_if(!report.passed()))
}

fn coords(model: &RobotModel, q: &str) -> Result<GenCoords> {
    Ok(match q {
        "zero" => GenCoords::zero(model),
        "default" => GenCoords::standing(model),
        other => {
            let seed = other
                .strip_prefix("random:")
                .with_context(|| format!("--q must be zero, default or random:SEED, not {other:?}"))?
                .parse::<u64>()
                .context("SEED in random:SEED must be an unsigned integer")?;
            random_coords(model, &mut rand_chacha::ChaCha8Rng::seed_from_u64(seed))
        }
    })
}

fn inspect(a: InspectArgs) -> Result<Exit> {
    let model = load(&a.robot)?;
    let c = coords(&model, &a.q)?;
    let nv = model.nv();
    let (engine_name, version, method, com, m): (String, String, String, [f64; 3], Vec<f64>) =
        if a.engine == "reference" {
            let m = model.mass_matrix(&c, a.armature).context("reference mass matrix")?;
            let com = model.com(&c).context("reference COM")?;
            (
                "reference".into(),
                robot_model::RigidBodyDynamics::NAME.into(),
                "RNEA unit-acceleration columns".into(),
                [com.x, com.y, com.z],
                m.transpose().as_slice().to_vec(),
            )
        } else {
            let kind = parse_engine(&a.engine)?;
            // Contact-free, undamped: only the configuration and (optionally) armature matter for M.
            let common = CommonSettings { armature: a.armature, ..CommonSettings::rigid_body_only() };
            let mut e: Box<dyn Engine> =
                make_engine(kind, &model, &common).with_context(|| format!("building engine {}", kind.name()))?;
            e.reset(&State::at_rest(c.clone())).context("reset")?;
            let com = e.com();
            let (m, method) = match e.mass_matrix() {
                Some(m) => (m, "engine's own mass matrix".to_string()),
                None => {
                    let m = mass_matrix_from_accelerations(e.as_mut(), nv).context("mass matrix from accelerations")?;
                    (m.transpose().as_slice().to_vec(), "from accelerations under unit generalized forces".to_string())
                }
            };
            (e.name().into(), e.version(), method, com, m)
        };
    let rows: Vec<Vec<f64>> = m.chunks(nv).map(|r| r.to_vec()).collect();
    let out = serde_json::json!({
        "robot": model.name,
        "engine": engine_name,
        "version": version,
        "q": a.q,
        "nq": model.nq(),
        "nv": model.nv(),
        "total_mass": model.total_mass(),
        "com": com,
        "armature_included": a.armature,
        "mass_matrix_method": method,
        "coordinates": "v = [base linear velocity (world, pelvis origin) 3, base angular velocity (pelvis frame) 3, joints in motor-slot order]",
        "joint_order": model.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>(),
        "base_pos": c.base_pos,
        "base_quat_wxyz": c.base_quat,
        "joint_q": c.q,
        "mass_matrix": rows,
    });
    match a.format {
        Format::Json => println!("{}", serde_json::to_string_pretty(&out).context("serialising")?),
        Format::Table => {
            println!("robot {} engine {} ({}) q={}", model.name, out["engine"], out["version"], a.q);
            println!(
                "nq {} nv {} total mass {:.6} kg COM [{:.6}, {:.6}, {:.6}] m",
                model.nq(),
                nv,
                model.total_mass(),
                com[0],
                com[1],
                com[2]
            );
            println!("mass matrix ({method}), diagonal:");
            for (i, r) in rows.iter().enumerate() {
                let label = if i < 6 { format!("base{i}") } else { model.joints[i - 6].name.clone() };
                println!("  {label:<28} {:.6e}", r[i]);
            }
        }
    }
    Ok(Exit::Success)
}
