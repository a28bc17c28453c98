//! Views of the fixed-layout `unitree_hg` types (H1-2, G1). Member lists as in
//! [`unitree_idl::hg`], checked against it at compile time.

use super::struct_view;

struct_view! {
    /// View of [`unitree_idl::hg::MotorCmd_`].
    unitree_idl::hg::MotorCmd_ => MotorCmdView {
        mode: value(u8),
        q: value(f32),
        dq: value(f32),
        tau: value(f32),
        kp: value(f32),
        kd: value(f32),
        reserve: value(u32),
    }
}

struct_view! {
    /// View of [`unitree_idl::hg::LowCmd_`] (`rt/lowcmd`).
    unitree_idl::hg::LowCmd_ => LowCmdView {
        mode_pr: value(u8),
        mode_machine: value(u8),
        motor_cmd: views(MotorCmdView, 35),
        reserve: value([u32; 4]),
        crc: value(u32),
    }
}

struct_view! {
    /// View of [`unitree_idl::hg::IMUState_`].
    unitree_idl::hg::IMUState_ => IMUStateView {
        quaternion: value([f32; 4]),
        gyroscope: value([f32; 3]),
        accelerometer: value([f32; 3]),
        rpy: value([f32; 3]),
        temperature: value(i16),
    }
}

struct_view! {
    /// View of [`unitree_idl::hg::MotorState_`].
    unitree_idl::hg::MotorState_ => MotorStateView {
        mode: value(u8),
        q: value(f32),
        dq: value(f32),
        ddq: value(f32),
        tau_est: value(f32),
        temperature: value([i16; 2]),
        vol: value(f32),
        sensor: value([u32; 2]),
        motorstate: value(u32),
        reserve: value([u32; 4]),
    }
}

struct_view! {
    /// View of [`unitree_idl::hg::LowState_`] (`rt/lowstate`).
    unitree_idl::hg::LowState_ => LowStateView {
        version: value([u32; 2]),
        mode_pr: value(u8),
        mode_machine: value(u8),
        tick: value(u32),
        imu_state: view(IMUStateView),
        motor_state: views(MotorStateView, 35),
        wireless_remote: value([u8; 40]),
        reserve: value([u32; 4]),
        crc: value(u32),
    }
}

struct_view! {
    /// View of [`unitree_idl::hg::PressSensorState_`].
    unitree_idl::hg::PressSensorState_ => PressSensorStateView {
        pressure: value([f32; 12]),
        temperature: value([f32; 12]),
        lost: value(u32),
        reserve: value(u32),
    }
}

struct_view! {
    /// View of [`unitree_idl::hg::BmsCmd_`].
    unitree_idl::hg::BmsCmd_ => BmsCmdView {
        cmd: value(u8),
        reserve: value([u8; 40]),
    }
}

struct_view! {
    /// View of [`unitree_idl::hg::BmsState_`].
    unitree_idl::hg::BmsState_ => BmsStateView {
        version_high: value(u8),
        version_low: value(u8),
        r#fn: value(u8),
        cell_vol: value([u16; 40]),
        bmsvoltage: value([u32; 3]),
        current: value(i32),
        soc: value(u8),
        soh: value(u8),
        temperature: value([i16; 12]),
        cycle: value(u16),
        manufacturer_date: value(u16),
        bmsstate: value([u32; 5]),
        reserve: value([u32; 3]),
    }
}

struct_view! {
    /// View of [`unitree_idl::hg::MainBoardState_`].
    unitree_idl::hg::MainBoardState_ => MainBoardStateView {
        fan_state: value([u16; 6]),
        temperature: value([i16; 6]),
        value: value([f32; 6]),
        state: value([u32; 6]),
    }
}
