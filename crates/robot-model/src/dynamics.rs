//! An independent rigid-body dynamics reference: recursive Newton-Euler in world-frame Plücker coordinates,
//! mass matrix by unit-acceleration columns (O(n²) but simple and obviously right), forward dynamics by a
//! dense solve. Used by `diff-physics` as the in-house oracle that every engine is compared against.
//!
//! Coordinates are those documented at the crate root: `v = [v_base (world), ω_base (base frame), dq]`,
//! generalized forces are their dual. Joint damping and friction are NOT modelled here (they are not rigid-body
//! quantities); armature is added to the joint diagonal when asked for.
use crate::error::ModelError;
use crate::kinematics::GenCoords;
use crate::model::RobotModel;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// Standard gravity (m/s²) as used by MuJoCo's default `gravity="0 0 -9.81"`.
pub const GRAVITY_EARTH: f64 = 9.81;

/// Marker so users can name the reference in reports.
#[derive(Debug, Clone, Copy)]
pub struct RigidBodyDynamics;

impl RigidBodyDynamics {
    pub const NAME: &'static str = "robot-model RNEA/CRBA (nalgebra, f64)";
}

#[derive(Debug, Clone, Copy)]
struct Sv {
    ang: Vector3<f64>,
    lin: Vector3<f64>,
}

impl Sv {
    fn zero() -> Self {
        Sv { ang: Vector3::zeros(), lin: Vector3::zeros() }
    }
    fn add(self, o: Sv) -> Sv {
        Sv { ang: self.ang + o.ang, lin: self.lin + o.lin }
    }
    fn scale(self, s: f64) -> Sv {
        Sv { ang: self.ang * s, lin: self.lin * s }
    }
    /// Motion cross product `self ×m m`.
    fn cross_m(self, m: Sv) -> Sv {
        Sv { ang: self.ang.cross(&m.ang), lin: self.ang.cross(&m.lin) + self.lin.cross(&m.ang) }
    }
    /// Force cross product `self ×* f`.
    fn cross_f(self, f: Sv) -> Sv {
        Sv { ang: self.ang.cross(&f.ang) + self.lin.cross(&f.lin), lin: self.ang.cross(&f.lin) }
    }
    fn dot(self, f: Sv) -> f64 {
        self.ang.dot(&f.ang) + self.lin.dot(&f.lin)
    }
}

/// Per-link world-frame inertia: mass, COM, rotational inertia about the COM.
struct BodyInertia {
    m: f64,
    c: Vector3<f64>,
    ic: Matrix3<f64>,
}

impl BodyInertia {
    /// Spatial inertia times a motion vector (momentum about the world origin).
    fn apply(&self, v: Sv) -> Sv {
        let vc = v.lin + v.ang.cross(&self.c);
        let h = vc * self.m;
        Sv { ang: self.ic * v.ang + self.c.cross(&h), lin: h }
    }
}

struct Kin {
    bodies: Vec<BodyInertia>,
    /// Joint motion subspaces (world Plücker).
    s: Vec<Sv>,
    base_r: Matrix3<f64>,
    base_p: Vector3<f64>,
}

impl RobotModel {
    fn kin(&self, c: &GenCoords) -> Result<Kin, ModelError> {
        let fk = self.fk(c)?;
        let bodies = self
            .links
            .iter()
            .zip(&fk.link_poses)
            .map(|(l, p)| {
                let r = p.rotation.to_rotation_matrix();
                BodyInertia {
                    m: l.inertial.mass,
                    c: p.translation.vector + r * l.inertial.com,
                    ic: r.matrix() * l.inertial.inertia * r.matrix().transpose(),
                }
            })
            .collect();
        let s = fk
            .joint_axes
            .iter()
            .zip(&fk.joint_points)
            .map(|(a, r)| Sv { ang: a.into_inner(), lin: r.cross(a) })
            .collect();
        let b = fk.link_poses[0];
        Ok(Kin { bodies, s, base_r: *b.rotation.to_rotation_matrix().matrix(), base_p: b.translation.vector })
    }

    fn check_len(&self, what: &str, x: &[f64], n: usize) -> Result<(), ModelError> {
        if x.len() != n || x.iter().any(|v| !v.is_finite()) {
            return Err(ModelError::Invalid(format!("{what}: expected {n} finite values, got {}", x.len())));
        }
        Ok(())
    }

    /// Inverse dynamics: generalized force needed for acceleration `a` at (`c`, `v`) under `gravity`
    /// (world vector, e.g. `[0, 0, -9.81]`), without contacts, damping or friction.
    /// `armature`: add each joint's armature × its acceleration.
    pub fn rnea(
        &self,
        c: &GenCoords,
        v: &[f64],
        a: &[f64],
        gravity: [f64; 3],
        armature: bool,
    ) -> Result<DVector<f64>, ModelError> {
        let nv = self.nv();
        self.check_len("v", v, nv)?;
        self.check_len("a", a, nv)?;
        let k = self.kin(c)?;
        Ok(self.rnea_kin(&k, v, a, gravity, armature))
    }

