//! The crate's only contact with DART: `extern "C"` declarations of `cpp/dart_glue.cpp` and [`World`], a safe
//! owner of one glue world. Everything else in the DART engine is safe Rust.
//!
//! # Invariants
//! - **Ownership.** A [`World`] owns exactly one `UlabDart*` returned by `ulab_dart_create` (never null once
//!   constructed) and frees it exactly once, in `Drop`, with `ulab_dart_destroy`. No pointer into the C++ world
//!   outlives the call that produced it: every read copies into Rust buffers.
//! - **Lifetimes of inputs.** `ulab_dart_create` copies names, numbers and shapes into DART's own objects; the
//!   `CString`s and arrays passed to it only need to live for the call ([`World::new`] keeps them on its
//!   stack frame).
//! - **Buffer sizes.** Every output buffer is allocated here with the length the glue writes: `ndofs`
//!   (= 6 + number of joints) for generalized vectors, `ndofs²` for the mass matrix, `7 · links` for poses,
//!   `3 · joints` for axes; `ulab_dart_contacts` is given its capacity and returns how many it wrote.
//! - **Errors.** The glue catches every C++ exception; fallible calls return non-zero with a NUL-terminated
//!   message in a caller buffer, turned into `Err(String)` here. No C++ exception crosses the boundary.
//! - **Threads.** A [`World`] is neither `Send` nor `Sync` (it holds a raw pointer): it is created, used and
//!   dropped on one thread. That is what ODE's per-thread collision data needs (DART's ODE detector allocates
//!   it for the creating thread). Creation and destruction take a process-wide mutex inside the glue (ODE's
//!   reference-counted global init is not thread-safe), so worlds on different threads are independent.
//!   `&self` methods may update DART's lazily computed kinematics caches; as the type is not `Sync`, no two
//!   threads can call them at once.
//! - **Process-wide DART state.** DART's contact constraint parameters (`ContactConstraint` statics: error
//!   allowance, ERP, max error-reduction velocity, CFM) are global. The first world created sets them; a later
//!   world asking for different values is refused with an error, so no world ever runs with parameters other
//!   than its own.
use std::ffi::{c_char, CStr, CString};
use std::ptr::NonNull;

/// One model link for the glue (C layout, see `UlabDartLink` in `cpp/dart_glue.cpp`).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
struct RawLink {
    name: *const c_char,
    joint_name: *const c_char,
    parent: i32,
    mass: f64,
    com: [f64; 3],
    inertia: [f64; 9],
    joint_pos: [f64; 3],
    joint_quat: [f64; 4],
    axis: [f64; 3],
    lower: f64,
    upper: f64,
    armature: f64,
    damping: f64,
    coulomb_friction: f64,
    first_shape: u32,
    num_shapes: u32,
}

/// A collision primitive (C layout of `UlabDartShape`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawShape {
    /// 0 box (half extents a, b, c), 1 sphere (radius a), 2 capsule (radius a, half length b), 3 cylinder.
    pub kind: i32,
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub pos: [f64; 3],
    /// `[w, x, y, z]`.
    pub quat: [f64; 4],
}

/// World settings (C layout of `UlabDartWorldSettings`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawWorldSettings {
    pub timestep: f64,
    pub gravity: [f64; 3],
    pub ground: i32,
    pub limits: i32,
    pub self_collision: i32,
    pub friction: f64,
    pub restitution: f64,
    /// 0 ODE, 1 FCL, 2 DART.
    pub collision_detector: i32,
    /// 0 Dantzig, 1 PGS.
    pub lcp_solver: i32,
    pub secondary_pgs: i32,
    pub pgs_iterations: u32,
    pub max_contacts: u32,
    pub error_allowance: f64,
    pub error_reduction: f64,
    pub max_error_reduction_velocity: f64,
    pub constraint_force_mixing: f64,
}

/// One contact as DART reports it (C layout of `UlabDartContact`): link indices (-1 = ground), normal from
/// body 2 to body 1, force on body 1, both in the world frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RawContact {
    pub link1: i32,
    pub link2: i32,
    pub point: [f64; 3],
    pub normal: [f64; 3],
    pub force: [f64; 3],
    pub depth: f64,
}

#[repr(C)]
struct UlabDart {
    _private: [u8; 0],
}

