//! `unitree_hg`: low-level messages of the H1-2 and G1 (module `unitree_hg::msg::dds_`).
//!
//! Member names, order and types follow Unitree's C++ SDK headers
//! (`include/unitree/idl/hg/*.hpp`), without the trailing underscore the C++ members carry.

use crate::macros::idl_struct;

/// Number of motor slots in hg LowCmd/LowState.
pub const MOTOR_SLOTS: usize = 35;

idl_struct! {
    /// Command for one motor: mode (0 disabled, 1 enabled), targets and gains of the PD law
    /// `tau = tau_ff + kp (q - q_meas) + kd (dq - dq_meas)`.
    "unitree_hg" struct MotorCmd_ {
        mode: u8,
        q: f32,
        dq: f32,
        tau: f32,
        kp: f32,
        kd: f32,
        reserve: u32,
    }
}

idl_struct! {
    /// Whole-body low-level command, topic `rt/lowcmd`.
    "unitree_hg" struct LowCmd_ {
        mode_pr: u8,
        mode_machine: u8,
        motor_cmd: [MotorCmd_; 35],
        reserve: [u32; 4],
        crc: u32,
    }
}

idl_struct! {
    /// IMU reading: quaternion (w, x, y, z), gyroscope (rad/s), accelerometer (m/s², specific
    /// force), roll-pitch-yaw (rad), temperature.
    "unitree_hg" struct IMUState_ {
        quaternion: [f32; 4],
        gyroscope: [f32; 3],
        accelerometer: [f32; 3],
        rpy: [f32; 3],
        temperature: i16,
    }
}

idl_struct! {
    /// State of one motor.
    "unitree_hg" struct MotorState_ {
        mode: u8,
        q: f32,
        dq: f32,
        ddq: f32,
        tau_est: f32,
        temperature: [i16; 2],
        vol: f32,
        sensor: [u32; 2],
        motorstate: u32,
        reserve: [u32; 4],
    }
}

idl_struct! {
    /// Whole-body low-level state, topic `rt/lowstate`.
    "unitree_hg" struct LowState_ {
        version: [u32; 2],
        mode_pr: u8,
        mode_machine: u8,
        tick: u32,
        imu_state: IMUState_,
        motor_state: [MotorState_; 35],
        wireless_remote: [u8; 40],
        reserve: [u32; 4],
        crc: u32,
    }
}

idl_struct! {
    /// Dexterous hand command.
    "unitree_hg" struct HandCmd_ {
        motor_cmd: Vec<MotorCmd_>,
        reserve: [u32; 4],
    }
}

idl_struct! {
    /// Tactile pressure sensor block of a hand.
    "unitree_hg" struct PressSensorState_ {
        pressure: [f32; 12],
        temperature: [f32; 12],
        lost: u32,
        reserve: u32,
    }
}

idl_struct! {
    /// Dexterous hand state.
    "unitree_hg" struct HandState_ {
        motor_state: Vec<MotorState_>,
        press_sensor_state: Vec<PressSensorState_>,
        imu_state: IMUState_,
        power_v: f32,
        power_a: f32,
        system_v: f32,
        device_v: f32,
        error: [u32; 2],
        reserve: [u32; 2],
    }
}

idl_struct! {
    /// Battery management command.
    "unitree_hg" struct BmsCmd_ {
        cmd: u8,
        reserve: [u8; 40],
    }
}

idl_struct! {
    /// Battery management state.
    "unitree_hg" struct BmsState_ {
        version_high: u8,
        version_low: u8,
        // `fn` in the C++ headers; a Rust keyword, so written raw here. Its wire/JSON name is `fn`.
        r#fn: u8,
        cell_vol: [u16; 40],
        bmsvoltage: [u32; 3],
        current: i32,
        soc: u8,
        soh: u8,
        temperature: [i16; 12],
        cycle: u16,
        manufacturer_date: u16,
        bmsstate: [u32; 5],
        reserve: [u32; 3],
    }
}

idl_struct! {
    /// Main board state.
    "unitree_hg" struct MainBoardState_ {
        fan_state: [u16; 6],
        temperature: [i16; 6],
        value: [f32; 6],
        state: [u32; 6],
    }
}
