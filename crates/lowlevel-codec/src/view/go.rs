//! Views of the fixed-layout `unitree_go` types (Go2, H1, B2). Member lists as in
//! [`unitree_idl::go`], checked against it at compile time.

use super::struct_view;

struct_view! {
    /// View of [`unitree_idl::go::MotorCmd_`].
    unitree_idl::go::MotorCmd_ => MotorCmdView {
        mode: value(u8),
        q: value(f32),
        dq: value(f32),
        tau: value(f32),
        kp: value(f32),
        kd: value(f32),
        reserve: value([u32; 3]),
    }
}

struct_view! {
    /// View of [`unitree_idl::go::BmsCmd_`].
    unitree_idl::go::BmsCmd_ => BmsCmdView {
        off: value(u8),
        reserve: value([u8; 3]),
    }
}

struct_view! {
    /// View of [`unitree_idl::go::LowCmd_`] (`rt/lowcmd`).
    unitree_idl::go::LowCmd_ => LowCmdView {
        head: value([u8; 2]),
        level_flag: value(u8),
        frame_reserve: value(u8),
        sn: value([u32; 2]),
        version: value([u32; 2]),
        bandwidth: value(u16),
        motor_cmd: views(MotorCmdView, 20),
        bms_cmd: view(BmsCmdView),
        wireless_remote: value([u8; 40]),
        led: value([u8; 12]),
        fan: value([u8; 2]),
        gpio: value(u8),
        reserve: value(u32),
        crc: value(u32),
    }
}

struct_view! {
    /// View of [`unitree_idl::go::MotorState_`].
    unitree_idl::go::MotorState_ => MotorStateView {
        mode: value(u8),
        q: value(f32),
        dq: value(f32),
        ddq: value(f32),
        tau_est: value(f32),
        q_raw: value(f32),
        dq_raw: value(f32),
        ddq_raw: value(f32),
        temperature: value(u8),
        lost: value(u32),
        reserve: value([u32; 2]),
    }
}

struct_view! {
    /// View of [`unitree_idl::go::IMUState_`].
    unitree_idl::go::IMUState_ => IMUStateView {
        quaternion: value([f32; 4]),
        gyroscope: value([f32; 3]),
        accelerometer: value([f32; 3]),
        rpy: value([f32; 3]),
        temperature: value(u8),
    }
}

struct_view! {
    /// View of [`unitree_idl::go::BmsState_`].
    unitree_idl::go::BmsState_ => BmsStateView {
        version_high: value(u8),
        version_low: value(u8),
        status: value(u8),
        soc: value(u8),
        current: value(i32),
        cycle: value(u16),
        bq_ntc: value([u8; 2]),
        mcu_ntc: value([u8; 2]),
        cell_vol: value([u16; 15]),
    }
}

struct_view! {
    /// View of [`unitree_idl::go::LowState_`] (`rt/lowstate`).
    unitree_idl::go::LowState_ => LowStateView {
        head: value([u8; 2]),
        level_flag: value(u8),
        frame_reserve: value(u8),
        sn: value([u32; 2]),
        version: value([u32; 2]),
        bandwidth: value(u16),
        imu_state: view(IMUStateView),
        motor_state: views(MotorStateView, 20),
        bms_state: view(BmsStateView),
        foot_force: value([i16; 4]),
        foot_force_est: value([i16; 4]),
        tick: value(u32),
        wireless_remote: value([u8; 40]),
        bit_flag: value(u8),
        adc_reel: value(f32),
        temperature_ntc1: value(u8),
        temperature_ntc2: value(u8),
        power_v: value(f32),
        power_a: value(f32),
        fan_frequency: value([u16; 4]),
        reserve: value(u32),
        crc: value(u32),
    }
}

struct_view! {
    /// View of [`unitree_idl::go::TimeSpec_`].
    unitree_idl::go::TimeSpec_ => TimeSpecView {
        sec: value(i32),
        nanosec: value(u32),
    }
}

struct_view! {
    /// View of [`unitree_idl::go::PathPoint_`].
    unitree_idl::go::PathPoint_ => PathPointView {
        t_from_start: value(f32),
        x: value(f32),
        y: value(f32),
        yaw: value(f32),
        vx: value(f32),
        vy: value(f32),
        vyaw: value(f32),
    }
}

struct_view! {
    /// View of [`unitree_idl::go::SportModeState_`] (`rt/sportmodestate`).
    unitree_idl::go::SportModeState_ => SportModeStateView {
        stamp: view(TimeSpecView),
        error_code: value(u32),
        imu_state: view(IMUStateView),
        mode: value(u8),
        progress: value(f32),
        gait_type: value(u8),
        foot_raise_height: value(f32),
        position: value([f32; 3]),
        body_height: value(f32),
        velocity: value([f32; 3]),
        yaw_speed: value(f32),
        range_obstacle: value([f32; 4]),
        foot_force: value([i16; 4]),
        foot_position_body: value([f32; 12]),
        foot_speed_body: value([f32; 12]),
        path_point: views(PathPointView, 10),
    }
}
