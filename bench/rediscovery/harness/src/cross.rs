//! The cross-engine half of the rediscovery benchmark: scenes for known bugs of MuJoCo, Bullet and DART, run
//! on old versions through each engine's own Python bindings (`../adapters/python`, one venv per wheel
//! version), and judged here by the project's invariants (`physics-invariants`, the same code `engine-diff`
//! applies to robot rollouts).
//!
//! Protocol: the `scenes` binary writes [`scenes`] as JSON; an adapter reads it and prints one
//! [`Observation`] line per scene (raw observables, no verdict); the `judge` binary turns observations into
//! [`Verdict`]s with [`judge`]. Thresholds are the invariants' (fixed before any version was run) and the
//! same for every engine and version; which version runs is unknown to the judge.
use crate::Verdict;
use physics_invariants as inv;
use serde::{Deserialize, Serialize};

/// A collision primitive of a compound rigid body, at a position in the body frame (no local rotation).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Geom {
    Box { pos: [f64; 3], half: [f64; 3] },
    Sphere { pos: [f64; 3], radius: f64 },
}

/// A fixed support whose top face is the plane z = 0.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Support {
    Plane,
    /// A box of these half-extents centred at (0, 0, −half[2]).
    Box {
        half: [f64; 3],
    },
}

/// One free rigid body made of primitives, with an explicit mass and the inertia of a solid box of
/// half-extents `inertia_half` (so no engine estimates inertia from shapes).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Compound {
    pub geoms: Vec<Geom>,
    /// Geoms after the first sit on a child body attached without a joint (what URDF fixed joints become),
    /// so that an engine's static-body fusion (`fusestatic`) has to merge them into the free body.
    pub fused_child: bool,
    pub mass: f64,
    pub inertia_half: [f64; 3],
}

/// Initial state of the free body.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Init {
    pub pos: [f64; 3],
    /// `[w, x, y, z]`.
    pub quat: [f64; 4],
    pub linvel: [f64; 3],
}

/// The scene kinds. Every scene names the physical expectation its oracle checks.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SceneKind {
    /// A body released on (or in) a support must end resting on it: penetration invariant over the last
    /// `settle` seconds, computed from the body's reported pose and the known geometry (not from the
    /// engine's contact report, which is what some bugs get wrong).
    Drop {
        support: Support,
        body: Compound,
        init: Init,
        dt: f64,
        duration: f64,
        gravity: f64,
        /// Soft-contact time constant for engines that have one (MuJoCo `solref`); `None`: engine default.
        contact_timeconst: Option<f64>,
        settle: f64,
    },
    /// Inverse dynamics of a floating robot held at rest in configuration `q`: joint torques against the
    /// reference engine's on the same URDF, relative error within the analytic dynamics tolerance.
    InverseDynamics { urdf: String, base_pos: [f64; 3], base_quat: [f64; 4], q: Vec<f64> },
    /// A passive chain released from rest (no actuation, no damping, no contact) for `duration`: the state must
    /// stay finite and mechanical energy must not grow beyond the passivity tolerance (zero actuator work).
    PassiveChain {
        /// Link masses (kg) and lengths (m): rods along the chain, revolute joints about y.
        masses: Vec<f64>,
        lengths: Vec<f64>,
        /// Joint limits `(lower, upper)` per joint (rad), enforced; `None`: unlimited.
        limits: Vec<Option<(f64, f64)>>,
        q0: Vec<f64>,
        dt: f64,
        duration: f64,
        gravity: f64,
    },
}

/// A scene of the cross-engine set.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Scene {
    pub id: String,
    /// Engines (label prefixes, lower case) that run the scene; empty: every engine that has the kind.
    pub engines: Vec<String>,
    #[serde(flatten)]
    pub kind: SceneKind,
}

/// What an adapter printed for one scene.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Observation {
    pub engine: String,
    pub scene: String,
    /// `ok`, `unsupported` or `error` (`crashed` is written by the runner when the process died).
    pub status: String,
    #[serde(default)]
    pub detail: String,
    #[serde(default)]
    pub data: Option<serde_json::Value>,
}

