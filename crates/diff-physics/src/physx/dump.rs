//! Scene dumps: what this adapter hands PhysX, as plain text, so that a program using only `physx-sys` can
//! rebuild the same scene and replay the same steps (the standalone reproducers under `corpus/`).
//!
//! # Format
//! One record per line, tokens separated by single spaces; `#` starts a comment line. Every number is the
//! **f32 value PhysX receives** (after the adapter's narrowing from f64 and quaternion renormalisation), written
//! in Rust's shortest round-trip form, so parsing it as f32 gives the same bits. Each record is a keyword
//! followed by labelled fields, always in this order:
//!
//! ```text
//! dt <s>
//! scene gravity <x> <y> <z> solver tgs|pgs iterations <position> <velocity> bounce_threshold_velocity <v>
//!       friction_offset_threshold <d> friction_correlation_distance <d> stabilization 0|1 enhanced_determinism 0|1
//! material static <mu_s> dynamic <mu_d> restitution <e>              (friction/restitution combine mode: average)
//! ground 0|1                                                 (1: static plane z = 0 with the shapes' offsets)
//! shapes contact_offset <m> rest_offset <m>                   (every shape, ground included)
//! articulation self_collision 0|1 max_linear_velocity <v> max_angular_velocity <w>
//!       max_depenetration_velocity <v>                        (the three velocities are set on every link)
//! link <i> parent <j>|- pose <pose> mass <kg> cmass <pose> inertia <ix> <iy> <iz>
//! shape <i> box <hx> <hy> <hz> local <pose>
//! shape <i> sphere <r> local <pose>
//! shape <i> capsule <r> <half_height> local <pose>            (PhysX capsule: axis along the shape's x)
//! joint <i> parent_pose <pose> child_pose <pose> limits <low> <high>|free armature <a>
//!       max_joint_velocity <w> friction_drive <max_force>|none
//! state root <pose> lin_vel <x> <y> <z> ang_vel <x> <y> <z>
//! q <q_1> ... <q_n>
//! qd <qd_1> ... <qd_n>
//! force <step> <f_1> ... <f_n>
//! ```
//! (each record on one line; shown wrapped here). `<pose>` is 7 numbers: position `x y z`, then the unit
//! quaternion in PhysX's order `x y z w`. Links are listed parents first and numbered from 0 (the root); each
//! `shape` and `joint` record belongs to the link `<i>` before it. Joints are revolute about the x axis of the
//! joint frames (PhysX eTWIST), joint frames in the parent and child link frames. `link.pose` is the link frame
//! at creation, `cmass` the centre-of-mass frame (principal axes) in the link frame, `inertia` the principal
//! moments. The state is the articulation state set after creation: root link frame, root centre-of-mass linear
//! velocity and angular velocity (world frame), joint positions `q` and velocities `qd`. `force` is the joint
//! force of each DoF applied for step `<step>` (0-based; PhysX keeps it until changed). Joint vectors (`q`, `qd`,
//! `force`, n = links − 1 entries) are in link order: entry `k` is the inbound joint of link `k + 1`.
use super::ffi::{f32_pose, Geometry, RawState, WorldDesc};
use std::fmt::Write;

fn nums(out: &mut String, xs: impl IntoIterator<Item = f32>) {
    for x in xs {
        let _ = write!(out, " {x:?}");
    }
}

fn narrow<const N: usize>(v: [f64; N]) -> [f32; N] {
    v.map(|x| x as f32)
}

fn flag(b: bool) -> u8 {
    u8::from(b)
}

