//! Unitree SDK2 topics as the transport sees them: a DDS topic name and a DDS type name. The names themselves
//! are defined once, in `unitree-idl`.

use unitree_idl::IdlStruct;

/// Low-level command topic (controller to robot).
pub const TOPIC_LOWCMD: &str = unitree_idl::topics::LOWCMD;
/// Low-level state topic (robot to controller).
pub const TOPIC_LOWSTATE: &str = unitree_idl::topics::LOWSTATE;

/// DDS type name of the humanoid ("hg": H1-2, G1) low-level command.
pub const HG_LOWCMD_TYPE: &str = unitree_idl::hg::LowCmd_::DDS_TYPE_NAME;
/// DDS type name of the humanoid ("hg") low-level state.
pub const HG_LOWSTATE_TYPE: &str = unitree_idl::hg::LowState_::DDS_TYPE_NAME;
/// DDS type name of the quadruped/H1 ("go") low-level command.
pub const GO_LOWCMD_TYPE: &str = unitree_idl::go::LowCmd_::DDS_TYPE_NAME;
/// DDS type name of the quadruped/H1 ("go") low-level state.
pub const GO_LOWSTATE_TYPE: &str = unitree_idl::go::LowState_::DDS_TYPE_NAME;

/// Which family of Unitree messages a robot speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// `unitree_hg` (H1-2, G1).
    Hg,
    /// `unitree_go` (Go2, B2, H1).
    Go,
}

/// A topic: its DDS name and the DDS type name it carries. All Unitree topics are keyless.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct TopicSpec {
    /// DDS topic name, e.g. `rt/lowcmd`.
    pub name: String,
    /// DDS type name, e.g. `unitree_hg::msg::dds_::LowCmd_`.
    pub type_name: String,
}

impl TopicSpec {
    /// A topic with the given names.
    pub fn new(name: impl Into<String>, type_name: impl Into<String>) -> Self {
        Self { name: name.into(), type_name: type_name.into() }
    }

    /// `rt/lowcmd` with the family's LowCmd_ type.
    pub fn lowcmd(family: Family) -> Self {
        match family {
            Family::Hg => Self::new(TOPIC_LOWCMD, HG_LOWCMD_TYPE),
            Family::Go => Self::new(TOPIC_LOWCMD, GO_LOWCMD_TYPE),
        }
    }

    /// `rt/lowstate` with the family's LowState_ type.
    pub fn lowstate(family: Family) -> Self {
        match family {
            Family::Hg => Self::new(TOPIC_LOWSTATE, HG_LOWSTATE_TYPE),
            Family::Go => Self::new(TOPIC_LOWSTATE, GO_LOWSTATE_TYPE),
        }
    }
}