extern "C" {
    fn ulab_dart_version(out: *mut c_char, len: usize);
    fn ulab_dart_create(
        links: *const RawLink,
        nlinks: usize,
        shapes: *const RawShape,
        nshapes: usize,
        settings: *const RawWorldSettings,
        base_pose: *const f64,
        q: *const f64,
        vel: *const f64,
        out: *mut *mut UlabDart,
        err: *mut c_char,
        err_len: usize,
    ) -> i32;
    fn ulab_dart_destroy(d: *mut UlabDart);
    fn ulab_dart_ndofs(d: *const UlabDart) -> usize;
    fn ulab_dart_step(d: *mut UlabDart, forces: *const f64, err: *mut c_char, err_len: usize) -> i32;
    fn ulab_dart_time(d: *const UlabDart) -> f64;
    fn ulab_dart_state(
        d: *mut UlabDart,
        base_pose: *mut f64,
        q: *mut f64,
        vel: *mut f64,
        err: *mut c_char,
        err_len: usize,
    ) -> i32;
    fn ulab_dart_num_contacts(d: *const UlabDart) -> usize;
    fn ulab_dart_contacts(d: *const UlabDart, out: *mut RawContact, cap: usize) -> usize;
    fn ulab_dart_link_poses(d: *const UlabDart, out: *mut f64);
    fn ulab_dart_joint_axes(d: *const UlabDart, out: *mut f64);
    fn ulab_dart_joint_limits(d: *const UlabDart, lower: *mut f64, upper: *mut f64) -> usize;
    fn ulab_dart_link_masses(d: *const UlabDart, out: *mut f64);
    fn ulab_dart_com(d: *const UlabDart, out: *mut f64);
    fn ulab_dart_energy(d: *const UlabDart, kinetic: *mut f64, potential: *mut f64);
    fn ulab_dart_mass_matrix(d: *const UlabDart, out: *mut f64, err: *mut c_char, err_len: usize) -> i32;
    fn ulab_dart_bias_forces(d: *const UlabDart, out: *mut f64, err: *mut c_char, err_len: usize) -> i32;
    fn ulab_dart_forward_dynamics(
        d: *mut UlabDart,
        forces: *const f64,
        acc: *mut f64,
        err: *mut c_char,
        err_len: usize,
    ) -> i32;
    fn ulab_dart_constraint_params(out: *mut f64);
    fn ulab_dart_urdf_probe(
        urdf: *const c_char,
        joint_names: *const *const c_char,
        nj: usize,
        base_pose: *const f64,
        q: *const f64,
        total_mass: *mut f64,
        mass_matrix: *mut f64,
        limits_enforced: *mut i32,
        damping: *mut f64,
        friction: *mut f64,
        err: *mut c_char,
        err_len: usize,
    ) -> i32;
}

const ERR_LEN: usize = 1024;

/// Runs a fallible glue call with an error buffer; `Err` carries the glue's message.
fn checked(f: impl FnOnce(*mut c_char, usize) -> i32) -> Result<(), String> {
    let mut buf = vec![0u8; ERR_LEN];
    let code = f(buf.as_mut_ptr().cast(), ERR_LEN);
    if code == 0 {
        return Ok(());
    }
    let msg = CStr::from_bytes_until_nul(&buf).map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();
    Err(if msg.is_empty() { format!("DART glue error {code}") } else { msg })
}

fn cstring(s: &str) -> Result<CString, String> {
    CString::new(s).map_err(|_| format!("name {s:?} contains a NUL byte"))
}

/// A model link as the safe side describes it.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkSpec {
    pub name: String,
    pub joint_name: String,
    /// Parent link index (`None` for the base, which must be link 0).
    pub parent: Option<usize>,
    pub mass: f64,
    pub com: [f64; 3],
    /// Row-major inertia about the COM in the link frame.
    pub inertia: [f64; 9],
    pub joint_pos: [f64; 3],
    pub joint_quat: [f64; 4],
    pub axis: [f64; 3],
    pub lower: f64,
    pub upper: f64,
    /// Reflected rotor inertia of the joint (the glue's `ArmatureRevoluteJoint`).
    pub armature: f64,
    pub damping: f64,
    pub coulomb_friction: f64,
    pub shapes: Vec<RawShape>,
}

