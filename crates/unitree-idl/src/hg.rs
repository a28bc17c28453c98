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
        /// 0 = motor off (no torque), 1 = enabled (runs the PD law above).
        mode: u8,
        /// Target position (rad).
        q: f32,
        /// Target velocity (rad/s).
        dq: f32,
        /// Feed-forward torque (N·m).
        tau: f32,
        /// Position gain, stiffness (N·m/rad).
        kp: f32,
        /// Velocity gain, damping (N·m·s/rad).
        kd: f32,
        /// Unused; zero.
        reserve: u32,
    }
}

idl_struct! {
    /// Whole-body low-level command, topic `rt/lowcmd`.
    "unitree_hg" struct LowCmd_ {
        /// Ankle parallel-mechanism mode: 0 = PR (commands address the pitch/roll joints), 1 = AB (the
        /// two ankle motors directly).
        mode_pr: u8,
        /// Robot type code; controllers copy it from the latest LowState.
        mode_machine: u8,
        /// One command per motor slot (see [`MOTOR_SLOTS`]; unused slots stay zero).
        motor_cmd: [MotorCmd_; 35],
        /// Unused; zero.
        reserve: [u32; 4],
        /// Unitree CRC32 of the C struct image up to this word (padding zeroed); `lowlevel_codec::crc`
        /// computes and checks it.
        crc: u32,
    }
}

idl_struct! {
    /// IMU reading: quaternion (w, x, y, z), gyroscope (rad/s), accelerometer (m/s², specific
    /// force), roll-pitch-yaw (rad), temperature.
    "unitree_hg" struct IMUState_ {
        /// Orientation as a unit quaternion (w, x, y, z).
        quaternion: [f32; 4],
        /// Angular velocity in the IMU frame (rad/s).
        gyroscope: [f32; 3],
        /// Specific force in the IMU frame (m/s²; reads about +9.81 upward at rest).
        accelerometer: [f32; 3],
        /// Roll, pitch, yaw (rad), the same orientation as Euler angles.
        rpy: [f32; 3],
        /// IMU temperature (°C).
        temperature: i16,
    }
}

idl_struct! {
    /// State of one motor.
    "unitree_hg" struct MotorState_ {
        /// Mode the motor is in (0 = off, 1 = enabled), as reported by its driver.
        mode: u8,
        /// Measured position (rad).
        q: f32,
        /// Measured velocity (rad/s).
        dq: f32,
        /// Measured acceleration (rad/s²).
        ddq: f32,
        /// Estimated output torque (N·m).
        tau_est: f32,
        /// Two temperature readings of the motor (°C).
        temperature: [i16; 2],
        /// Motor supply voltage (V).
        vol: f32,
        /// Raw sensor words, meaning not published.
        sensor: [u32; 2],
        /// Motor status/error bits as the driver reports them; 0 when healthy.
        motorstate: u32,
        /// Unused; zero.
        reserve: [u32; 4],
    }
}

idl_struct! {
    /// Whole-body low-level state, topic `rt/lowstate`.
    "unitree_hg" struct LowState_ {
        /// Firmware version words.
        version: [u32; 2],
        /// Ankle parallel-mechanism mode in effect (0 = PR, 1 = AB), as in [`LowCmd_::mode_pr`].
        mode_pr: u8,
        /// Robot type code; controllers echo it in [`LowCmd_::mode_machine`].
        mode_machine: u8,
        /// Time counter of the robot (ms); wraps around.
        tick: u32,
        /// The main IMU (on the H1-2 it sits on the torso, past the waist joint [`crate::h1_2::TORSO_SLOT`]).
        imu_state: IMUState_,
        /// One state per motor slot (see [`MOTOR_SLOTS`]).
        motor_state: [MotorState_; 35],
        /// Raw frame of the handheld wireless remote (buttons and sticks).
        wireless_remote: [u8; 40],
        /// Unused; zero.
        reserve: [u32; 4],
        /// Unitree CRC32 of the C struct image up to this word, as in [`LowCmd_::crc`].
        crc: u32,
    }
}

idl_struct! {
    /// Dexterous hand command.
    "unitree_hg" struct HandCmd_ {
        /// One command per hand motor; the length is the hand's motor count.
        motor_cmd: Vec<MotorCmd_>,
        /// Unused; zero.
        reserve: [u32; 4],
    }
}

idl_struct! {
    /// Tactile pressure sensor block of a hand.
    "unitree_hg" struct PressSensorState_ {
        /// Readings of the 12 pressure cells.
        pressure: [f32; 12],
        /// Temperature of each of the 12 cells (°C).
        temperature: [f32; 12],
        /// Count of lost sensor frames.
        lost: u32,
        /// Unused; zero.
        reserve: u32,
    }
}

idl_struct! {
    /// Dexterous hand state.
    "unitree_hg" struct HandState_ {
        /// State of each hand motor, in the order of [`HandCmd_::motor_cmd`].
        motor_state: Vec<MotorState_>,
        /// The hand's tactile sensor blocks.
        press_sensor_state: Vec<PressSensorState_>,
        /// IMU of the hand.
        imu_state: IMUState_,
        /// Supply voltage (V).
        power_v: f32,
        /// Supply current (A).
        power_a: f32,
        /// System rail voltage (V).
        system_v: f32,
        /// Device rail voltage (V).
        device_v: f32,
        /// Error bits; 0 when healthy.
        error: [u32; 2],
        /// Unused; zero.
        reserve: [u32; 2],
    }
}

idl_struct! {
    /// Battery management command.
    "unitree_hg" struct BmsCmd_ {
        /// Command code for the battery management system.
        cmd: u8,
        /// Unused; zero.
        reserve: [u8; 40],
    }
}

idl_struct! {
    /// Battery management state.
    "unitree_hg" struct BmsState_ {
        /// Major part of the BMS firmware version.
        version_high: u8,
        /// Minor part of the BMS firmware version.
        version_low: u8,
        // `fn` in the C++ headers; a Rust keyword, so written raw here. Its wire/JSON name is `fn`.
        /// BMS function/status code (member `fn` on the wire and in JSON).
        r#fn: u8,
        /// Voltage of each cell (mV); unused entries are zero.
        cell_vol: [u16; 40],
        /// Pack voltage readings.
        bmsvoltage: [u32; 3],
        /// Pack current, signed (charging and discharging have opposite signs).
        current: i32,
        /// State of charge (%).
        soc: u8,
        /// State of health (%).
        soh: u8,
        /// Temperature sensors of the pack (°C).
        temperature: [i16; 12],
        /// Charge cycle count.
        cycle: u16,
        /// Date of manufacture, packed as the BMS reports it.
        manufacturer_date: u16,
        /// BMS status words.
        bmsstate: [u32; 5],
        /// Unused; zero.
        reserve: [u32; 3],
    }
}

idl_struct! {
    /// Main board state.
    "unitree_hg" struct MainBoardState_ {
        /// State of each fan.
        fan_state: [u16; 6],
        /// Board temperatures (°C).
        temperature: [i16; 6],
        /// Board measurements, meaning not published.
        value: [f32; 6],
        /// Board status words.
        state: [u32; 6],
    }
}
