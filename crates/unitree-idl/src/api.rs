//! `unitree_api`: the request/response types of Unitree's SDK2 RPC (module `unitree_api::msg::dds_`), carried on
//! `rt/api/<service>/request` and `rt/api/<service>/response` by every high-level client (`LocoClient`,
//! `SportClient`, ...).
//!
//! Member names, order and types follow Unitree's C++ SDK headers
//! (`include/unitree/robot/internal/internal_idl_decl/*_.hpp` of unitreerobotics/unitree_sdk2, commit
//! `21d0a3b2c46ee48c8fdf2783becb6be3beb0a59b`), without the trailing underscore of the C++ members; Unitree's
//! Python classes (`unitree_sdk2py/idl/unitree_api/msg/dds_/`) declare the same, `@final`. The payloads are JSON
//! text in `parameter` / `data` (and raw bytes in `binary` for the binary calls).

use crate::macros::idl_struct;

idl_struct! {
    /// Which call this is: `id` pairs a response with its request (Unitree's clients use a monotonic clock in
    /// nanoseconds), `api_id` names the call (`ROBOT_API_ID_*`).
    "unitree_api" struct RequestIdentity_ {
        /// Request id, unique per client; the response carries the same value.
        id: i64,
        /// Which call of the service this is (`ROBOT_API_ID_*`, e.g. [`loco::LocoApi::set_velocity`]).
        api_id: i64,
    }
}

idl_struct! {
    /// The caller's lease (0 without one).
    "unitree_api" struct RequestLease_ {
        /// Lease id held by the caller, 0 if none.
        id: i64,
    }
}

idl_struct! {
    /// Scheduling of the request: priority queue and whether the caller waits for an answer.
    "unitree_api" struct RequestPolicy_ {
        /// Priority of the request (0 is the default).
        priority: i32,
        /// True if the caller expects no response.
        noreply: bool,
    }
}

idl_struct! {
    /// Header of a request.
    "unitree_api" struct RequestHeader_ {
        /// Request id and API id.
        identity: RequestIdentity_,
        /// The caller's lease.
        lease: RequestLease_,
        /// Priority and reply policy.
        policy: RequestPolicy_,
    }
}

idl_struct! {
    /// An RPC request, topic `rt/api/<service>/request`.
    "unitree_api" struct Request_ {
        /// Identity, lease and policy of the request.
        header: RequestHeader_,
        /// Parameters of the call as JSON text (empty if it takes none).
        parameter: String,
        /// Raw bytes for the binary calls; empty otherwise.
        binary: Vec<u8>,
    }
}

idl_struct! {
    /// Outcome of a call: 0 or an SDK status code (`UT_ROBOT_ERR_*`, service-specific codes).
    "unitree_api" struct ResponseStatus_ {
        /// [`status::OK`] (0) on success, otherwise an error code.
        code: i32,
    }
}

idl_struct! {
    /// Header of a response: the request's identity, echoed, and the status.
    "unitree_api" struct ResponseHeader_ {
        /// Identity of the request answered, copied from it.
        identity: RequestIdentity_,
        /// Outcome of the call.
        status: ResponseStatus_,
    }
}

idl_struct! {
    /// An RPC response, topic `rt/api/<service>/response`.
    "unitree_api" struct Response_ {
        /// Which request this answers and its outcome.
        header: ResponseHeader_,
        /// Result of the call as JSON text (empty if it returns nothing).
        data: String,
        /// Raw bytes for the binary calls; empty otherwise.
        binary: Vec<u8>,
    }
}

/// Topic on which a client sends requests to `service` (unitree_sdk2py `core/channel_name.py`,
/// `GetClientChannelName`: `"rt/api/" + service + "/request"`).
pub fn request_topic(service: &str) -> String {
    format!("rt/api/{service}/request")
}

/// Topic on which `service` answers (`"rt/api/" + service + "/response"`).
pub fn response_topic(service: &str) -> String {
    format!("rt/api/{service}/response")
}