/// State in DART's coordinates: pelvis pose `[x, y, z, w, qx, qy, qz]`, joint angles (link order) and the
/// DART velocity vector `[ω pelvis frame, v pelvis frame, joint rates (link order)]`.
#[derive(Debug, Clone, PartialEq)]
pub struct RawState {
    pub base_pose: [f64; 7],
    pub q: Vec<f64>,
    pub vel: Vec<f64>,
}

/// What DART's URDF loader made of a URDF (see `ulab_dart_urdf_probe`).
#[derive(Debug, Clone, PartialEq)]
pub struct UrdfProbe {
    pub total_mass: f64,
    /// Row-major, DART coordinates, `[free joint (6), joints in the order asked]`.
    pub mass_matrix: Vec<f64>,
    pub limits_enforced: Vec<bool>,
    pub damping: Vec<f64>,
    pub friction: Vec<f64>,
}

/// One DART world with the robot (and ground); see the module invariants.
#[derive(Debug)]
pub struct World {
    ptr: NonNull<UlabDart>,
    ndofs: usize,
    nlinks: usize,
}

impl Drop for World {
    fn drop(&mut self) {
        // SAFETY: `ptr` came from ulab_dart_create and is destroyed only here, once.
        unsafe { ulab_dart_destroy(self.ptr.as_ptr()) }
    }
}

/// `"DART 6.12.1 (ODE ...)"`.
pub fn version() -> String {
    let mut buf = vec![0u8; 512];
    // SAFETY: the glue writes at most `len` bytes including the NUL.
    unsafe { ulab_dart_version(buf.as_mut_ptr().cast(), buf.len()) };
    CStr::from_bytes_until_nul(&buf).map(|c| c.to_string_lossy().into_owned()).unwrap_or_default()
}

/// DART's process-wide constraint parameters in force: `[error allowance, ERP, max ERV, CFM]` of contacts, then
/// of joint limits.
pub fn constraint_params() -> [f64; 8] {
    let mut out = [0.0; 8];
    // SAFETY: writes exactly 8 doubles.
    unsafe { ulab_dart_constraint_params(out.as_mut_ptr()) };
    out
}

/// Loads `urdf` with DART's own URDF loader and reports its mass properties and joint settings at a
/// configuration (joint angles in `joint_names` order). For tests: an independent route to the skeleton.
pub fn urdf_probe(urdf: &str, joint_names: &[&str], base_pose: [f64; 7], q: &[f64]) -> Result<UrdfProbe, String> {
    if q.len() != joint_names.len() {
        return Err(format!("{} joint angles for {} joints", q.len(), joint_names.len()));
    }
    let urdf_c = cstring(urdf)?;
    let names: Vec<CString> = joint_names.iter().map(|n| cstring(n)).collect::<Result<_, _>>()?;
    let name_ptrs: Vec<*const c_char> = names.iter().map(|n| n.as_ptr()).collect();
    let nj = joint_names.len();
    let n = 6 + nj;
    let mut out = UrdfProbe {
        total_mass: 0.0,
        mass_matrix: vec![0.0; n * n],
        limits_enforced: Vec::new(),
        damping: vec![0.0; nj],
        friction: vec![0.0; nj],
    };
    let mut enforced = vec![0i32; nj];
    checked(|err, len| {
        // SAFETY: inputs live for the call; outputs have the sizes the glue writes (n², nj).
        unsafe {
            ulab_dart_urdf_probe(
                urdf_c.as_ptr(),
                name_ptrs.as_ptr(),
                nj,
                base_pose.as_ptr(),
                q.as_ptr(),
                &mut out.total_mass,
                out.mass_matrix.as_mut_ptr(),
                enforced.as_mut_ptr(),
                out.damping.as_mut_ptr(),
                out.friction.as_mut_ptr(),
                err,
                len,
            )
        }
    })?;
    out.limits_enforced = enforced.into_iter().map(|e| e != 0).collect();
    Ok(out)
}

