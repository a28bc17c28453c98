//! `unitree_go`: low-level messages of the Go2, H1 and B2 (module `unitree_go::msg::dds_`).
//!
//! Member names, order and types follow Unitree's C++ SDK headers
//! (`include/unitree/idl/go2/*.hpp`), without the trailing underscore.

use crate::macros::idl_struct;

/// Number of motor slots in go LowCmd/LowState.
pub const MOTOR_SLOTS: usize = 20;

/// Value of `head` in every go LowCmd (`FE EF`).
pub const LOWCMD_HEAD: [u8; 2] = [0xFE, 0xEF];
/// Value of `level_flag` for low-level control.
pub const LOWLEVEL_FLAG: u8 = 0xFF;

idl_struct! {
    /// Command for one motor.
    "unitree_go" struct MotorCmd_ {
        mode: u8,
        q: f32,
        dq: f32,
        tau: f32,
        kp: f32,
        kd: f32,
        reserve: [u32; 3],
    }
}

idl_struct! {
    /// Battery command.
    "unitree_go" struct BmsCmd_ {
        off: u8,
        reserve: [u8; 3],
    }
}

idl_struct! {
    /// Whole-body low-level command, topic `rt/lowcmd`.
    "unitree_go" struct LowCmd_ {
        head: [u8; 2],
        level_flag: u8,
        frame_reserve: u8,
        sn: [u32; 2],
        version: [u32; 2],
        bandwidth: u16,
        motor_cmd: [MotorCmd_; 20],
        bms_cmd: BmsCmd_,
        wireless_remote: [u8; 40],
        led: [u8; 12],
        fan: [u8; 2],
        gpio: u8,
        reserve: u32,
        crc: u32,
    }
}

idl_struct! {
    /// State of one motor.
    "unitree_go" struct MotorState_ {
        mode: u8,
        q: f32,
        dq: f32,
        ddq: f32,
        tau_est: f32,
        q_raw: f32,
        dq_raw: f32,
        ddq_raw: f32,
        temperature: u8,
        lost: u32,
        reserve: [u32; 2],
    }
}

idl_struct! {
    /// IMU reading; unlike hg, the temperature is an unsigned byte.
    "unitree_go" struct IMUState_ {
        quaternion: [f32; 4],
        gyroscope: [f32; 3],
        accelerometer: [f32; 3],
        rpy: [f32; 3],
        temperature: u8,
    }
}

idl_struct! {
    /// Battery state.
    "unitree_go" struct BmsState_ {
        version_high: u8,
        version_low: u8,
        status: u8,
        soc: u8,
        current: i32,
        cycle: u16,
        bq_ntc: [u8; 2],
        mcu_ntc: [u8; 2],
        cell_vol: [u16; 15],
    }
}

idl_struct! {
    /// Whole-body low-level state, topic `rt/lowstate`.
    "unitree_go" struct LowState_ {
        head: [u8; 2],
        level_flag: u8,
        frame_reserve: u8,
        sn: [u32; 2],
        version: [u32; 2],
        bandwidth: u16,
        imu_state: IMUState_,
        motor_state: [MotorState_; 20],
        bms_state: BmsState_,
        foot_force: [i16; 4],
        foot_force_est: [i16; 4],
        tick: u32,
        wireless_remote: [u8; 40],
        bit_flag: u8,
        adc_reel: f32,
        temperature_ntc1: u8,
        temperature_ntc2: u8,
        power_v: f32,
        power_a: f32,
        fan_frequency: [u16; 4],
        reserve: u32,
        crc: u32,
    }
}
