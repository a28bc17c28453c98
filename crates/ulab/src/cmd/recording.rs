//! Command-line pieces shared by the DDS subcommands (`record`, `replay`, `sim`, `conform`): the network
//! options and which topics carry which types. The recording format itself lives in the `recording` crate.

use anyhow::{bail, Context, Result};
use dds_transport::{DomainConfig, TopicSpec};
use unitree_idl::MessageType;

/// Network options common to the DDS subcommands.
#[derive(Debug, Clone, clap::Args)]
pub struct NetArgs {
    /// DDS domain id (0 is the real robot's and needs --allow-robot).
    #[arg(long, default_value_t = dds_transport::config::DEFAULT_DOMAIN)]
    pub domain: u32,
    /// Network interface (anything but loopback needs --allow-robot).
    #[arg(long, default_value = dds_transport::config::DEFAULT_INTERFACE)]
    pub interface: String,
    /// Permit domain 0 and non-loopback interfaces, where a real robot may be.
    #[arg(long)]
    pub allow_robot: bool,
}

impl NetArgs {
    /// The transport configuration, with the safety rule checked.
    pub fn domain_config(&self) -> Result<DomainConfig> {
        let cfg = DomainConfig::loopback(self.domain).interface(self.interface.clone()).allow_robot(self.allow_robot);
        match cfg.validate() {
            Ok(()) => Ok(cfg),
            Err(e @ dds_transport::Error::RobotNotAllowed { .. }) => {
                Err(anyhow::Error::new(e)
                    .context("network settings refused (pass --allow-robot to reach a real robot)"))
            }
            Err(e) => Err(anyhow::Error::new(e).context("invalid network settings")),
        }
    }
}

/// A topic to record: DDS topic name and type (known to the codec, or only a DDS type name).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicChoice {
    pub spec: TopicSpec,
    pub kind: Option<MessageType>,
}

/// Parses `TOPIC=TYPE` (TYPE a short name like `hg/LowState` or a DDS type name) or a bare
/// `rt/lowcmd` / `rt/lowstate`, whose type follows `family` (`hg` or `go`), or `rt/sportmodestate` (go).
pub fn parse_topic(text: &str, family: &str) -> Result<TopicChoice> {
    let (name, ty) = match text.split_once('=') {
        Some((n, t)) => (n.trim(), t.trim().to_owned()),
        None => {
            let ty = match text.trim() {
                "rt/lowcmd" => format!("{family}/LowCmd"),
                "rt/lowstate" => format!("{family}/LowState"),
                // unitree_go on every robot (Unitree's MuJoCo bridge publishes it for humanoids too).
                unitree_idl::topics::SPORTMODESTATE => MessageType::GoSportModeState.name().to_owned(),
                other => {
                    bail!("topic {other:?} needs a type: write it as {other}=hg/LowState or {other}=<DDS type name>")
                }
            };
            (text.trim(), ty)
        }
    };
    if name.is_empty() || ty.is_empty() {
        bail!("bad topic {text:?}: expected TOPIC=TYPE");
    }
    match MessageType::from_name(&ty) {
        Ok(kind) => Ok(TopicChoice { spec: TopicSpec::new(name, kind.dds_type_name()), kind: Some(kind) }),
        Err(_) if ty.contains("::") => Ok(TopicChoice { spec: TopicSpec::new(name, ty), kind: None }),
        Err(e) => Err(e).with_context(|| format!("topic {name:?}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_topics() {
        let t = parse_topic("rt/lowstate", "hg").expect("parse");
        assert_eq!(t.spec.type_name, "unitree_hg::msg::dds_::LowState_");
        assert_eq!(t.kind, Some(MessageType::HgLowState));
        let t = parse_topic("rt/lowcmd", "go").expect("parse");
        assert_eq!(t.spec.type_name, "unitree_go::msg::dds_::LowCmd_");
        let t = parse_topic("rt/sportmodestate", "hg").expect("parse");
        assert_eq!(t.spec.type_name, "unitree_go::msg::dds_::SportModeState_");
        let t = parse_topic("rt/x=hg/HandCmd", "hg").expect("parse");
        assert_eq!(t.kind, Some(MessageType::HgHandCmd));
        let t = parse_topic("rt/y=foo::Bar_", "hg").expect("parse");
        assert_eq!((t.spec.type_name.as_str(), t.kind), ("foo::Bar_", None));
        assert!(parse_topic("rt/odd", "hg").is_err());
        assert!(parse_topic("rt/odd=nope", "hg").is_err());
    }
}
