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
        /// Motor mode: 0x01 = servo (PD law) enabled, 0x00 = off.
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
        reserve: [u32; 3],
    }
}

idl_struct! {
    /// Battery command.
    "unitree_go" struct BmsCmd_ {
        /// Battery power-off request byte; zero in normal operation.
        off: u8,
        /// Unused; zero.
        reserve: [u8; 3],
    }
}

idl_struct! {
    /// Whole-body low-level command, topic `rt/lowcmd`.
    "unitree_go" struct LowCmd_ {
        /// Frame header, always [`LOWCMD_HEAD`].
        head: [u8; 2],
        /// Control level; [`LOWLEVEL_FLAG`] for low-level control.
        level_flag: u8,
        /// Unused; zero.
        frame_reserve: u8,
        /// Serial number words.
        sn: [u32; 2],
        /// Version words.
        version: [u32; 2],
        /// Link bandwidth field; zero in commands.
        bandwidth: u16,
        /// One command per motor slot (see [`MOTOR_SLOTS`]; unused slots stay zero).
        motor_cmd: [MotorCmd_; 20],
        /// Battery command.
        bms_cmd: BmsCmd_,
        /// Raw wireless-remote frame (buttons and sticks).
        wireless_remote: [u8; 40],
        /// LED control bytes.
        led: [u8; 12],
        /// Fan control bytes.
        fan: [u8; 2],
        /// GPIO output byte.
        gpio: u8,
        /// Unused; zero.
        reserve: u32,
        /// Unitree CRC32 of the C struct image up to this word (padding zeroed); `lowlevel_codec::crc`
        /// computes and checks it.
        crc: u32,
    }
}

idl_struct! {
    /// State of one motor.
    "unitree_go" struct MotorState_ {
        /// Mode the motor is in, as reported by its driver.
        mode: u8,
        /// Measured position (rad).
        q: f32,
        /// Measured velocity (rad/s).
        dq: f32,
        /// Measured acceleration (rad/s²).
        ddq: f32,
        /// Estimated output torque (N·m).
        tau_est: f32,
        /// Unfiltered position reading (rad).
        q_raw: f32,
        /// Unfiltered velocity reading (rad/s).
        dq_raw: f32,
        /// Unfiltered acceleration reading (rad/s²).
        ddq_raw: f32,
        /// Motor temperature (°C).
        temperature: u8,
        /// Count of lost frames between the board and this motor.
        lost: u32,
        /// Unused; zero.
        reserve: [u32; 2],
    }
}

idl_struct! {
    /// IMU reading; unlike hg, the temperature is an unsigned byte.
    "unitree_go" struct IMUState_ {
        /// Orientation as a unit quaternion (w, x, y, z).
        quaternion: [f32; 4],
        /// Angular velocity in the IMU frame (rad/s).
        gyroscope: [f32; 3],
        /// Specific force in the IMU frame (m/s²; reads about +9.81 upward at rest).
        accelerometer: [f32; 3],
        /// Roll, pitch, yaw (rad), the same orientation as Euler angles.
        rpy: [f32; 3],
        /// IMU temperature (°C).
        temperature: u8,
    }
}

idl_struct! {
    /// Battery state.
    "unitree_go" struct BmsState_ {
        /// Major part of the BMS firmware version.
        version_high: u8,
        /// Minor part of the BMS firmware version.
        version_low: u8,
        /// BMS status code.
        status: u8,
        /// State of charge (%).
        soc: u8,
        /// Pack current, signed (charging and discharging have opposite signs).
        current: i32,
        /// Charge cycle count.
        cycle: u16,
        /// Thermistor temperatures at the battery monitor chip (°C).
        bq_ntc: [u8; 2],
        /// Thermistor temperatures at the BMS microcontroller (°C).
        mcu_ntc: [u8; 2],
        /// Voltage of each cell (mV).
        cell_vol: [u16; 15],
    }
}