/// A known bug of the cross-engine set: the scene that should expose it and the version pair.
#[derive(Debug, Clone, Copy)]
pub struct CrossBug {
    pub id: &'static str,
    /// Engine label prefix of both versions, e.g. "MuJoCo".
    pub engine: &'static str,
    pub scene: &'static str,
    pub url: &'static str,
    pub last_bad: &'static str,
    pub first_good: &'static str,
    pub note: &'static str,
}

pub const CROSS_BUGS: [CrossBug; 7] = [
    CrossBug {
        id: "MuJoCo box-box deep",
        engine: "MuJoCo",
        scene: "embedded_box",
        url: "https://github.com/google-deepmind/mujoco/commit/f2a967348c64197b9a29fb9e1c7dd9879984e10b",
        last_bad: "3.1.0",
        first_good: "3.1.1",
        note: "changelog 3.1.1: box-box collisions produced no contacts if one box was deeply embedded (introduced in 3.1.0)",
    },
    CrossBug {
        id: "MuJoCo #1069/#1577",
        engine: "MuJoCo",
        scene: "fused_foot",
        url: "https://github.com/google-deepmind/mujoco/issues/1069",
        last_bad: "3.1.5",
        first_good: "3.1.6",
        note: "changelog 3.1.6: collisions missed with fusestatic (URDF imports); commit 96844db9 recomputes the BVH",
    },
    CrossBug {
        id: "MuJoCo #2206",
        engine: "MuJoCo",
        scene: "small_sphere_soft_contact",
        url: "https://github.com/google-deepmind/mujoco/issues/2206",
        last_bad: "3.2.6",
        first_good: "3.2.7",
        note: "changelog 3.2.7: box-sphere depth incorrect for deep penetrations (commit 0e7d2ef6)",
    },
    CrossBug {
        id: "MuJoCo #1800",
        engine: "MuJoCo",
        scene: "thin_plate_drop",
        url: "https://github.com/google-deepmind/mujoco/issues/1800",
        last_bad: "3.11.0",
        first_good: "3.12.0",
        note: "changelog 3.12.0: box-box penetrations deeper than a box's smallest half-size produced no contacts (commit fb07a9ca)",
    },
    CrossBug {
        id: "Bullet PR #4585",
        engine: "pybullet",
        scene: "floating_inverse_dynamics",
        url: "https://github.com/bulletphysics/bullet3/pull/4585",
        last_bad: "3.2.6",
        first_good: "3.2.7",
        note: "PR #4585 (merged 2024-04-09, after 3.2.6): calculateInverseDynamics skipped one joint slot of floating bodies",
    },
    CrossBug {
        id: "DART gz-physics#846",
        engine: "dartpy",
        scene: "inverted_joint_limits",
        url: "https://github.com/dartsim/dart/releases/tag/v6.16.5",
        last_bad: "6.16.4",
        first_good: "6.16.5",
        note: "release notes 6.16.5: invalid joint limits (lower > upper) no longer enforced (gz-physics#846)",
    },
    CrossBug {
        id: "DART gz-physics#849",
        engine: "dartpy",
        scene: "massless_link_chain",
        url: "https://github.com/dartsim/dart/releases/tag/v6.16.6",
        last_bad: "6.16.5",
        first_good: "6.16.6",
        note: "release notes 6.16.6: guard against non-finite articulated-body results from zero/epsilon mass",
    },
];

/// The label of the engine whose inverse dynamics is the reference for [`SceneKind::InverseDynamics`].
pub const REFERENCE_ENGINE: &str = "MuJoCo 3.17.0";

const IDENTITY: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

/// A floating base (box) with a chain of four revolute links: the smallest robot whose joint vector can be
/// shifted by one slot without the lengths changing.
fn floating_chain_urdf() -> String {
    let link = |name: &str, m: f64, l: f64| {
        format!(
            r#"<link name="{name}"><inertial><origin xyz="{c} 0 0"/><mass value="{m}"/><inertia ixx="0.001" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/></inertial></link>"#,
            c = l / 2.0,
            i = m * l * l / 12.0 + 0.001
        )
    };
    let mut s = String::from(
        r#"<robot name="floating_chain"><link name="base"><inertial><origin xyz="0 0 0"/><mass value="5"/><inertia ixx="0.05" iyy="0.05" izz="0.05" ixy="0" ixz="0" iyz="0"/></inertial></link>"#,
    );
    let axes = ["0 1 0", "1 0 0", "0 1 0", "0 0 1"];
    let masses = [2.0, 1.5, 1.0, 0.5];
    let mut parent = "base".to_string();
    for (i, (axis, m)) in axes.iter().zip(masses).enumerate() {
        let name = format!("l{i}");
        let x = if i == 0 { 0.1 } else { 0.3 };
        s.push_str(&link(&name, m, 0.3));
        s.push_str(&format!(
            r#"<joint name="j{i}" type="revolute"><parent link="{parent}"/><child link="{name}"/><origin xyz="{x} 0 0"/><axis xyz="{axis}"/><limit lower="-3" upper="3" effort="100" velocity="10"/></joint>"#
        ));
        parent = name;
    }
    s.push_str("</robot>");
    s
}

