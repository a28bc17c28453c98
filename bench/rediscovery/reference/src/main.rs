//! MuJoCo as the reference engine of the rediscovery benchmark: the same scenes (built as MJCF
//! strings) and the same oracles as the rapier versions. Every oracle must stay quiet here, which
//! shows that what it flags in a rapier version is not an artefact of the scene or the threshold.
#![forbid(unsafe_code)]

use mujoco_rs::prelude::*;
use rediscovery_harness::{
    BallJointLimit, Engine, OffCentreLanding, RestitutionDrop, SceneError, Series, WeldedDrop, WeldedDropRun, GRAVITY,
};

/// Reference time step (s): small, so that the reference is converged rather than fast.
const TIMESTEP: f64 = 0.001;

#[derive(Debug)]
struct Mujoco;

fn load(worldbody: &str) -> Result<MjData<Box<MjModel>>, SceneError> {
    let xml = format!(
        r#"<mujoco>
  <compiler angle="radian"/>
  <option timestep="{TIMESTEP}" gravity="0 0 {g}"/>
  <worldbody>
{worldbody}
  </worldbody>
</mujoco>"#,
        g = -GRAVITY
    );
    let m = MjModel::from_xml_string(&xml).map_err(|e| SceneError::Engine(format!("MJCF: {e}")))?;
    MjData::try_new(Box::new(m)).map_err(|e| SceneError::Engine(format!("MjData: {e}")))
}

/// Steps for `duration` seconds, sampling `observe(qpos, qvel)` after every step.
fn run(
    d: &mut MjData<Box<MjModel>>,
    duration: f64,
    mut observe: impl FnMut(&[f64], &[f64], f64),
) -> Result<(), SceneError> {
    let steps = (duration / TIMESTEP).ceil() as usize;
    observe(d.qpos(), d.qvel(), 0.0);
    for i in 1..=steps {
        d.step();
        if d.qpos().iter().chain(d.qvel().iter()).any(|x| !x.is_finite()) {
            return Err(SceneError::Engine("non-finite state".into()));
        }
        observe(d.qpos(), d.qvel(), i as f64 * TIMESTEP);
    }
    Ok(())
}

impl Engine for Mujoco {
    fn label(&self) -> String {
        format!("MuJoCo {}", mujoco_rs::mujoco_version())
    }

    fn restitution_drop(&mut self, _: &RestitutionDrop, _: f64) -> Result<Series, SceneError> {
        Err(SceneError::Unsupported("MuJoCo has no restitution coefficient; the reference is the analytic e²".into()))
    }

    fn offcentre_landing(&mut self, s: &OffCentreLanding) -> Result<Series, SceneError> {
        let [px, py, pz] = s.pedestal_half;
        let [bx, by, bz] = s.bar_half;
        let f = s.friction;
        let mut d = load(&format!(
            r#"<geom type="box" size="{px} {py} {pz}" pos="0 0 {pzn}" friction="{f} 0 0"/>
<body name="bar" pos="{x} 0 {z}">
  <freejoint/>
  <geom type="box" size="{bx} {by} {bz}" friction="{f} 0 0"/>
  <body name="tip" pos="{o} 0 0"><geom type="sphere" size="{r}" friction="{f} 0 0"/></body>
</body>"#,
            pzn = -pz,
            x = s.bar_x,
            z = s.gap + bz,
            r = s.tip_radius,
            o = s.tip_offset
        ))?;
        let mut out = Series::new();
        run(&mut d, s.duration, |q, _, t| out.push((t, rediscovery_harness::x_axis_tilt(q[3], q[4], q[5], q[6]))))?;
        Ok(out)
    }

    fn ball_joint_limit(&mut self, s: &BallJointLimit) -> Result<Series, SceneError> {
        let [rx, ry, rz] = s.rod_half;
        let mut d = load(&format!(
            r#"<body name="rod" pos="0 0 {z}">
  <joint type="ball" limited="true" range="0 {limit}"/>
  <geom type="box" size="{rx} {ry} {rz}" pos="{rx} 0 0"/>
</body>"#,
            z = s.pivot_z,
            limit = s.limit
        ))?;
        let mut out = Series::new();
        run(&mut d, s.duration, |q, _, t| out.push((t, rediscovery_harness::quat_angle(q[0], q[1], q[2], q[3]))))?;
        Ok(out)
    }

    fn welded_drop(&mut self, s: &WeldedDrop) -> Result<WeldedDropRun, SceneError> {
        let f = s.friction;
        let mut d = load(&format!(
            r#"<geom type="box" size="10 10 1" pos="0 0 -1" friction="{f} 0 0"/>
<body name="root" pos="0 0 {z}">
  <freejoint/>
  <geom type="sphere" size="{r}" friction="{f} 0 0"/>
  <body name="top" pos="0 0 {o}"><geom type="sphere" size="{tr}" friction="{f} 0 0"/></body>
</body>"#,
            z = s.radius + s.drop_height,
            r = s.radius,
            o = s.offset,
            tr = s.top_radius
        ))?;
        let mut out = WeldedDropRun::default();
        run(&mut d, s.duration, |q, v, t| {
            out.speed.push((t, (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()));
            out.height.push((t, q[2]));
        })?;
        Ok(out)
    }
}

fn main() -> std::process::ExitCode {
    rediscovery_harness::print_verdicts(&mut Mujoco)
}