idl_struct! {
    /// Whole-body low-level state, topic `rt/lowstate`.
    "unitree_go" struct LowState_ {
        /// Frame header.
        head: [u8; 2],
        /// Control level the robot is in.
        level_flag: u8,
        /// Unused.
        frame_reserve: u8,
        /// Serial number words.
        sn: [u32; 2],
        /// Version words.
        version: [u32; 2],
        /// Link bandwidth field.
        bandwidth: u16,
        /// The body IMU.
        imu_state: IMUState_,
        /// One state per motor slot (see [`MOTOR_SLOTS`]).
        motor_state: [MotorState_; 20],
        /// Battery state.
        bms_state: BmsState_,
        /// Foot contact sensor readings, one per foot (raw units).
        foot_force: [i16; 4],
        /// Estimated foot contact forces, one per foot (raw units).
        foot_force_est: [i16; 4],
        /// Time counter of the robot (ms); wraps around.
        tick: u32,
        /// Raw wireless-remote frame (buttons and sticks).
        wireless_remote: [u8; 40],
        /// Status bits.
        bit_flag: u8,
        /// ADC reading reported by the board.
        adc_reel: f32,
        /// First board thermistor (°C).
        temperature_ntc1: u8,
        /// Second board thermistor (°C).
        temperature_ntc2: u8,
        /// Supply voltage (V).
        power_v: f32,
        /// Supply current (A).
        power_a: f32,
        /// Speed of each fan.
        fan_frequency: [u16; 4],
        /// Unused; zero.
        reserve: u32,
        /// Unitree CRC32 of the C struct image up to this word, as in [`LowCmd_::crc`].
        crc: u32,
    }
}

idl_struct! {
    /// A time stamp (`builtin_interfaces` style).
    "unitree_go" struct TimeSpec_ {
        /// Seconds.
        sec: i32,
        /// Nanoseconds within the second.
        nanosec: u32,
    }
}

idl_struct! {
    /// One point of the sport mode's planned path.
    "unitree_go" struct PathPoint_ {
        /// Time of the point from the start of the path (s).
        t_from_start: f32,
        /// Position x (m).
        x: f32,
        /// Position y (m).
        y: f32,
        /// Heading (rad).
        yaw: f32,
        /// Velocity x (m/s).
        vx: f32,
        /// Velocity y (m/s).
        vy: f32,
        /// Yaw rate (rad/s).
        vyaw: f32,
    }
}

idl_struct! {
    /// The sport (high-level) controller's state, topic [`crate::topics::SPORTMODESTATE`]: the body's pose and
    /// velocity in the odometry frame. Unitree's MuJoCo bridge publishes it with the simulator's own pelvis pose,
    /// and so does `ulab sim`.
    "unitree_go" struct SportModeState_ {
        /// Time of the state.
        stamp: TimeSpec_,
        /// Error code of the sport controller; 0 = none.
        error_code: u32,
        /// The body IMU.
        imu_state: IMUState_,
        /// Sport mode.
        mode: u8,
        /// Progress of the current motion (0 to 1).
        progress: f32,
        /// Gait type.
        gait_type: u8,
        /// Foot raise height (m).
        foot_raise_height: f32,
        /// Body position, odometry frame (m).
        position: [f32; 3],
        /// Body height above the ground (m).
        body_height: f32,
        /// Body velocity, odometry frame (m/s).
        velocity: [f32; 3],
        /// Yaw rate (rad/s).
        yaw_speed: f32,
        /// Distance to obstacles in four directions (m).
        range_obstacle: [f32; 4],
        /// Foot contact forces (raw units).
        foot_force: [i16; 4],
        /// Foot positions in the body frame (m), x, y, z per foot.
        foot_position_body: [f32; 12],
        /// Foot velocities in the body frame (m/s), x, y, z per foot.
        foot_speed_body: [f32; 12],
        /// The planned path.
        path_point: [PathPoint_; 10],
    }
}
