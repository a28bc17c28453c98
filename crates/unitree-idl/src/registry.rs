//! Names of every message type, as the CLI, reports and DDS spell them.

use crate::{go, hg, IdlStruct};

/// Every SDK2 low-level message type this crate knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MessageType {
    HgLowCmd,
    HgMotorCmd,
    HgLowState,
    HgMotorState,
    HgImuState,
    HgHandCmd,
    HgHandState,
    HgPressSensorState,
    HgBmsCmd,
    HgBmsState,
    HgMainBoardState,
    GoLowCmd,
    GoMotorCmd,
    GoLowState,
    GoMotorState,
    GoImuState,
    GoBmsCmd,
    GoBmsState,
}

/// A type name that names no SDK2 low-level type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownMessageType(pub String);

impl core::fmt::Display for UnknownMessageType {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "unknown message type `{}`; known: ", self.0)?;
        for (i, t) in MessageType::ALL.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            f.write_str(t.name())?;
        }
        Ok(())
    }
}

impl std::error::Error for UnknownMessageType {}

macro_rules! registry {
    ($( $variant:ident => $name:literal, $ty:ty; )*) => {
        impl MessageType {
            /// All types, hg first.
            pub const ALL: &'static [MessageType] = &[$( MessageType::$variant ),*];

            /// Short name: package and IDL name without the trailing underscore (`hg/LowCmd`).
            pub const fn name(self) -> &'static str {
                match self { $( MessageType::$variant => $name ),* }
            }

            /// Fully qualified DDS type name (`unitree_hg::msg::dds_::LowCmd_`).
            pub const fn dds_type_name(self) -> &'static str {
                match self { $( MessageType::$variant => <$ty as IdlStruct>::DDS_TYPE_NAME ),* }
            }

            /// Looks a type up by short name (`hg/LowCmd`) or DDS type name.
            pub fn from_name(name: &str) -> Result<Self, UnknownMessageType> {
                Self::ALL
                    .iter()
                    .copied()
                    .find(|t| t.name() == name || t.dds_type_name() == name)
                    .ok_or_else(|| UnknownMessageType(name.to_owned()))
            }
        }

    };
}

registry! {
    HgLowCmd => "hg/LowCmd", hg::LowCmd_;
    HgMotorCmd => "hg/MotorCmd", hg::MotorCmd_;
    HgLowState => "hg/LowState", hg::LowState_;
    HgMotorState => "hg/MotorState", hg::MotorState_;
    HgImuState => "hg/IMUState", hg::IMUState_;
    HgHandCmd => "hg/HandCmd", hg::HandCmd_;
    HgHandState => "hg/HandState", hg::HandState_;
    HgPressSensorState => "hg/PressSensorState", hg::PressSensorState_;
    HgBmsCmd => "hg/BmsCmd", hg::BmsCmd_;
    HgBmsState => "hg/BmsState", hg::BmsState_;
    HgMainBoardState => "hg/MainBoardState", hg::MainBoardState_;
    GoLowCmd => "go/LowCmd", go::LowCmd_;
    GoMotorCmd => "go/MotorCmd", go::MotorCmd_;
    GoLowState => "go/LowState", go::LowState_;
    GoMotorState => "go/MotorState", go::MotorState_;
    GoImuState => "go/IMUState", go::IMUState_;
    GoBmsCmd => "go/BmsCmd", go::BmsCmd_;
    GoBmsState => "go/BmsState", go::BmsState_;
}

/// Runs `$body` with the type alias `$T` bound to the Rust type of a [`MessageType`] value:
/// the one place that turns a runtime type name into generic code.
///
/// ```
/// use unitree_idl::{with_message_type, IdlStruct, MessageType};
/// let members = with_message_type!(MessageType::HgLowCmd, T => T::MEMBERS.len());
/// assert_eq!(members, 5);
/// ```
#[macro_export]
macro_rules! with_message_type {
    ($kind:expr, $T:ident => $body:expr) => {
        match $kind {
            $crate::MessageType::HgLowCmd => {
                type $T = $crate::hg::LowCmd_;
                $body
            }
            $crate::MessageType::HgMotorCmd => {
                type $T = $crate::hg::MotorCmd_;
                $body
            }
            $crate::MessageType::HgLowState => {
                type $T = $crate::hg::LowState_;
                $body
            }
            $crate::MessageType::HgMotorState => {
                type $T = $crate::hg::MotorState_;
                $body
            }
            $crate::MessageType::HgImuState => {
                type $T = $crate::hg::IMUState_;
                $body
            }
            $crate::MessageType::HgHandCmd => {
                type $T = $crate::hg::HandCmd_;
                $body
            }
            $crate::MessageType::HgHandState => {
                type $T = $crate::hg::HandState_;
                $body
            }
            $crate::MessageType::HgPressSensorState => {
                type $T = $crate::hg::PressSensorState_;
                $body
            }
            $crate::MessageType::HgBmsCmd => {
                type $T = $crate::hg::BmsCmd_;
                $body
            }
            $crate::MessageType::HgBmsState => {
                type $T = $crate::hg::BmsState_;
                $body
            }
            $crate::MessageType::HgMainBoardState => {
                type $T = $crate::hg::MainBoardState_;
                $body
            }
            $crate::MessageType::GoLowCmd => {
                type $T = $crate::go::LowCmd_;
                $body
            }
            $crate::MessageType::GoMotorCmd => {
                type $T = $crate::go::MotorCmd_;
                $body
            }
            $crate::MessageType::GoLowState => {
                type $T = $crate::go::LowState_;
                $body
            }
            $crate::MessageType::GoMotorState => {
                type $T = $crate::go::MotorState_;
                $body
            }
            $crate::MessageType::GoImuState => {
                type $T = $crate::go::IMUState_;
                $body
            }
            $crate::MessageType::GoBmsCmd => {
                type $T = $crate::go::BmsCmd_;
                $body
            }
            $crate::MessageType::GoBmsState => {
                type $T = $crate::go::BmsState_;
                $body
            }
        }
    };
}

impl core::fmt::Display for MessageType {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

impl core::str::FromStr for MessageType {
    type Err = UnknownMessageType;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::from_name(s)
    }
}