/// SDK status codes shared by every service: `include/unitree/robot/internal/internal_error.hpp`
/// (`UT_DECL_ERR`, same values in unitree_sdk2py `rpc/internal.py`).
pub mod status {
    /// `UT_ROBOT_OK`.
    pub const OK: i32 = 0;
    /// `UT_ROBOT_ERR_UNKNOWN`.
    pub const ERR_UNKNOWN: i32 = 3001;
    /// `UT_ROBOT_ERR_CLIENT_SEND`.
    pub const ERR_CLIENT_SEND: i32 = 3102;
    /// `UT_ROBOT_ERR_CLIENT_API_NOT_REG`.
    pub const ERR_CLIENT_API_NOT_REG: i32 = 3103;
    /// `UT_ROBOT_ERR_CLIENT_API_TIMEOUT`.
    pub const ERR_CLIENT_API_TIMEOUT: i32 = 3104;
    /// `UT_ROBOT_ERR_CLIENT_API_NOT_MATCH`.
    pub const ERR_CLIENT_API_NOT_MATCH: i32 = 3105;
    /// `UT_ROBOT_ERR_CLIENT_API_DATA`.
    pub const ERR_CLIENT_API_DATA: i32 = 3106;
    /// `UT_ROBOT_ERR_CLIENT_LEASE_INVALID`.
    pub const ERR_CLIENT_LEASE_INVALID: i32 = 3107;
    /// `UT_ROBOT_ERR_SERVER_SEND`.
    pub const ERR_SERVER_SEND: i32 = 3201;
    /// `UT_ROBOT_ERR_SERVER_INTERNAL`.
    pub const ERR_SERVER_INTERNAL: i32 = 3202;
    /// `UT_ROBOT_ERR_SERVER_API_NOT_IMPL`.
    pub const ERR_SERVER_API_NOT_IMPL: i32 = 3203;
    /// `UT_ROBOT_ERR_SERVER_API_PARAMETER`.
    pub const ERR_SERVER_API_PARAMETER: i32 = 3204;
    /// `UT_ROBOT_ERR_SERVER_LEASE_DENIED`.
    pub const ERR_SERVER_LEASE_DENIED: i32 = 3205;
    /// `UT_ROBOT_ERR_SERVER_LEASE_NOT_EXIST`.
    pub const ERR_SERVER_LEASE_NOT_EXIST: i32 = 3206;
    /// `UT_ROBOT_ERR_SERVER_LEASE_EXIST`.
    pub const ERR_SERVER_LEASE_EXIST: i32 = 3207;
}

/// API ids every server answers (`include/unitree/robot/internal/internal_api.hpp`).
pub mod internal {
    /// `ROBOT_INTERNAL_API_ID_MAX`: ids up to this are the SDK's own, not a service's.
    pub const API_ID_MAX: i64 = 100;
    /// `ROBOT_API_ID_INTERNAL_API_VERSION`: the server answers with its API version string.
    pub const API_VERSION: i64 = 1;
    /// `ROBOT_API_ID_LEASE_APPLY`.
    pub const LEASE_APPLY: i64 = 101;
    /// `ROBOT_API_ID_LEASE_RENEWAL`.
    pub const LEASE_RENEWAL: i64 = 102;
}

/// The locomotion services of Unitree's humanoids, as the SDK's `LocoClient`s call them.
pub mod loco {
    /// One variant of the locomotion RPC: its service name, API version and API ids.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct LocoApi {
        /// Which SDK header it comes from (for messages).
        pub robot: &'static str,
        /// Service name: topics `rt/api/<service>/request|response`.
        pub service: &'static str,
        /// What the server answers to `ROBOT_API_ID_INTERNAL_API_VERSION`.
        pub version: &'static str,
        /// Reads the current FSM id (the locomotion state machine's state).
        pub get_fsm_id: i64,
        /// Reads the FSM mode, a detail of the current FSM state.
        pub get_fsm_mode: i64,
        /// Reads the balance mode (0 = balance stand, 1 = continuous gait).
        pub get_balance_mode: i64,
        /// Reads the swing (foot lift) height of the gait.
        pub get_swing_height: i64,
        /// Reads the standing height.
        pub get_stand_height: i64,
        /// Reads the gait phase. Deprecated in the headers.
        pub get_phase: i64,
        /// Switches the FSM to another id (see [`fsm`]).
        pub set_fsm_id: i64,
        /// Sets the balance mode (0 = balance stand, 1 = continuous gait).
        pub set_balance_mode: i64,
        /// Sets the swing (foot lift) height of the gait.
        pub set_swing_height: i64,
        /// Sets the standing height.
        pub set_stand_height: i64,
        /// Sets the body velocity command (vx, vy in m/s, yaw rate in rad/s) for a duration in s.
        pub set_velocity: i64,
        /// Odometry calls (H1 only): enable, disable, get.
        pub odom: Option<[i64; 3]>,
    }

    /// H1 / H1-2: `include/unitree/robot/h1/loco/h1_loco_api.hpp` (`LOCO_SERVICE_NAME = "loco"`,
    /// `LOCO_API_VERSION = "2.0.0.0"`, `ROBOT_API_ID_LOCO_*` 8001..8006, 8101..8105, odometry 8201..8203); the same
    /// values in unitree_sdk2_python `unitree_sdk2py/h1/loco/h1_loco_api.py` (which lacks the odometry ids).
    pub const H1: LocoApi = LocoApi {
        robot: "h1",
        service: "loco",
        version: "2.0.0.0",
        get_fsm_id: 8001,
        get_fsm_mode: 8002,
        get_balance_mode: 8003,
        get_swing_height: 8004,
        get_stand_height: 8005,
        get_phase: 8006,
        set_fsm_id: 8101,
        set_balance_mode: 8102,
        set_swing_height: 8103,
        set_stand_height: 8104,
        set_velocity: 8105,
        odom: Some([8201, 8202, 8203]),
    };

    /// G1: `include/unitree/robot/g1/loco/g1_loco_api.hpp` (`LOCO_SERVICE_NAME = "sport"`,
    /// `LOCO_API_VERSION = "1.0.0.0"`, `ROBOT_API_ID_LOCO_*` 7001..7006, 7101..7105).
    pub const G1: LocoApi = LocoApi {
        robot: "g1",
        service: "sport",
        version: "1.0.0.0",
        get_fsm_id: 7001,
        get_fsm_mode: 7002,
        get_balance_mode: 7003,
        get_swing_height: 7004,
        get_stand_height: 7005,
        get_phase: 7006,
        set_fsm_id: 7101,
        set_balance_mode: 7102,
        set_swing_height: 7103,
        set_stand_height: 7104,
        set_velocity: 7105,
        odom: None,
    };

    /// H1 locomotion error codes: `include/unitree/robot/h1/loco/h1_loco_error.hpp`.
    pub mod status {
        /// `UT_ROBOT_LOCO_ERR_LOCOSTATE_NOT_AVAILABLE`.
        pub const ERR_LOCOSTATE_NOT_AVAILABLE: i32 = 8301;
        /// `UT_ROBOT_LOCO_ERR_INVALID_FSM_ID`.
        pub const ERR_INVALID_FSM_ID: i32 = 8302;
        /// `UT_ROBOT_LOCO_ERR_ODOMSTATE_NOT_AVAILABLE`.
        pub const ERR_ODOMSTATE_NOT_AVAILABLE: i32 = 8303;
    }

    /// FSM ids the SDK's `LocoClient` high-level calls set (`h1_loco_client.hpp`: `ZeroTorque()` = `SetFsmId(0)`,
    /// `Damp()` = 1, `StandUp()` = 2, `Start()` = 204).
    pub mod fsm {
        /// All motors without torque (`ZeroTorque()`).
        pub const ZERO_TORQUE: i64 = 0;
        /// Damping only: motors resist motion but hold no pose (`Damp()`).
        pub const DAMP: i64 = 1;
        /// Stand up and hold the standing pose (`StandUp()`).
        pub const STAND_UP: i64 = 2;
        /// Walking controller running, velocity commands accepted (`Start()`).
        pub const START: i64 = 204;
    }

    /// `duration` the SDK's `Move(vx, vy, vyaw, continous_move = true)` sends (`h1_loco_client.hpp`: 864000 s,
    /// ten days); `StopMove()` is `SetVelocity(0, 0, 0)` with the default duration 1 s.
    pub const CONTINUOUS_MOVE_DURATION: f64 = 864000.0;
}

