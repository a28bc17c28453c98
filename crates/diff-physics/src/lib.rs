//! `diff-physics`: the same robot model in several physics engines behind one [`Engine`] interface, plus the
//! oracles that compare them with each other and with the model crate's own rigid-body reference.
//!
//! Conventions (stated once, used by every engine; see [`engine`]):
//! - quaternions `[w, x, y, z]`, base(pelvis)-to-world;
//! - joint vectors in motor-slot order (`model.joints` order);
//! - base linear velocity: velocity of the pelvis ORIGIN, WORLD frame; base angular velocity: PELVIS (body) frame
//!   (MuJoCo's free-joint convention; every other engine converts inside).
// Unsafe code is forbidden, except in the one FFI module of each C++ engine (`bullet::ffi`, ...), which allows it
// locally and states its invariants; with such an engine compiled in, the crate-wide level is `deny`.
#![cfg_attr(not(any(feature = "bullet", feature = "dart", feature = "physx")), forbid(unsafe_code))]
#![cfg_attr(any(feature = "bullet", feature = "dart", feature = "physx"), deny(unsafe_code))]

pub mod engine;
pub mod oracle;
pub mod pd;
pub mod precision;

#[cfg(feature = "mujoco")]
pub mod mujoco;
#[cfg(feature = "mujoco")]
pub mod suspension;

// Rapier engines (written against `engine.rs` by the Rapier work), behind the default feature `rapier` so that
// `--no-default-features --features mujoco` builds the rest while they are in progress.
#[cfg(feature = "rapier")]
pub mod rapier_common;
#[cfg(feature = "rapier")]
pub mod rapier_impulse;
#[cfg(feature = "rapier")]
pub mod rapier_multibody;

#[cfg(feature = "bullet")]
pub mod bullet;
// DART 6.12 through a C++ layer (cpp/dart_glue.cpp), feature `dart`.
#[cfg(feature = "dart")]
pub mod dart;
// PhysX 5 reduced-coordinate articulation (f32), feature `physx`.
#[cfg(feature = "physx")]
pub mod physx;
// Newton (NVIDIA Warp) through a Python server (python/newton_server.py), feature `newton`.
#[cfg(feature = "newton")]
pub mod newton;

pub use engine::{CommonSettings, Contact, Energy, Engine, EngineError, EngineKind, LinkPose, State};
pub use pd::{pd_torques, PdTarget};

/// Creates an engine of the given kind for `model` with the common settings and the engine's own
/// default specific settings. Kinds whose module is not compiled in return [`EngineError::Unavailable`].
pub fn make_engine(
    kind: EngineKind,
    model: &robot_model::RobotModel,
    common: &CommonSettings,
) -> Result<Box<dyn Engine>, EngineError> {
    match kind {
        #[cfg(feature = "mujoco")]
        EngineKind::Mujoco => {
            Ok(Box::new(mujoco::MujocoEngine::new(model, common, &mujoco::MujocoSettings::default())?))
        }
        #[cfg(feature = "rapier")]
        EngineKind::RapierMultibody => {
            Ok(Box::new(rapier_multibody::RapierMultibodyEngine::new(model, common, &Default::default())?))
        }
        #[cfg(feature = "rapier")]
        EngineKind::RapierImpulse => {
            Ok(Box::new(rapier_impulse::RapierImpulseEngine::new(model, common, &Default::default())?))
        }
        #[cfg(feature = "bullet")]
        EngineKind::Bullet => Ok(Box::new(bullet::BulletEngine::new(model, common, &Default::default())?)),
        #[cfg(feature = "dart")]
        EngineKind::Dart => Ok(Box::new(dart::DartEngine::new(model, common, &dart::DartSettings::default())?)),
        #[cfg(feature = "physx")]
        EngineKind::Physx => Ok(Box::new(physx::PhysxEngine::new(model, common, &physx::PhysxSettings::default())?)),
        #[cfg(feature = "newton")]
        EngineKind::NewtonFeatherstone
        | EngineKind::NewtonSteel
        | EngineKind::NewtonXpbd
        | EngineKind::NewtonSemiImplicit
        | EngineKind::NewtonMujoco => {
            let solver = match kind {
                EngineKind::NewtonSteel => newton::NewtonSolver::Steel,
                EngineKind::NewtonXpbd => newton::NewtonSolver::Xpbd,
                EngineKind::NewtonSemiImplicit => newton::NewtonSolver::SemiImplicit,
                EngineKind::NewtonMujoco => newton::NewtonSolver::Mujoco,
                _ => newton::NewtonSolver::Featherstone,
            };
            Ok(Box::new(newton::NewtonEngine::new(model, common, &newton::NewtonSettings::for_solver(solver))?))
        }
        #[allow(unreachable_patterns)]
        other => {
            // Without any engine feature, nothing uses the model and settings.
            let _ = (model, common);
            Err(EngineError::Unavailable(other.name().to_string()))
        }
    }
}
