//! Loading and validation of URDF + sidecar TOML.
use crate::error::ModelError;
use crate::model::*;
use nalgebra::{Isometry3, Matrix3, Translation3, Unit, UnitQuaternion, Vector3};
use serde::Deserialize;
use std::collections::HashMap;
use std::path::Path;

const H1_2_URDF: &str = include_str!("../../../robots/h1_2/h1_2.urdf");
const H1_2_TOML: &str = include_str!("../../../robots/h1_2/h1_2.toml");

/// The sidecar TOML file, as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SidecarFile {
    pub model: SidecarModel,
    pub joint_defaults: JointDefaults,
    pub standing: SidecarStanding,
    pub contact: SidecarContact,
    pub imu: SidecarImu,
    pub motor: Vec<SidecarMotor>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SidecarModel {
    pub name: String,
    pub urdf: String,
    pub base_link: String,
    pub slot_count: usize,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointDefaults {
    pub armature: f64,
    pub damping: f64,
    pub frictionloss: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SidecarStanding {
    pub base_pos: [f64; 3],
    pub base_quat: [f64; 4],
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SidecarContact {
    pub friction: f64,
    pub torsional_friction: f64,
    pub rolling_friction: f64,
    pub restitution: f64,
    pub self_collision: bool,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SidecarImu {
    pub link: String,
    pub pos: [f64; 3],
    pub quat: [f64; 4],
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SidecarMotor {
    pub slot: usize,
    pub name: String,
    pub joint: String,
    pub torque_limit: f64,
    pub speed_limit: f64,
    pub kp: f64,
    pub kd: f64,
    pub default_q: f64,
    pub armature: Option<f64>,
    pub damping: Option<f64>,
    pub frictionloss: Option<f64>,
}

fn finite(x: f64) -> bool {
    x.is_finite()
}

fn pose(o: &urdf_rs::Pose) -> Isometry3<f64> {
    let r = UnitQuaternion::from_euler_angles(o.rpy[0], o.rpy[1], o.rpy[2]);
    Isometry3::from_parts(Translation3::new(o.xyz[0], o.xyz[1], o.xyz[2]), r)
}

fn inertial(link: &urdf_rs::Link) -> Result<Inertial, ModelError> {
    let bad = |reason: String| ModelError::BadInertial { link: link.name.clone(), reason };
    let i = &link.inertial;
    let m = i.mass.value;
    if !finite(m) || m <= 0.0 {
        return Err(bad(format!("mass {m} must be positive")));
    }
    let t = &i.inertia;
    let local = Matrix3::new(t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz);
    if local.iter().any(|x| !x.is_finite()) {
        return Err(bad("inertia has non-finite entries".into()));
    }
    // The inertial frame may be rotated: express the tensor in the link frame, I = R I' R^T.
    let o = pose(&i.origin);
    let r = o.rotation.to_rotation_matrix();
    let inertia = r.matrix() * local * r.matrix().transpose();
    let eig = inertia.symmetric_eigenvalues();
    let (a, b, c) = (eig[0], eig[1], eig[2]);
    if a <= 0.0 || b <= 0.0 || c <= 0.0 {
        return Err(bad(format!("inertia not positive definite (eigenvalues {a}, {b}, {c})")));
    }
    // Triangle inequality of principal moments (physical realizability), with relative slack for rounding.
    let tol = 1e-9 * (a + b + c);
    if a + b + tol < c || a + c + tol < b || b + c + tol < a {
        return Err(bad(format!("principal moments {a}, {b}, {c} violate the triangle inequality")));
    }
    Ok(Inertial { mass: m, com: o.translation.vector, inertia })
}

fn collisions(link: &urdf_rs::Link) -> Result<Vec<Collision>, ModelError> {
    let mut out = Vec::new();
    for c in &link.collision {
        let bad = |what: &str| ModelError::BadInertial {
            link: link.name.clone(),
            reason: format!("collision {what} must be positive and finite"),
        };
        let pos = |x: f64| x.is_finite() && x > 0.0;
        let shape = match &c.geometry {
            urdf_rs::Geometry::Box { size } => {
                if !size.iter().all(|&s| pos(s)) {
                    return Err(bad("box size"));
                }
                Shape::Box { half_extents: [size[0] / 2.0, size[1] / 2.0, size[2] / 2.0] }
            }
            urdf_rs::Geometry::Sphere { radius } => {
                if !pos(*radius) {
                    return Err(bad("sphere radius"));
                }
                Shape::Sphere { radius: *radius }
            }
            urdf_rs::Geometry::Capsule { radius, length } => {
                if !pos(*radius) || !pos(*length) {
                    return Err(bad("capsule size"));
                }
                Shape::Capsule { radius: *radius, half_length: length / 2.0 }
            }
            urdf_rs::Geometry::Cylinder { radius, length } => {
                if !pos(*radius) || !pos(*length) {
                    return Err(bad("cylinder size"));
                }
                Shape::Cylinder { radius: *radius, half_length: length / 2.0 }
            }
            urdf_rs::Geometry::Mesh { .. } => {
                return Err(ModelError::UnsupportedGeometry { link: link.name.clone(), kind: "mesh".into() })
            }
        };
        out.push(Collision { origin: pose(&c.origin), shape });
    }
    Ok(out)
}

fn unit_quat(q: [f64; 4], what: &str) -> Result<(), ModelError> {
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !n.is_finite() || (n - 1.0).abs() > 1e-6 {
        return Err(ModelError::Invalid(format!("{what}: quaternion {q:?} is not unit length")));
    }
    Ok(())
}

impl RobotModel {
    /// The built-in Unitree H1-2 without hands (`robots/h1_2/`).
    pub fn h1_2() -> Result<Self, ModelError> {
        Self::from_strs(H1_2_URDF, H1_2_TOML)
    }

    /// The embedded files of the built-in H1-2: (URDF, TOML).
    pub fn h1_2_sources() -> (&'static str, &'static str) {
        (H1_2_URDF, H1_2_TOML)
    }

    /// Loads a sidecar TOML and the URDF it names (relative to the TOML's directory).
    pub fn load(toml_path: &Path) -> Result<Self, ModelError> {
        let io = |p: &Path| {
            let path = p.display().to_string();
            move |source| ModelError::Io { path, source }
        };
        let toml_text = std::fs::read_to_string(toml_path).map_err(io(toml_path))?;
        let side: SidecarFile = toml::from_str(&toml_text)?;
        let urdf_path = toml_path.parent().unwrap_or(Path::new(".")).join(&side.model.urdf);
        let urdf_text = std::fs::read_to_string(&urdf_path).map_err(io(&urdf_path))?;
        Self::from_parts(&urdf_text, side)
    }

    /// Builds a model from URDF text and sidecar TOML text.
    pub fn from_strs(urdf: &str, sidecar_toml: &str) -> Result<Self, ModelError> {
        let side: SidecarFile = toml::from_str(sidecar_toml)?;
        Self::from_parts(urdf, side)
    }

    fn from_parts(urdf: &str, side: SidecarFile) -> Result<Self, ModelError> {
        let robot = urdf_rs::read_from_string(urdf).map_err(ModelError::Urdf)?;
        let by_name: HashMap<&str, &urdf_rs::Link> = robot.links.iter().map(|l| (l.name.as_str(), l)).collect();
        if by_name.len() != robot.links.len() {
            return Err(ModelError::Invalid("duplicate link names in the URDF".into()));
        }
        // Joints: revolute only, known links, one parent per link.
        let mut parent_of: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
        for j in &robot.joints {
            match j.joint_type {
                urdf_rs::JointType::Revolute => {}
                ref other => {
                    return Err(ModelError::UnsupportedJoint { joint: j.name.clone(), kind: format!("{other:?}") })
                }
            }
            for l in [&j.parent.link, &j.child.link] {
                if !by_name.contains_key(l.as_str()) {
                    return Err(ModelError::UnknownLink { joint: j.name.clone(), link: l.clone() });
                }
            }
            if parent_of.insert(j.child.link.as_str(), j).is_some() {
                return Err(ModelError::MultipleParents(j.child.link.clone()));
            }
        }
        let roots: Vec<String> =
            robot.links.iter().filter(|l| !parent_of.contains_key(l.name.as_str())).map(|l| l.name.clone()).collect();
        if roots.len() != 1 {
            return Err(ModelError::Roots(roots));
        }
        let root = roots[0].clone();
        if root != side.model.base_link {
            return Err(ModelError::BaseMismatch { sidecar: side.model.base_link.clone(), urdf: root });
        }

        // Motor map: slot -> joint, each URDF joint exactly once.
        let mut motors = side.motor.clone();
        motors.sort_by_key(|m| m.slot);
        for w in motors.windows(2) {
            if w[0].slot == w[1].slot {
                return Err(ModelError::BadMotor { slot: w[0].slot, reason: "slot used twice".into() });
            }
        }
        let urdf_joint: HashMap<&str, &urdf_rs::Joint> = robot.joints.iter().map(|j| (j.name.as_str(), j)).collect();
        let mut seen = std::collections::HashSet::new();
        for m in &motors {
            if m.slot >= side.model.slot_count {
                return Err(ModelError::BadMotor {
                    slot: m.slot,
                    reason: format!("beyond slot_count {}", side.model.slot_count),
                });
            }
            if !urdf_joint.contains_key(m.joint.as_str()) {
                return Err(ModelError::MotorJointMissing { slot: m.slot, joint: m.joint.clone() });
            }
            if !seen.insert(m.joint.as_str()) {
                return Err(ModelError::BadMotor { slot: m.slot, reason: format!("joint {:?} mapped twice", m.joint) });
            }
        }
        if let Some(j) = robot.joints.iter().find(|j| !seen.contains(j.name.as_str())) {
            return Err(ModelError::UnactuatedJoint(j.name.clone()));
        }

        // Links: depth-first from the root, children in slot order, so parents precede children.
        let joint_pos: HashMap<&str, usize> = motors.iter().enumerate().map(|(i, m)| (m.joint.as_str(), i)).collect();
        let mut order: Vec<&str> = Vec::new();
        let mut stack = vec![root.as_str()];
        while let Some(l) = stack.pop() {
            if order.len() > robot.links.len() {
                return Err(ModelError::Unreachable(l.to_string()));
            }
            order.push(l);
            let mut kids: Vec<&urdf_rs::Joint> = robot.joints.iter().filter(|j| j.parent.link == l).collect();
            kids.sort_by_key(|j| joint_pos.get(j.name.as_str()).copied().unwrap_or(usize::MAX));
            for k in kids.iter().rev() {
                stack.push(k.child.link.as_str());
            }
        }
        if order.len() != robot.links.len() {
            let missing = robot.links.iter().find(|l| !order.contains(&l.name.as_str()));
            return Err(ModelError::Unreachable(missing.map(|l| l.name.clone()).unwrap_or_default()));
        }
        let link_idx: HashMap<&str, usize> = order.iter().enumerate().map(|(i, &n)| (n, i)).collect();

        let mut joints = Vec::with_capacity(motors.len());
        for m in &motors {
            let j = urdf_joint[m.joint.as_str()];
            let bad = |reason: String| ModelError::BadJoint { joint: j.name.clone(), reason };
            let a = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
            let n = a.norm();
            if !n.is_finite() || (n - 1.0).abs() > 1e-6 {
                return Err(bad(format!("axis {a:?} is not unit length")));
            }
            let (lo, hi) = (j.limit.lower, j.limit.upper);
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(bad(format!("limits [{lo}, {hi}] are not an interval")));
            }
            if !(m.default_q >= lo && m.default_q <= hi) {
                return Err(bad(format!("default_q {} outside [{lo}, {hi}]", m.default_q)));
            }
            if (j.limit.effort - m.torque_limit).abs() > 1e-9 {
                return Err(bad(format!(
                    "URDF effort {} differs from sidecar torque_limit {}",
                    j.limit.effort, m.torque_limit
                )));
            }
            if (j.limit.velocity - m.speed_limit).abs() > 1e-9 {
                return Err(bad(format!(
                    "URDF velocity {} differs from sidecar speed_limit {}",
                    j.limit.velocity, m.speed_limit
                )));
            }
            let arm = m.armature.unwrap_or(side.joint_defaults.armature);
            let damp = m.damping.unwrap_or(side.joint_defaults.damping);
            let fl = m.frictionloss.unwrap_or(side.joint_defaults.frictionloss);
            for (what, v) in [
                ("torque_limit", m.torque_limit),
                ("speed_limit", m.speed_limit),
                ("kp", m.kp),
                ("kd", m.kd),
                ("armature", arm),
                ("damping", damp),
                ("frictionloss", fl),
            ] {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(ModelError::BadMotor {
                        slot: m.slot,
                        reason: format!("{what} = {v} must be finite and >= 0"),
                    });
                }
            }
            joints.push(Joint {
                name: j.name.clone(),
                motor_name: m.name.clone(),
                slot: m.slot,
                parent_link: link_idx[j.parent.link.as_str()],
                child_link: link_idx[j.child.link.as_str()],
                origin: pose(&j.origin),
                axis: Unit::new_normalize(a),
                lower: lo,
                upper: hi,
                torque_limit: m.torque_limit,
                speed_limit: m.speed_limit,
                armature: arm,
                damping: damp,
                frictionloss: fl,
                kp: m.kp,
                kd: m.kd,
                default_q: m.default_q,
            });
        }
        let mut links = Vec::with_capacity(order.len());
        for &name in &order {
            let l = by_name[name];
            let pj = joints.iter().position(|j| links_child(j, &link_idx, name));
            links.push(Link {
                name: name.to_string(),
                parent_joint: pj,
                parent_link: pj.map(|j| joints[j].parent_link),
                inertial: inertial(l)?,
                collisions: collisions(l)?,
            });
        }

        unit_quat(side.standing.base_quat, "standing.base_quat")?;
        unit_quat(side.imu.quat, "imu.quat")?;
        let imu_link = *link_idx
            .get(side.imu.link.as_str())
            .ok_or_else(|| ModelError::Invalid(format!("imu.link {:?} is not a link", side.imu.link)))?;
        let c = &side.contact;
        for (what, v) in [
            ("friction", c.friction),
            ("torsional_friction", c.torsional_friction),
            ("rolling_friction", c.rolling_friction),
            ("restitution", c.restitution),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ModelError::Invalid(format!("contact.{what} = {v} must be finite and >= 0")));
            }
        }
        let standing_q = joints.iter().map(|j| j.default_q).collect();
        Ok(RobotModel {
            name: side.model.name.clone(),
            links,
            joints,
            slot_count: side.model.slot_count,
            standing: StandingPose {
                base_pos: side.standing.base_pos,
                base_quat: side.standing.base_quat,
                q: standing_q,
            },
            contact: ContactParams {
                friction: c.friction,
                torsional_friction: c.torsional_friction,
                rolling_friction: c.rolling_friction,
                restitution: c.restitution,
                self_collision: c.self_collision,
            },
            imu: ImuSite { link: imu_link, link_name: side.imu.link.clone(), pos: side.imu.pos, quat: side.imu.quat },
        })
    }
}

fn links_child(j: &Joint, link_idx: &HashMap<&str, usize>, name: &str) -> bool {
    link_idx.get(name) == Some(&j.child_link)
}