/// Every scene of the cross-engine set. Parameters come from each bug's report or fixing commit; the
/// judge's thresholds are the invariants', not tuned per scene.
pub fn scenes() -> Vec<Scene> {
    let cube = |h: f64| Compound {
        geoms: vec![Geom::Box { pos: [0.0; 3], half: [h; 3] }],
        fused_child: false,
        mass: 1.0,
        inertia_half: [h; 3],
    };
    vec![
        // A 10 cm cube completely inside a thick fixed box (the 3.1.1 fix: "one box completely inside
        // another"): the contact pushes it out and it ends resting on top.
        Scene {
            id: "embedded_box".into(),
            engines: vec![],
            kind: SceneKind::Drop {
                support: Support::Box { half: [1.0, 1.0, 0.5] },
                body: cube(0.05),
                init: Init { pos: [0.0, 0.0, -0.2], quat: IDENTITY, linvel: [0.0; 3] },
                dt: 0.002,
                // Long enough for the engines that eject the box high (MuJoCo ≥ 3.11: ~1 m, Bullet: ~4 m) to
                // land and settle; a first version judged at 1 s caught MuJoCo 3.17 in flight.
                duration: 3.0,
                gravity: -inv::GRAVITY_EARTH,
                contact_timeconst: None,
                settle: 0.2,
            },
        },
        // A leg (box) with a foot (a tripod of spheres) attached without a joint, as a URDF fixed joint imports: the
        // foot must hold the body up.
        Scene {
            id: "fused_foot".into(),
            engines: vec![],
            kind: SceneKind::Drop {
                support: Support::Plane,
                body: Compound {
                    geoms: vec![
                        Geom::Box { pos: [0.0; 3], half: [0.05, 0.05, 0.2] },
                        Geom::Sphere { pos: [0.15, 0.1, -0.3], radius: 0.1 },
                        Geom::Sphere { pos: [-0.15, 0.1, -0.3], radius: 0.1 },
                        Geom::Sphere { pos: [0.0, -0.15, -0.3], radius: 0.1 },
                    ],
                    fused_child: true,
                    mass: 2.0,
                    inertia_half: [0.2, 0.1, 0.25],
                },
                init: Init { pos: [0.0, 0.0, 0.5], quat: IDENTITY, linvel: [0.0; 3] },
                dt: 0.002,
                duration: 2.0,
                gravity: -inv::GRAVITY_EARTH,
                contact_timeconst: None,
                settle: 0.2,
            },
        },
        // A 5 mm sphere resting on a box with soft contacts (time constant 0.15 s): the soft contact's
        // equilibrium depth (~g·τ²/2 ≈ 1 cm) exceeds the radius, so the sphere's centre is inside the box
        // (#2206's regime); the contact must still hold it within the penetration bound.
        Scene {
            id: "small_sphere_soft_contact".into(),
            engines: vec!["mujoco".into()],
            kind: SceneKind::Drop {
                support: Support::Box { half: [0.5, 0.5, 0.5] },
                body: Compound {
                    geoms: vec![Geom::Sphere { pos: [0.0; 3], radius: 0.005 }],
                    fused_child: false,
                    mass: 0.1,
                    inertia_half: [0.004; 3],
                },
                init: Init { pos: [0.0, 0.0, 0.005], quat: IDENTITY, linvel: [0.0; 3] },
                dt: 0.002,
                duration: 3.0,
                gravity: -inv::GRAVITY_EARTH,
                contact_timeconst: Some(0.15),
                settle: 0.2,
            },
        },
        // A box dropped on a 1 cm thick plate: at impact it moves ~9 mm per step, more than the plate's
        // half-thickness (#1800's regime); it must come to rest on the plate.
        Scene {
            id: "thin_plate_drop".into(),
            engines: vec![],
            kind: SceneKind::Drop {
                support: Support::Box { half: [1.0, 1.0, 0.005] },
                body: cube(0.05),
                init: Init { pos: [0.0, 0.0, 0.05 + 1.0], quat: IDENTITY, linvel: [0.0; 3] },
                dt: 0.002,
                duration: 1.5,
                gravity: -inv::GRAVITY_EARTH,
                contact_timeconst: None,
                settle: 0.2,
            },
        },
        Scene {
            id: "floating_inverse_dynamics".into(),
            // The reference's own version and the engine whose inverse dynamics is under test.
            engines: vec!["mujoco 3.17".into(), "pybullet".into()],
            kind: SceneKind::InverseDynamics {
                urdf: floating_chain_urdf(),
                base_pos: [0.0, 0.0, 1.0],
                base_quat: IDENTITY,
                q: vec![0.4, -0.7, 1.1, 0.3],
            },
        },
        // A two-link pendulum whose first joint's limits are inverted (lower > upper), released from rest.
        Scene {
            id: "inverted_joint_limits".into(),
            engines: vec![],
            kind: SceneKind::PassiveChain {
                masses: vec![1.0, 1.0],
                lengths: vec![0.5, 0.5],
                limits: vec![Some((0.5, -0.5)), None],
                q0: vec![0.2, 0.0],
                dt: 0.001,
                duration: 2.0,
                gravity: -inv::GRAVITY_EARTH,
            },
        },
        // A three-link pendulum whose last link is massless (a frame, as URDF exports often carry).
        Scene {
            id: "massless_link_chain".into(),
            engines: vec![],
            kind: SceneKind::PassiveChain {
                masses: vec![1.0, 1.0, 0.0],
                lengths: vec![0.5, 0.5, 0.1],
                limits: vec![None, None, None],
                q0: vec![0.5, 0.3, 0.2],
                dt: 0.001,
                duration: 2.0,
                gravity: -inv::GRAVITY_EARTH,
            },
        },
    ]
}