impl World {
    /// Builds a world from links (parents before children, link 0 the floating base) at a state.
    pub fn new(links: &[LinkSpec], settings: &RawWorldSettings, state: &RawState) -> Result<Self, String> {
        let nlinks = links.len();
        if nlinks == 0 || links[0].parent.is_some() {
            return Err("link 0 must be the floating base".into());
        }
        let ndofs = 6 + nlinks - 1;
        if state.q.len() != nlinks - 1 || state.vel.len() != ndofs {
            return Err(format!("state sizes {} / {} do not match {nlinks} links", state.q.len(), state.vel.len()));
        }
        let mut names = Vec::with_capacity(2 * nlinks);
        let mut shapes = Vec::new();
        let mut raw = Vec::with_capacity(nlinks);
        for (i, l) in links.iter().enumerate() {
            let parent = match l.parent {
                None if i == 0 => -1,
                Some(p) if p < i => i32::try_from(p).map_err(|_| "too many links".to_string())?,
                _ => return Err(format!("link {}: its parent must precede it", l.name)),
            };
            let name = cstring(&l.name)?;
            let joint_name = cstring(&l.joint_name)?;
            let first_shape = u32::try_from(shapes.len()).map_err(|_| "too many shapes".to_string())?;
            let num_shapes = u32::try_from(l.shapes.len()).map_err(|_| "too many shapes".to_string())?;
            shapes.extend_from_slice(&l.shapes);
            raw.push(RawLink {
                name: name.as_ptr(),
                joint_name: joint_name.as_ptr(),
                parent,
                mass: l.mass,
                com: l.com,
                inertia: l.inertia,
                joint_pos: l.joint_pos,
                joint_quat: l.joint_quat,
                axis: l.axis,
                lower: l.lower,
                upper: l.upper,
                armature: l.armature,
                damping: l.damping,
                coulomb_friction: l.coulomb_friction,
                first_shape,
                num_shapes,
            });
            // The CStrings' heap buffers do not move when the CString values are moved into `names`.
            names.push(name);
            names.push(joint_name);
        }
        let mut ptr: *mut UlabDart = std::ptr::null_mut();
        checked(|err, len| {
            // SAFETY: every pointer is valid for the call (names, raw, shapes and state live on this frame);
            // sizes are passed alongside; the glue writes the new world into `ptr` only on success.
            unsafe {
                ulab_dart_create(
                    raw.as_ptr(),
                    raw.len(),
                    shapes.as_ptr(),
                    shapes.len(),
                    settings,
                    state.base_pose.as_ptr(),
                    state.q.as_ptr(),
                    state.vel.as_ptr(),
                    &mut ptr,
                    err,
                    len,
                )
            }
        })?;
        drop(names);
        let ptr = NonNull::new(ptr).ok_or_else(|| "DART glue returned no world".to_string())?;
        let world = World { ptr, ndofs, nlinks };
        // SAFETY: valid world.
        let got = unsafe { ulab_dart_ndofs(world.ptr.as_ptr()) };
        if got != ndofs {
            return Err(format!("DART built {got} dofs, expected {ndofs}"));
        }
        Ok(world)
    }

    pub fn ndofs(&self) -> usize {
        self.ndofs
    }

    /// One `World::step` with generalized forces in DART coordinates.
    pub fn step(&mut self, forces: &[f64]) -> Result<(), String> {
        if forces.len() != self.ndofs {
            return Err(format!("{} forces for {} dofs", forces.len(), self.ndofs));
        }
        // SAFETY: valid world; `forces` has ndofs entries.
        checked(|err, len| unsafe { ulab_dart_step(self.ptr.as_ptr(), forces.as_ptr(), err, len) })
    }

    pub fn time(&self) -> f64 {
        // SAFETY: valid world.
        unsafe { ulab_dart_time(self.ptr.as_ptr()) }
    }

    pub fn state(&self) -> Result<RawState, String> {
        let mut s = RawState { base_pose: [0.0; 7], q: vec![0.0; self.nlinks - 1], vel: vec![0.0; self.ndofs] };
        checked(|err, len| {
            // SAFETY: valid world; buffers of 7, nlinks - 1 and ndofs doubles.
            unsafe {
                ulab_dart_state(
                    self.ptr.as_ptr(),
                    s.base_pose.as_mut_ptr(),
                    s.q.as_mut_ptr(),
                    s.vel.as_mut_ptr(),
                    err,
                    len,
                )
            }
        })?;
        Ok(s)
    }