/// The motion-switcher service: which motion service (the robot's own locomotion controller) holds the motors, and
/// releasing it so that a low-level controller can drive them alone. One API for every robot that has it (Unitree
/// declares it once, under `b2`, and the G1/H1-2 low-level examples use that client).
///
/// Values from Unitree's C++ SDK `include/unitree/robot/b2/motion_switcher/motion_switcher_api.hpp`
/// (`MOTION_SWITCHER_SERVICE_NAME`, `MOTION_SWITCHER_API_VERSION`, `MOTION_SWITCHER_API_ID_*`, the JSON classes
/// `JsonizeModeName` {`name`, `form`} and `JsonizeSilent` {`silent`}); the same values in unitree_sdk2_python
/// `unitree_sdk2py/comm/motion_switcher/motion_switcher_api.py` and `motion_switcher_client.py` (which the PyPI
/// wheel `unitree_sdk2` 1.0.1 does not ship).
pub mod motion_switcher {
    /// Service name: topics `rt/api/motion_switcher/request|response`.
    pub const SERVICE: &str = "motion_switcher";
    /// What the server answers to `ROBOT_API_ID_INTERNAL_API_VERSION`.
    pub const VERSION: &str = "1.0.0.1";
    /// `CheckMode`: answers `{"form": F, "name": N}`, `N` the active motion service's name, empty when released.
    pub const CHECK_MODE: i64 = 1001;
    /// `SelectMode(nameOrAlias)`: parameter `{"name": N}`, starts that motion service.
    pub const SELECT_MODE: i64 = 1002;
    /// `ReleaseMode()`: stops the active motion service.
    pub const RELEASE_MODE: i64 = 1003;
    /// `SetSilent(flag)`: parameter `{"silent": bool}`, whether the robot boots with no motion service.
    pub const SET_SILENT: i64 = 1004;
    /// `GetSilent()`: answers `{"silent": bool}`.
    pub const GET_SILENT: i64 = 1005;

    /// Service error codes listed in Unitree's G1 developer documentation, "Motion Switcher Service Interface"
    /// (support.unitree.com, `G1_developer/motion_witcher_service_interface`); no SDK header declares them.
    pub mod status {
        /// "Request parameter error."
        pub const ERR_PARAMETER: i32 = 7001;
        /// "Service busy, retry again please."
        pub const ERR_BUSY: i32 = 7002;
        /// "Unsupport mode name."
        pub const ERR_UNSUPPORTED_MODE_NAME: i32 = 7004;
    }
}