/// The world description and the time step (see the module docs for the format).
pub fn scene(desc: &WorldDesc, dt: f64) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "dt {:?}", dt as f32);
    o.push_str("scene gravity");
    nums(&mut o, narrow(desc.gravity));
    let _ = write!(o, " solver {}", if desc.tgs { "tgs" } else { "pgs" });
    let _ = write!(o, " iterations {} {}", desc.position_iterations, desc.velocity_iterations);
    let _ = write!(o, " bounce_threshold_velocity {:?}", desc.bounce_threshold_velocity as f32);
    let _ = write!(o, " friction_offset_threshold {:?}", desc.friction_offset_threshold as f32);
    let _ = write!(o, " friction_correlation_distance {:?}", desc.friction_correlation_distance as f32);
    let _ = writeln!(
        o,
        " stabilization {} enhanced_determinism {}",
        flag(desc.stabilization),
        flag(desc.enhanced_determinism)
    );
    let _ = writeln!(
        o,
        "material static {:?} dynamic {:?} restitution {:?}",
        desc.static_friction as f32, desc.dynamic_friction as f32, desc.restitution as f32
    );
    let _ = writeln!(o, "ground {}", flag(desc.ground));
    let _ =
        writeln!(o, "shapes contact_offset {:?} rest_offset {:?}", desc.contact_offset as f32, desc.rest_offset as f32);
    let _ = writeln!(
        o,
        "articulation self_collision {} max_linear_velocity {:?} max_angular_velocity {:?} \
         max_depenetration_velocity {:?}",
        flag(desc.self_collision),
        desc.max_linear_velocity as f32,
        desc.max_angular_velocity as f32,
        desc.max_depenetration_velocity as f32
    );
    for (i, l) in desc.links.iter().enumerate() {
        let _ = write!(o, "link {i} parent ");
        match l.parent {
            Some(p) => {
                let _ = write!(o, "{p}");
            }
            None => o.push('-'),
        }
        o.push_str(" pose");
        nums(&mut o, f32_pose(&l.pose));
        let _ = write!(o, " mass {:?} cmass", l.mass as f32);
        nums(&mut o, f32_pose(&l.mass_frame));
        o.push_str(" inertia");
        nums(&mut o, narrow(l.principal_inertia));
        o.push('\n');
        for s in &l.shapes {
            let _ = write!(o, "shape {i} ");
            match s.geometry {
                Geometry::Box { half_extents } => {
                    o.push_str("box");
                    nums(&mut o, narrow(half_extents));
                }
                Geometry::Sphere { radius } => {
                    o.push_str("sphere");
                    nums(&mut o, [radius as f32]);
                }
                Geometry::Capsule { radius, half_height } => {
                    o.push_str("capsule");
                    nums(&mut o, [radius as f32, half_height as f32]);
                }
            }
            o.push_str(" local");
            nums(&mut o, f32_pose(&s.local));
            o.push('\n');
        }
        if let Some(j) = &l.joint {
            let _ = write!(o, "joint {i} parent_pose");
            nums(&mut o, f32_pose(&j.parent_pose));
            o.push_str(" child_pose");
            nums(&mut o, f32_pose(&j.child_pose));
            match j.limits {
                Some((lo, hi)) => {
                    o.push_str(" limits");
                    nums(&mut o, [lo as f32, hi as f32]);
                }
                None => o.push_str(" limits free"),
            }
            let _ = write!(o, " armature {:?} max_joint_velocity {:?}", j.armature as f32, j.max_joint_velocity as f32);
            match j.friction_drive {
                Some(f) => {
                    let _ = writeln!(o, " friction_drive {:?}", f as f32);
                }
                None => o.push_str(" friction_drive none\n"),
            }
        }
    }
    o
}

/// The articulation state handed to PhysX (`state`, `q` and `qd` records).
pub fn state(s: &RawState) -> String {
    let mut o = String::from("state root");
    nums(&mut o, f32_pose(&s.root));
    o.push_str(" lin_vel");
    nums(&mut o, narrow(s.root_lin_vel));
    o.push_str(" ang_vel");
    nums(&mut o, narrow(s.root_ang_vel));
    o.push_str("\nq");
    nums(&mut o, s.q.iter().map(|&x| x as f32));
    o.push_str("\nqd");
    nums(&mut o, s.dq.iter().map(|&x| x as f32));
    o.push('\n');
    o
}

/// The joint forces of step `step` (a `force` record).
pub fn forces(step: usize, f: &[f64]) -> String {
    let mut o = format!("force {step}");
    nums(&mut o, f.iter().map(|&x| x as f32));
    o.push('\n');
    o
}