    pub fn contacts(&self) -> Vec<RawContact> {
        // SAFETY: valid world.
        let n = unsafe { ulab_dart_num_contacts(self.ptr.as_ptr()) };
        let mut out = vec![RawContact::default(); n];
        // SAFETY: `out` has capacity n; the glue writes at most n and returns the count written.
        let written = unsafe { ulab_dart_contacts(self.ptr.as_ptr(), out.as_mut_ptr(), n) };
        out.truncate(written);
        out
    }

    /// `[x, y, z, w, qx, qy, qz]` of every link frame, link order.
    pub fn link_poses(&self) -> Vec<[f64; 7]> {
        let mut flat = vec![0.0; 7 * self.nlinks];
        // SAFETY: valid world; 7 doubles per link.
        unsafe { ulab_dart_link_poses(self.ptr.as_ptr(), flat.as_mut_ptr()) };
        flat.chunks_exact(7).map(|c| [c[0], c[1], c[2], c[3], c[4], c[5], c[6]]).collect()
    }

    /// World axes of the joints of links 1.. (link order).
    pub fn joint_axes(&self) -> Vec<[f64; 3]> {
        let mut flat = vec![0.0; 3 * (self.nlinks - 1)];
        // SAFETY: valid world; 3 doubles per joint.
        unsafe { ulab_dart_joint_axes(self.ptr.as_ptr(), flat.as_mut_ptr()) };
        flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
    }

    /// `(lower, upper)` of the joints of links 1.. (link order) and how many enforce their limits.
    pub fn joint_limits(&self) -> (Vec<(f64, f64)>, usize) {
        let n = self.nlinks - 1;
        let (mut lo, mut hi) = (vec![0.0; n], vec![0.0; n]);
        // SAFETY: valid world; n doubles each.
        let enforced = unsafe { ulab_dart_joint_limits(self.ptr.as_ptr(), lo.as_mut_ptr(), hi.as_mut_ptr()) };
        (lo.into_iter().zip(hi).collect(), enforced)
    }

    pub fn link_masses(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.nlinks];
        // SAFETY: valid world; one double per link.
        unsafe { ulab_dart_link_masses(self.ptr.as_ptr(), out.as_mut_ptr()) };
        out
    }

    pub fn com(&self) -> [f64; 3] {
        let mut out = [0.0; 3];
        // SAFETY: valid world; 3 doubles.
        unsafe { ulab_dart_com(self.ptr.as_ptr(), out.as_mut_ptr()) };
        out
    }

    /// DART's `(kinetic, potential)` energy of the robot skeleton.
    pub fn energy(&self) -> (f64, f64) {
        let (mut k, mut p) = (0.0, 0.0);
        // SAFETY: valid world; two doubles.
        unsafe { ulab_dart_energy(self.ptr.as_ptr(), &mut k, &mut p) };
        (k, p)
    }

    /// Row-major mass matrix in DART coordinates.
    pub fn mass_matrix(&self) -> Result<Vec<f64>, String> {
        let mut out = vec![0.0; self.ndofs * self.ndofs];
        // SAFETY: valid world; ndofs² doubles.
        checked(|err, len| unsafe { ulab_dart_mass_matrix(self.ptr.as_ptr(), out.as_mut_ptr(), err, len) })?;
        Ok(out)
    }

    /// Coriolis, centrifugal and gravity forces in DART coordinates.
    pub fn bias_forces(&self) -> Result<Vec<f64>, String> {
        let mut out = vec![0.0; self.ndofs];
        // SAFETY: valid world; ndofs doubles.
        checked(|err, len| unsafe { ulab_dart_bias_forces(self.ptr.as_ptr(), out.as_mut_ptr(), err, len) })?;
        Ok(out)
    }

    /// Contact-free accelerations (DART coordinates) under generalized forces (DART coordinates); the state is
    /// left as it was.
    pub fn forward_dynamics(&mut self, forces: &[f64]) -> Result<Vec<f64>, String> {
        if forces.len() != self.ndofs {
            return Err(format!("{} forces for {} dofs", forces.len(), self.ndofs));
        }
        let mut acc = vec![0.0; self.ndofs];
        checked(|err, len| {
            // SAFETY: valid world; forces and acc have ndofs entries.
            unsafe { ulab_dart_forward_dynamics(self.ptr.as_ptr(), forces.as_ptr(), acc.as_mut_ptr(), err, len) }
        })?;
        Ok(acc)
    }
}
