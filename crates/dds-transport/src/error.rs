//! Errors of the transport.

/// Everything that can go wrong in the transport. Nothing here is produced from received bytes:
/// a reader hands over whatever arrived and never fails on its content.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The configuration would reach a real robot (domain 0, or a non-loopback interface)
    /// and `allow_robot` was not set.
    #[error("refusing {what}: a real robot may be there; set allow_robot to use it")]
    RobotNotAllowed {
        /// What was refused, e.g. "domain 0".
        what: String,
    },
    /// A configuration value is invalid (domain out of range, bad interface name, ...).
    #[error("invalid configuration: {0}")]
    InvalidConfig(String),
    /// The same DDS domain is already open in this process with a different configuration;
    /// Cyclone DDS keeps one configuration per domain and process.
    #[error("domain {domain} is already open in this process with a different configuration")]
    DomainConfigConflict {
        /// The DDS domain id.
        domain: u32,
    },
    /// A topic or type name contains a NUL byte or is empty.
    #[error("invalid name {0:?}")]
    InvalidName(String),
    /// A payload too short to carry the 4-byte encapsulation header.
    #[error("payload of {len} bytes is shorter than the 4-byte encapsulation header")]
    PayloadTooShort {
        /// Its length.
        len: usize,
    },
    /// A Cyclone DDS call failed.
    #[error("{op} failed: {message} ({code})")]
    Dds {
        /// The call that failed.
        op: &'static str,
        /// Cyclone's return code.
        code: i32,
        /// Cyclone's text for the code.
        message: String,
    },
}

/// Result with the transport's error.
pub type Result<T> = std::result::Result<T, Error>;
