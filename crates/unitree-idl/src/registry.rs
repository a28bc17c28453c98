//! Names of every message type, as the CLI, reports and DDS spell them.

use crate::{api, go, hg, IdlStruct};

/// Every SDK2 message type this crate knows: the low-level types and the RPC types.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MessageType {
    /// `hg/LowCmd`: [`hg::LowCmd_`].
    HgLowCmd,
    /// `hg/MotorCmd`: [`hg::MotorCmd_`].
    HgMotorCmd,
    /// `hg/LowState`: [`hg::LowState_`].
    HgLowState,
    /// `hg/MotorState`: [`hg::MotorState_`].
    HgMotorState,
    /// `hg/IMUState`: [`hg::IMUState_`].
    HgImuState,
    /// `hg/HandCmd`: [`hg::HandCmd_`].
    HgHandCmd,
    /// `hg/HandState`: [`hg::HandState_`].
    HgHandState,
    /// `hg/PressSensorState`: [`hg::PressSensorState_`].
    HgPressSensorState,
    /// `hg/BmsCmd`: [`hg::BmsCmd_`].
    HgBmsCmd,
    /// `hg/BmsState`: [`hg::BmsState_`].
    HgBmsState,
    /// `hg/MainBoardState`: [`hg::MainBoardState_`].
    HgMainBoardState,
    /// `go/LowCmd`: [`go::LowCmd_`].
    GoLowCmd,
    /// `go/MotorCmd`: [`go::MotorCmd_`].
    GoMotorCmd,
    /// `go/LowState`: [`go::LowState_`].
    GoLowState,
    /// `go/MotorState`: [`go::MotorState_`].
    GoMotorState,
    /// `go/IMUState`: [`go::IMUState_`].
    GoImuState,
    /// `go/BmsCmd`: [`go::BmsCmd_`].
    GoBmsCmd,
    /// `go/BmsState`: [`go::BmsState_`].
    GoBmsState,
    /// `go/TimeSpec`: [`go::TimeSpec_`].
    GoTimeSpec,
    /// `go/PathPoint`: [`go::PathPoint_`].
    GoPathPoint,
    /// `go/SportModeState`: [`go::SportModeState_`].
    GoSportModeState,
    /// `api/Request`: [`api::Request_`].
    ApiRequest,
    /// `api/RequestHeader`: [`api::RequestHeader_`].
    ApiRequestHeader,
    /// `api/RequestIdentity`: [`api::RequestIdentity_`].
    ApiRequestIdentity,
    /// `api/RequestLease`: [`api::RequestLease_`].
    ApiRequestLease,
    /// `api/RequestPolicy`: [`api::RequestPolicy_`].
    ApiRequestPolicy,
    /// `api/Response`: [`api::Response_`].
    ApiResponse,
    /// `api/ResponseHeader`: [`api::ResponseHeader_`].
    ApiResponseHeader,
    /// `api/ResponseStatus`: [`api::ResponseStatus_`].
    ApiResponseStatus,
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

/// The one list of message types: generates [`MessageType`]'s tables and `with_message_type!`.
/// `$d` is a literal `$` handed in by the invocation, so that the generated macro can declare
/// its own metavariables.
macro_rules! registry {
    ($d:tt $( $variant:ident => $name:literal, $module:ident :: $ty:ident; )*) => {
        impl MessageType {
            /// All types: hg, go, then the RPC types (api).
            pub const ALL: &'static [MessageType] = &[$( MessageType::$variant ),*];

            /// Short name: package and IDL name without the trailing underscore (`hg/LowCmd`).
            pub const fn name(self) -> &'static str {
                match self { $( MessageType::$variant => $name ),* }
            }

            /// Fully qualified DDS type name (`unitree_hg::msg::dds_::LowCmd_`).
            pub const fn dds_type_name(self) -> &'static str {
                match self { $( MessageType::$variant => <$module::$ty as IdlStruct>::DDS_TYPE_NAME ),* }
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

        /// Runs `$body` with the type alias `$T` bound to the Rust type of a [`MessageType`]
        /// value: the one place that turns a runtime type name into generic code.
        ///
        /// ```
        /// use unitree_idl::{with_message_type, IdlStruct, MessageType};
        /// let members = with_message_type!(MessageType::HgLowCmd, T => T::MEMBERS.len());
        /// assert_eq!(members, 5);
        /// ```
        #[macro_export]
        macro_rules! with_message_type {
            ($d kind:expr, $d T:ident => $d body:expr) => {
                match $d kind {
                    $( $d crate::MessageType::$variant => {
                        type $d T = $d crate::$module::$ty;
                        $d body
                    } )*
                }
            };
        }
    };
}

registry! {
    $
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
    GoTimeSpec => "go/TimeSpec", go::TimeSpec_;
    GoPathPoint => "go/PathPoint", go::PathPoint_;
    GoSportModeState => "go/SportModeState", go::SportModeState_;
    ApiRequest => "api/Request", api::Request_;
    ApiRequestHeader => "api/RequestHeader", api::RequestHeader_;
    ApiRequestIdentity => "api/RequestIdentity", api::RequestIdentity_;
    ApiRequestLease => "api/RequestLease", api::RequestLease_;
    ApiRequestPolicy => "api/RequestPolicy", api::RequestPolicy_;
    ApiResponse => "api/Response", api::Response_;
    ApiResponseHeader => "api/ResponseHeader", api::ResponseHeader_;
    ApiResponseStatus => "api/ResponseStatus", api::ResponseStatus_;
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
