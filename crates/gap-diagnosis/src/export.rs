//! The corrected model a diagnosis hands back: the robot's MJCF with the named effects' fitted parameters, for the
//! user's own simulator (`ulab gap diagnose --export-mjcf`).
//!
//! What MJCF can hold goes into the model: armature (the joint's `armature`), viscous damping (`damping`), dry
//! friction (`frictionloss`: MuJoCo's is a hard Coulomb law, the library's a smooth one with stiction), a torque
//! saturation (the motor's `ctrlrange`, without the library's torque-speed line), a link's mass and inertia and its
//! centre of mass (the body's `inertial`). What belongs to the drive or the sensors, which a simulator's controller
//! applies, goes into `<custom><numeric>` entries, one value per motor slot, with the law in the file's comment:
//! `ulab_gain_scale` (kp and kd multiplier), `ulab_encoder_offset` (rad; reading = true angle + offset),
//! `ulab_backlash` (rad; the PD law sees no position error inside the band and the error beyond it minus half the
//! band), `ulab_command_latency` (s), `ulab_imu_gyro_bias` (rad/s, IMU frame) and `ulab_imu_misalignment` (rotation
//! vector, rad).
use crate::diagnose::Report;
use crate::effects::EffectKind;
use crate::plant::{joint_groups, Effects, EngineChoice, DT, GROUPS};
use crate::GapError;
use robot_model::{MjcfOptions, RobotModel};

/// The named effects of `report` as effect parameters on `model`'s joints.
pub fn named_effects(model: &RobotModel, report: &Report) -> Result<Effects, GapError> {
    let mut fx = Effects::none(model.nj());
    let groups = joint_groups(model);
    for e in report.effects.iter().filter(|e| e.named) {
        for p in &e.params {
            let internal = if e.kind == EffectKind::Latency { p.value * 1e-3 / DT } else { p.value };
            let unit = p.unit.as_str();
            if let Some(axis) = ["imu_x", "imu_y", "imu_z"].iter().position(|a| *a == unit) {
                e.kind.set(&mut fx, axis, internal);
            } else if unit == "robot" {
                e.kind.set(&mut fx, 0, internal);
            } else if let Some(g) = GROUPS.iter().position(|g| *g == unit) {
                (0..model.nj()).filter(|&j| groups[j] == g).for_each(|j| e.kind.set(&mut fx, j, internal));
            } else if let Some(j) = model.joints.iter().position(|j| j.motor_name == unit) {
                e.kind.set(&mut fx, j, internal);
            } else {
                return Err(GapError::Input(format!("report: {} names unknown unit {unit:?}", e.kind.name())));
            }
        }
    }
    Ok(fx)
}

/// The MJCF of `model` corrected by the named effects of `report` (which must describe a log of this model).
pub fn corrected_mjcf(model: &RobotModel, report: &Report) -> Result<String, GapError> {
    mjcf_with(model, report, &named_effects(model, report)?)
}

/// The MJCF of `model` as the diagnosis replayed it, without any named effect: the file [`corrected_mjcf`] differs
/// from by exactly the corrections (same numerics, same layout).
pub fn nominal_mjcf(model: &RobotModel, report: &Report) -> Result<String, GapError> {
    mjcf_with(model, report, &Effects::none(model.nj()))
}

fn mjcf_with(model: &RobotModel, report: &Report, fx: &Effects) -> Result<String, GapError> {
    let mut m = fx.apply_to_model(model);
    for (j, joint) in m.joints.iter_mut().enumerate() {
        joint.damping += fx.damping[j];
        joint.frictionloss += fx.coulomb[j];
        joint.torque_limit *= fx.torque_scale[j];
    }
    let engine = EngineChoice::parse(&report.engine)?;
    let integrator = engine.mujoco_integrator()?.to_string();
    let timestep = report.numerics.as_ref().and_then(|n| n.better_variant()).map_or(DT, |v| 1e-3 * v.timestep_ms);
    let nothing = fx == &Effects::none(model.nj());
    let named: Vec<String> = report
        .effects
        .iter()
        .filter(|e| e.named && !nothing)
        .map(|e| {
            let p: Vec<String> = e.params.iter().map(|p| format!("{} = {}", p.unit, p.value)).collect();
            format!("  {} ({}): {}", e.kind.name(), e.kind.parameter(), p.join(", "))
        })
        .collect();
    let comment = format!(
        "{} corrected by `ulab gap diagnose` ({}).\nNamed effects:\n{}\nIn the model: armature, damping, \
         frictionloss (a hard Coulomb law), the motors' ctrlrange (a torque saturation, without the library's \
         torque-speed line), link masses, inertias and centres of mass.\nFor the controller (custom numerics, one \
         value per motor slot): ulab_gain_scale multiplies kp and kd; ulab_encoder_offset is added to the true angle \
         in every reading; ulab_backlash is a dead band on the PD law's position error (none inside it, the error \
         minus half the band beyond it); ulab_command_latency delays every command (s); ulab_imu_gyro_bias is added \
         to the gyroscope (IMU frame); ulab_imu_misalignment rotates the IMU (rotation vector).\nTimestep {timestep} \
         s, integrator {integrator}: the numerics the log was replayed with.",
        model.name,
        report.schema_version,
        if named.is_empty() { "  none".to_string() } else { named.join("\n") }
    );
    let opts = MjcfOptions {
        timestep,
        option_attrs: vec![("integrator".into(), integrator)],
        motor_limits: true,
        custom: vec![
            ("ulab_gain_scale".into(), fx.gain_scale.clone()),
            ("ulab_encoder_offset".into(), fx.encoder_offset.clone()),
            ("ulab_backlash".into(), fx.backlash.clone()),
            ("ulab_command_latency".into(), vec![fx.latency_steps as f64 * DT]),
            ("ulab_imu_gyro_bias".into(), fx.imu_gyro_bias.to_vec()),
            ("ulab_imu_misalignment".into(), fx.imu_misalignment.to_vec()),
        ],
        comment: Some(comment),
        ..MjcfOptions::default()
    };
    Ok(m.to_mjcf(&opts))
}
