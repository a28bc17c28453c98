use thiserror::Error;

/// Everything that can be wrong with a model's files.
#[derive(Debug, Error)]
pub enum ModelError {
    #[error("unknown robot {0:?} (built-in: h1_2)")]
    UnknownRobot(String),
    #[error("cannot read {path}: {source}")]
    Io { path: String, source: std::io::Error },
    /// The URDF text does not parse (the `urdf_rs` error says where and why).
    #[error("parsing the URDF")]
    Urdf(#[source] urdf_rs::UrdfError),
    #[error("sidecar TOML: {0}")]
    Toml(#[from] toml::de::Error),
    #[error("joint {joint:?}: type {kind} is not supported (revolute joints only; fixed joints must be merged)")]
    UnsupportedJoint { joint: String, kind: String },
    #[error("joint {joint:?} refers to unknown link {link:?}")]
    UnknownLink { joint: String, link: String },
    #[error("link {0:?} has more than one parent joint")]
    MultipleParents(String),
    #[error("expected exactly one root link, found {0:?}")]
    Roots(Vec<String>),
    #[error("base link in the sidecar is {sidecar:?} but the URDF root is {urdf:?}")]
    BaseMismatch { sidecar: String, urdf: String },
    #[error("link {0:?} is not reachable from the root (cycle or disconnected)")]
    Unreachable(String),
    #[error("link {link:?}: {reason}")]
    BadInertial { link: String, reason: String },
    #[error("link {link:?}: unsupported collision geometry ({kind}); use box, sphere, capsule or cylinder")]
    UnsupportedGeometry { link: String, kind: String },
    #[error("joint {joint:?}: {reason}")]
    BadJoint { joint: String, reason: String },
    #[error("motor slot {slot} names joint {joint:?}, which is not in the URDF")]
    MotorJointMissing { slot: usize, joint: String },
    #[error("joint {0:?} has no motor slot in the sidecar")]
    UnactuatedJoint(String),
    #[error("motor slot {slot}: {reason}")]
    BadMotor { slot: usize, reason: String },
    #[error("{0}")]
    Invalid(String),
}
