//! MJCF export of a model: a free-floating base (free joint), hinge joints in slot order, motors in slot order,
//! explicit inertials (`fullinertia` in the link frame), the primitive collision shapes and optionally a floor.
//! Written from the model, not through MuJoCo's URDF import, so nothing is left to the importer's defaults.
use crate::model::{RobotModel, Shape};
use nalgebra::Isometry3;
use std::fmt::Write;

/// Which collision shapes to emit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum ShapeFilter {
    /// Every collision shape of the model.
    All,
    /// None (pure multibody, no contacts possible).
    None,
}

/// What the generated MJCF contains beyond the model itself.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MjcfOptions {
    pub timestep: f64,
    pub gravity: [f64; 3],
    /// Add the ground plane z = 0.
    pub floor: bool,
    pub shapes: ShapeFilter,
    /// Emit the model's armature / damping / frictionloss (false: 0).
    pub armature: bool,
    pub damping: bool,
    pub frictionloss: bool,
    /// Emit joint ranges as limits.
    pub joint_limits: bool,
    /// Extra attributes of `<option>` (e.g. integrator, cone, iterations), written verbatim.
    pub option_attrs: Vec<(String, String)>,
    /// Attributes of `<option><flag/>` (e.g. `energy="enable"`).
    pub flag_attrs: Vec<(String, String)>,
    /// Limit each motor's torque to its joint's `torque_limit` (`ctrlrange`, gear 1).
    pub motor_limits: bool,
    /// `<custom><numeric>` entries (name, data): values a simulator reads beside the model.
    pub custom: Vec<(String, Vec<f64>)>,
    /// An XML comment written at the top of the file (`--` is replaced, which XML comments cannot hold).
    pub comment: Option<String>,
}

impl Default for MjcfOptions {
    fn default() -> Self {
        MjcfOptions {
            timestep: 0.002,
            gravity: [0.0, 0.0, -crate::GRAVITY_EARTH],
            floor: true,
            shapes: ShapeFilter::All,
            armature: true,
            damping: true,
            frictionloss: true,
            joint_limits: true,
            option_attrs: Vec::new(),
            flag_attrs: Vec::new(),
            motor_limits: false,
            custom: Vec::new(),
            comment: None,
        }
    }
}

fn f(x: f64) -> String {
    // Shortest round-trip representation: MuJoCo parses it back to the same f64.
    let s = format!("{x:?}");
    if s == "-0.0" {
        "0".into()
    } else {
        s
    }
}

fn v3(v: &[f64]) -> String {
    v.iter().map(|&x| f(x)).collect::<Vec<_>>().join(" ")
}