fn quat_rotate(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let [w, x, y, z] = q;
    // v + 2w(u×v) + 2u×(u×v), u = (x, y, z)
    let u = [x, y, z];
    let cross =
        |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let t = cross(u, v);
    let t2 = cross(u, t);
    [v[0] + 2.0 * (w * t[0] + t2[0]), v[1] + 2.0 * (w * t[1] + t2[1]), v[2] + 2.0 * (w * t[2] + t2[2])]
}

/// Lowest world z of a compound body at pose (`pos`, `quat`).
pub fn compound_lowest_z(body: &Compound, pos: [f64; 3], quat: [f64; 4]) -> f64 {
    body.geoms
        .iter()
        .map(|g| match g {
            Geom::Box { pos: p, half } => {
                let c = quat_rotate(quat, *p);
                inv::box_lowest_z([pos[0] + c[0], pos[1] + c[1], pos[2] + c[2]], quat, *half)
            }
            Geom::Sphere { pos: p, radius } => pos[2] + quat_rotate(quat, *p)[2] - radius,
        })
        .fold(f64::INFINITY, f64::min)
}

#[derive(Debug, Deserialize)]
struct DropData {
    t: Vec<f64>,
    pos: Vec<Vec<Option<f64>>>,
    quat: Vec<Vec<Option<f64>>>,
}

#[derive(Debug, Deserialize)]
struct TauData {
    tau: Vec<Option<f64>>,
}

#[derive(Debug, Deserialize)]
struct ChainData {
    t: Vec<f64>,
    /// Mechanical energy (kinetic + potential, the engine's own) per sample.
    energy: Vec<Option<f64>>,
}

fn arr<const N: usize>(v: &[Option<f64>]) -> Option<[f64; N]> {
    if v.len() != N {
        return None;
    }
    let mut a = [0.0; N];
    for (x, y) in a.iter_mut().zip(v) {
        *x = (*y)?;
    }
    a.iter().all(|x| x.is_finite()).then_some(a)
}