    fn rnea_kin(&self, k: &Kin, v: &[f64], a: &[f64], gravity: [f64; 3], armature: bool) -> DVector<f64> {
        let nl = self.links.len();
        let (r0, p0) = (k.base_r, k.base_p);
        let vo = Vector3::new(v[0], v[1], v[2]);
        let w0 = r0 * Vector3::new(v[3], v[4], v[5]);
        let ao = Vector3::new(a[0], a[1], a[2]);
        let al0 = r0 * Vector3::new(a[3], a[4], a[5]);
        let g = Vector3::new(gravity[0], gravity[1], gravity[2]);
        let mut vel = vec![Sv::zero(); nl];
        let mut acc = vec![Sv::zero(); nl];
        vel[0] = Sv { ang: w0, lin: vo + p0.cross(&w0) };
        // Gravity as a fictitious upward acceleration of the base.
        acc[0] = Sv { ang: al0, lin: ao + p0.cross(&al0) + vo.cross(&w0) - g };
        for li in 1..nl {
            let Some(ji) = self.links[li].parent_joint else { continue };
            let pl = self.joints[ji].parent_link;
            let s = k.s[ji];
            let vj = s.scale(v[6 + ji]);
            vel[li] = vel[pl].add(vj);
            acc[li] = acc[pl].add(s.scale(a[6 + ji])).add(vel[li].cross_m(vj));
        }
        let mut f: Vec<Sv> = (0..nl)
            .map(|i| {
                let b = &k.bodies[i];
                b.apply(acc[i]).add(vel[i].cross_f(b.apply(vel[i])))
            })
            .collect();
        let mut tau = DVector::zeros(self.nv());
        for li in (1..nl).rev() {
            let Some(ji) = self.links[li].parent_joint else { continue };
            let j = &self.joints[ji];
            tau[6 + ji] = k.s[ji].dot(f[li]) + if armature { j.armature * a[6 + ji] } else { 0.0 };
            let fl = f[li];
            f[j.parent_link] = f[j.parent_link].add(fl);
        }
        let (n, fo) = (f[0].ang, f[0].lin);
        let n_base = r0.transpose() * (n - p0.cross(&fo));
        for i in 0..3 {
            tau[i] = fo[i];
            tau[3 + i] = n_base[i];
        }
        tau
    }

    /// Joint-space mass matrix (nv × nv), optionally with armature on the joint diagonal.
    pub fn mass_matrix(&self, c: &GenCoords, armature: bool) -> Result<DMatrix<f64>, ModelError> {
        let k = self.kin(c)?;
        let nv = self.nv();
        let zero = vec![0.0; nv];
        let mut m = DMatrix::zeros(nv, nv);
        let mut e = vec![0.0; nv];
        for col in 0..nv {
            e.iter_mut().for_each(|x| *x = 0.0);
            e[col] = 1.0;
            let t = self.rnea_kin(&k, &zero, &e, [0.0; 3], armature);
            m.set_column(col, &t);
        }
        // Symmetrise away rounding (the exact matrix is symmetric).
        Ok((&m + m.transpose()) * 0.5)
    }

    /// Bias forces `C(q, v) v + g(q)` (generalized force at zero acceleration).
    pub fn bias_forces(&self, c: &GenCoords, v: &[f64], gravity: [f64; 3]) -> Result<DVector<f64>, ModelError> {
        self.rnea(c, v, &vec![0.0; self.nv()], gravity, false)
    }

    /// Forward dynamics without contact, damping or friction: `a = M⁻¹ (f − b)`.
    /// `f` is the full generalized force (nv); use [`RobotModel::joint_force`] for joint torques only.
    pub fn forward_dynamics(
        &self,
        c: &GenCoords,
        v: &[f64],
        f: &[f64],
        gravity: [f64; 3],
        armature: bool,
    ) -> Result<DVector<f64>, ModelError> {
        self.check_len("f", f, self.nv())?;
        let m = self.mass_matrix(c, armature)?;
        let b = self.bias_forces(c, v, gravity)?;
        let rhs = DVector::from_column_slice(f) - b;
        m.cholesky()
            .map(|ch| ch.solve(&rhs))
            .ok_or_else(|| ModelError::Invalid("mass matrix is not positive definite".into()))
    }

    /// Generalized force vector with zero base wrench and the given joint torques (slot order).
    pub fn joint_force(&self, tau: &[f64]) -> Vec<f64> {
        let mut f = vec![0.0; self.nv()];
        for (i, t) in tau.iter().enumerate().take(self.nj()) {
            f[6 + i] = *t;
        }
        f
    }

    /// Kinetic energy `½ vᵀ M v` (with or without armature).
    pub fn kinetic_energy(&self, c: &GenCoords, v: &[f64], armature: bool) -> Result<f64, ModelError> {
        self.check_len("v", v, self.nv())?;
        let m = self.mass_matrix(c, armature)?;
        let v = DVector::from_column_slice(v);
        Ok(0.5 * v.dot(&(m * &v)))
    }

    /// Gravitational potential energy `−m g·com` (zero at the world origin).
    pub fn potential_energy(&self, c: &GenCoords, gravity: [f64; 3]) -> Result<f64, ModelError> {
        let com = self.com(c)?;
        Ok(-self.total_mass() * Vector3::new(gravity[0], gravity[1], gravity[2]).dot(&com))
    }

    /// Spatial momentum (world frame): (angular momentum about the world origin, linear momentum).
    pub fn momentum(&self, c: &GenCoords, v: &[f64]) -> Result<([f64; 3], [f64; 3]), ModelError> {
        self.check_len("v", v, self.nv())?;
        let k = self.kin(c)?;
        let (r0, p0) = (k.base_r, k.base_p);
        let vo = Vector3::new(v[0], v[1], v[2]);
        let w0 = r0 * Vector3::new(v[3], v[4], v[5]);
        let mut vel = vec![Sv::zero(); self.links.len()];
        vel[0] = Sv { ang: w0, lin: vo + p0.cross(&w0) };
        let mut h = k.bodies[0].apply(vel[0]);
        for li in 1..self.links.len() {
            let Some(ji) = self.links[li].parent_joint else { continue };
            vel[li] = vel[self.joints[ji].parent_link].add(k.s[ji].scale(v[6 + ji]));
            h = h.add(k.bodies[li].apply(vel[li]));
        }
        Ok((h.ang.into(), h.lin.into()))
    }
}
