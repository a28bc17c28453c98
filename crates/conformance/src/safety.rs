//! Safety rules of `ulab conform` on top of the transport's own (domain 0 or a non-loopback
//! interface need `allow_robot`, checked by `DomainConfig::validate`): fuzzing sends deliberately
//! wrong commands, so on anything but loopback it needs a second, explicit permission.

use crate::ConformError;
use dds_transport::DomainConfig;

/// Whether `cfg` may be opened at all (the transport's rule: loopback and a non-zero domain,
/// or `allow_robot`).
pub fn check_network(cfg: &DomainConfig) -> Result<(), ConformError> {
    cfg.validate().map_err(|e| {
        ConformError::Refused(format!("{e} (pass --allow-robot and the exact --interface to reach a robot)"))
    })
}

/// Whether fuzzing `cfg` is permitted: always on a loopback interface with a non-zero domain;
/// otherwise only with `allow_robot` and `allow_robot_fuzz` both set.
pub fn check_fuzz(cfg: &DomainConfig, allow_robot_fuzz: bool) -> Result<(), ConformError> {
    check_network(cfg)?;
    if cfg.may_reach_robot() && !allow_robot_fuzz {
        return Err(ConformError::Refused(format!(
            "fuzzing domain {} on `{}` may send harmful commands to a real robot; it needs --allow-robot-fuzz as well as --allow-robot",
            cfg.domain_id(), cfg.interface_name()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_nonzero_domain_is_allowed() {
        let cfg = DomainConfig::loopback(81);
        assert!(check_network(&cfg).is_ok());
        assert!(check_fuzz(&cfg, false).is_ok());
        assert!(!cfg.may_reach_robot());
    }

    #[test]
    fn domain_zero_needs_allow_robot_and_fuzz_needs_both_flags() {
        let cfg = DomainConfig::loopback(0);
        assert!(matches!(check_network(&cfg), Err(ConformError::Refused(_))));
        let cfg = cfg.allow_robot(true);
        assert!(check_network(&cfg).is_ok());
        assert!(matches!(check_fuzz(&cfg, false), Err(ConformError::Refused(_))));
        assert!(check_fuzz(&cfg, true).is_ok());
    }

    #[test]
    fn non_loopback_interface_needs_allow_robot() {
        let cfg = DomainConfig::loopback(81).interface("eth0");
        assert!(matches!(check_network(&cfg), Err(ConformError::Refused(_))));
        // The fuzz flag alone never replaces --allow-robot.
        assert!(matches!(check_fuzz(&cfg, true), Err(ConformError::Refused(_))));
        let cfg = cfg.allow_robot(true);
        assert!(matches!(check_fuzz(&cfg, false), Err(ConformError::Refused(_))));
        assert!(check_fuzz(&cfg, true).is_ok());
    }
}