/// Judges one observation. `reference` is the reference engine's observation of the same scene (needed by
/// inverse-dynamics scenes only). `None` when the scene is not in [`scenes`].
pub fn judge(obs: &Observation, reference: Option<&Observation>) -> Option<Verdict> {
    let scene = scenes().into_iter().find(|s| s.id == obs.scene)?;
    let bug = CROSS_BUGS.iter().find(|b| b.scene == obs.scene).map_or("-", |b| b.id);
    let (metric, threshold) = match &scene.kind {
        SceneKind::Drop { settle, .. } => (
            format!("max penetration into the support over the last {settle} s (m), from poses"),
            format!("<= {} ({})", inv::PENETRATION_MAX, inv::names::PENETRATION),
        ),
        SceneKind::InverseDynamics { .. } => (
            format!("joint torques, rel. error vs {REFERENCE_ENGINE}"),
            format!("<= {:e} ({})", inv::DYNAMICS_REL_TOL, inv::names::INVERSE_DYNAMICS),
        ),
        SceneKind::PassiveChain { .. } => (
            "energy gain with zero actuator work (J)".to_string(),
            format!("<= {} ({}; finite state)", inv::energy_tolerance(0.0), inv::names::ENERGY),
        ),
    };
    let mut v = Verdict {
        engine: obs.engine.clone(),
        bug: bug.to_string(),
        scene: obs.scene.clone(),
        metric,
        value: None,
        threshold,
        flagged: false,
        detail: String::new(),
        runtime_ms: 0.0,
    };
    match obs.status.as_str() {
        "unsupported" => {
            v.detail = format!("not run: {}", obs.detail);
            return Some(v);
        }
        "ok" => {}
        _ => {
            v.flagged = true;
            v.detail = format!("engine failure ({}): {}", obs.status, obs.detail);
            return Some(v);
        }
    }
    let Some(data) = obs.data.clone() else {
        v.flagged = true;
        v.detail = "no observables".into();
        return Some(v);
    };
    match &scene.kind {
        SceneKind::Drop { body, settle, duration, dt, .. } => {
            let Ok(d) = serde_json::from_value::<DropData>(data) else {
                v.flagged = true;
                v.detail = "malformed observables".into();
                return Some(v);
            };
            let expected = (duration / dt).round() as usize + 1;
            let mut worst = f64::NEG_INFINITY;
            let mut finite = d.t.len() == expected && d.pos.len() == expected && d.quat.len() == expected;
            for ((t, p), q) in d.t.iter().zip(&d.pos).zip(&d.quat) {
                match (arr::<3>(p), arr::<4>(q)) {
                    (Some(p), Some(q)) => {
                        if *t >= duration - settle - 1e-9 {
                            worst = worst.max(inv::penetration_below(0.0, compound_lowest_z(body, p, q)));
                        }
                    }
                    _ => finite = false,
                }
            }
            let last_z = d.pos.last().and_then(|p| arr::<3>(p)).map_or(f64::NAN, |p| p[2]);
            if !finite {
                v.flagged = true;
                v.detail = format!("{}: the run stopped or went non-finite", inv::names::NON_FINITE);
            } else {
                v.value = Some(worst);
                v.flagged = inv::exceeds(worst, inv::PENETRATION_MAX);
                v.detail = format!("final body height {last_z:.4} m");
            }
        }
        SceneKind::InverseDynamics { .. } => {
            let tau = serde_json::from_value::<TauData>(data).ok().map(|d| d.tau);
            let reference = reference
                .filter(|r| r.status == "ok")
                .and_then(|r| r.data.clone())
                .and_then(|d| serde_json::from_value::<TauData>(d).ok())
                .map(|d| d.tau);
            match (tau, reference) {
                (Some(t), Some(r)) => {
                    let t: Vec<f64> = t.iter().map(|x| x.unwrap_or(f64::NAN)).collect();
                    let r: Vec<f64> = r.iter().map(|x| x.unwrap_or(f64::NAN)).collect();
                    let e = inv::relative_error(&t, &r);
                    v.value = Some(e);
                    v.flagged = inv::exceeds(e, inv::DYNAMICS_REL_TOL);
                    let f = |x: &[f64]| x.iter().map(|y| format!("{y:.4}")).collect::<Vec<_>>().join(", ");
                    v.detail = format!("tau [{}] vs reference [{}] N·m", f(&t), f(&r));
                }
                (None, _) => {
                    v.flagged = true;
                    v.detail = "malformed observables".into();
                }
                (_, None) => v.detail = format!("not judged: no {REFERENCE_ENGINE} observation"),
            }
        }
        SceneKind::PassiveChain { .. } => {
            let Ok(d) = serde_json::from_value::<ChainData>(data) else {
                v.flagged = true;
                v.detail = "malformed observables".into();
                return Some(v);
            };
            let e: Vec<f64> = d.energy.iter().map(|x| x.unwrap_or(f64::NAN)).collect();
            let e0 = e.first().copied().unwrap_or(f64::NAN);
            let finite = e.iter().all(|x| x.is_finite()) && !e.is_empty();
            let gain = e.iter().map(|x| x - e0).fold(f64::NEG_INFINITY, f64::max);
            if !finite {
                v.flagged = true;
                let at = d.t.iter().zip(&e).find(|(_, x)| !x.is_finite()).map_or(f64::NAN, |(t, _)| *t);
                v.detail = format!("{} from t = {at:.3} s", inv::names::NON_FINITE);
            } else {
                v.value = Some(gain);
                v.flagged = inv::exceeds(gain, inv::energy_tolerance(0.0));
                v.detail = format!("initial energy {e0:.3} J, {} samples", e.len());
            }
        }
    }
    Some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_serialise_and_name_their_bugs() {
        let s = scenes();
        let text = serde_json::to_string(&s).unwrap_or_default();
        let back: Vec<Scene> = serde_json::from_str(&text).unwrap_or_default();
        assert_eq!(back, s);
        for b in CROSS_BUGS {
            assert!(s.iter().any(|x| x.id == b.scene), "{}", b.scene);
        }
    }

    #[test]
    fn lowest_point_of_the_fused_foot() {
        let Some(Scene { kind: SceneKind::Drop { body, .. }, .. }) =
            scenes().into_iter().find(|s| s.id == "fused_foot")
        else {
            panic!("scene missing")
        };
        // Upright at 0.4 m: the spheres' bottoms are at 0.4 − 0.3 − 0.1 = 0.
        assert!(compound_lowest_z(&body, [0.0, 0.0, 0.4], IDENTITY).abs() < 1e-12);
        // Turned upside down about x: the spheres are above, the box's other end is lowest: 0.4 − 0.2.
        let z = compound_lowest_z(&body, [0.0, 0.0, 0.4], [0.0, 1.0, 0.0, 0.0]);
        assert!((z - 0.2).abs() < 1e-12, "{z}");
    }

    fn obs(data: serde_json::Value) -> Observation {
        Observation {
            engine: "X 1".into(),
            scene: "embedded_box".into(),
            status: "ok".into(),
            detail: String::new(),
            data: Some(data),
        }
    }

    #[test]
    fn a_box_resting_on_top_is_quiet_and_one_that_fell_through_is_flagged() {
        // embedded_box runs 3 s at 2 ms: 1501 samples.
        let n = 1501;
        let rest = serde_json::json!({"t": (0..n).map(|i| i as f64 * 0.002).collect::<Vec<_>>(),
            "pos": vec![vec![0.0, 0.0, 0.0499]; n], "quat": vec![vec![1.0, 0.0, 0.0, 0.0]; n]});
        let v = judge(&obs(rest), None).expect("known scene");
        assert!(!v.flagged, "{v:?}");
        let fell = serde_json::json!({"t": (0..n).map(|i| i as f64 * 0.002).collect::<Vec<_>>(),
            "pos": vec![vec![0.0, 0.0, -3.0]; n], "quat": vec![vec![1.0, 0.0, 0.0, 0.0]; n]});
        assert!(judge(&obs(fell), None).is_some_and(|v| v.flagged));
        // A run that stopped early (non-finite state) is flagged.
        let short = serde_json::json!({"t": [0.0], "pos": [[0.0, 0.0, 0.05]], "quat": [[1.0, 0.0, 0.0, 0.0]]});
        assert!(judge(&obs(short), None).is_some_and(|v| v.flagged));
    }
}