fn pose_attrs(p: &Isometry3<f64>) -> String {
    let t = p.translation.vector;
    let q = p.rotation;
    format!(r#"pos="{}" quat="{}""#, v3(&[t.x, t.y, t.z]), v3(&[q.w, q.i, q.j, q.k]))
}

impl RobotModel {
    /// Generates an MJCF document of this model.
    pub fn to_mjcf(&self, o: &MjcfOptions) -> String {
        let mut s = String::new();
        let c = &self.contact;
        // Contact filtering by bitmasks: robot geoms (type 2, affinity 1) touch the floor (type 1, affinity 2);
        // robot-robot pairs collide only when the sidecar enables self-collision.
        let (rt, ra) = if c.self_collision { (3, 3) } else { (2, 1) };
        let fr = v3(&[c.friction, c.torsional_friction, c.rolling_friction]);
        if let Some(c) = &o.comment {
            let _ = writeln!(s, "<!--\n{}\n-->", c.replace("--", "- -"));
        }
        let _ = writeln!(s, r#"<mujoco model="{}">"#, self.name);
        let _ = writeln!(s, r#"  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>"#);
        let mut opt = format!(r#"timestep="{}" gravity="{}""#, f(o.timestep), v3(&o.gravity));
        for (k, v) in &o.option_attrs {
            let _ = write!(opt, r#" {k}="{v}""#);
        }
        if o.flag_attrs.is_empty() {
            let _ = writeln!(s, "  <option {opt}/>");
        } else {
            let flags: Vec<String> = o.flag_attrs.iter().map(|(k, v)| format!(r#"{k}="{v}""#)).collect();
            let _ = writeln!(s, "  <option {opt}>\n    <flag {}/>\n  </option>", flags.join(" "));
        }
        let _ = writeln!(s, "  <worldbody>");
        if o.floor {
            let _ = writeln!(
                s,
                r#"    <geom name="floor" type="plane" size="0 0 0.05" contype="1" conaffinity="{}" condim="3" friction="{fr}"/>"#,
                if c.self_collision { 3 } else { 2 }
            );
        }
        let base = &self.standing;
        let bp = base.base_pos;
        let bq = base.base_quat;
        self.body(&mut s, 0, 2, &format!(r#"pos="{}" quat="{}""#, v3(&bp), v3(&bq)), o, rt, ra, &fr);
        let _ = writeln!(s, "  </worldbody>");
        let _ = writeln!(s, "  <actuator>");
        for j in &self.joints {
            let range = if o.motor_limits {
                format!(r#" ctrllimited="true" ctrlrange="{} {}""#, f(-j.torque_limit), f(j.torque_limit))
            } else {
                String::new()
            };
            let _ = writeln!(s, r#"    <motor name="{}" joint="{}" gear="1"{range}/>"#, j.motor_name, j.name);
        }
        let _ = writeln!(s, "  </actuator>");
        if !o.custom.is_empty() {
            let _ = writeln!(s, "  <custom>");
            for (name, data) in &o.custom {
                let d: Vec<String> = data.iter().map(|x| f(*x)).collect();
                let _ = writeln!(s, r#"    <numeric name="{name}" data="{}"/>"#, d.join(" "));
            }
            let _ = writeln!(s, "  </custom>");
        }
        let _ = writeln!(s, "</mujoco>");
        s
    }

    #[allow(clippy::too_many_arguments)]
    fn body(
        &self,
        s: &mut String,
        li: usize,
        depth: usize,
        placement: &str,
        o: &MjcfOptions,
        rt: u32,
        ra: u32,
        fr: &str,
    ) {
        let pad = " ".repeat(depth * 2);
        let l = &self.links[li];
        let _ = writeln!(s, r#"{pad}<body name="{}" {placement}>"#, l.name);
        let i = &l.inertial;
        let m = &i.inertia;
        let _ = writeln!(
            s,
            r#"{pad}  <inertial pos="{}" mass="{}" fullinertia="{}"/>"#,
            v3(&[i.com.x, i.com.y, i.com.z]),
            f(i.mass),
            v3(&[m[(0, 0)], m[(1, 1)], m[(2, 2)], m[(0, 1)], m[(0, 2)], m[(1, 2)]])
        );
        match l.parent_joint {
            None => {
                let _ = writeln!(s, r#"{pad}  <freejoint name="floating_base_joint"/>"#);
            }
            Some(ji) => {
                let j = &self.joints[ji];
                let a = j.axis;
                let mut attrs = format!(
                    r#"name="{}" type="hinge" pos="0 0 0" axis="{}" armature="{}" damping="{}" frictionloss="{}""#,
                    j.name,
                    v3(&[a.x, a.y, a.z]),
                    f(if o.armature { j.armature } else { 0.0 }),
                    f(if o.damping { j.damping } else { 0.0 }),
                    f(if o.frictionloss { j.frictionloss } else { 0.0 }),
                );
                if o.joint_limits {
                    let _ = write!(attrs, r#" limited="true" range="{} {}""#, f(j.lower), f(j.upper));
                } else {
                    let _ = write!(attrs, r#" limited="false""#);
                }
                let _ = writeln!(s, "{pad}  <joint {attrs}/>");
            }
        }
        if o.shapes == ShapeFilter::All {
            for (k, c) in l.collisions.iter().enumerate() {
                let (ty, size) = match c.shape {
                    Shape::Box { half_extents: h } => ("box", v3(&h)),
                    Shape::Sphere { radius } => ("sphere", f(radius)),
                    Shape::Capsule { radius, half_length } => ("capsule", v3(&[radius, half_length])),
                    Shape::Cylinder { radius, half_length } => ("cylinder", v3(&[radius, half_length])),
                };
                let _ = writeln!(
                    s,
                    r#"{pad}  <geom name="{}_c{k}" type="{ty}" size="{size}" {} contype="{rt}" conaffinity="{ra}" condim="3" friction="{fr}" mass="0"/>"#,
                    l.name,
                    pose_attrs(&c.origin)
                );
            }
        }
        if li == self.imu.link {
            let _ =
                writeln!(s, r#"{pad}  <site name="imu" pos="{}" quat="{}"/>"#, v3(&self.imu.pos), v3(&self.imu.quat));
        }
        for ji in self.child_joints(li) {
            let j = &self.joints[ji];
            self.body(s, j.child_link, depth + 1, &pose_attrs(&j.origin), o, rt, ra, fr);
        }
        let _ = writeln!(s, "{pad}</body>");
    }
}
