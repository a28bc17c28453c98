//! The only unsafe code of the Bullet engine: declarations of the C ABI of `cpp/bullet_glue.cpp` and a safe
//! owner of one simulation ([`Sim`]).
//!
//! # Invariants
//! - **Ownership.** `ubt_create` returns a heap object that owns every Bullet object of one world and copies
//!   of the descriptions it was built from; [`Sim`] holds the only pointer to it and frees it exactly once in
//!   `Drop` (`ubt_destroy`). The C++ side never keeps a pointer into Rust memory: every array is copied during
//!   the call.
//! - **Lengths.** Every array handed to C++ is checked here against the body count fixed at creation
//!   (`nlinks` joint entries, `nlinks + 1` bodies, `6 + nlinks` accelerations) before the call, so the C++
//!   side never reads or writes past a Rust buffer.
//! - **Errors.** Every fallible C++ function catches every exception and returns non-zero with a NUL-terminated
//!   message written into a buffer of the length passed; no exception crosses the ABI.
//! - **Threads.** A `Sim` is neither `Send` nor `Sync` (it holds a raw pointer): it is used on the thread that
//!   created it. Independent `Sim`s on different threads share no Bullet object; Debian's Bullet is built
//!   without `BT_THREADSAFE` and without profiling, and the only process-wide state the simulation touches is
//!   read-only (`gContactBreakingThreshold` and friends) or statistics counters that it never reads back.
//! - **Layout.** The `#[repr(C)]` structs below mirror the structs of `bullet_glue.cpp` field by field; the
//!   C++ file asserts at compile time that `btScalar` is `double` (the `bullet-float64` build).
#![allow(unsafe_code)]

use std::ffi::{c_char, CStr};

#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct UbtBody {
    pub parent: i32,
    pub reserved: i32,
    pub mass: f64,
    pub inertia: [f64; 3],
    pub rot_parent_to_this: [f64; 4],
    pub axis: [f64; 3],
    pub parent_com_to_pivot: [f64; 3],
    pub pivot_to_com: [f64; 3],
    pub lower: f64,
    pub upper: f64,
    pub friction_torque: f64,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct UbtShape {
    pub body: i32,
    pub kind: i32,
    pub dims: [f64; 3],
    pub pos: [f64; 3],
    pub quat: [f64; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct UbtConfig {
    pub timestep: f64,
    pub gravity: [f64; 3],
    pub ground: i32,
    pub collisions: i32,
    pub joint_limits: i32,
    pub self_collision: i32,
    pub solver_iterations: i32,
    pub gyroscopic: i32,
    pub friction: f64,
    pub restitution: f64,
    pub rolling_friction: f64,
    pub spinning_friction: f64,
    pub erp: f64,
    pub erp2: f64,
    pub global_cfm: f64,
    pub friction_erp: f64,
    pub warmstarting_factor: f64,
    pub articulated_warmstarting_factor: f64,
    pub solver_mode: i32,
    pub reserved: i32,
    pub collision_margin: f64,
    pub max_coordinate_velocity: f64,
    pub joint_limit_max_impulse: f64,
    pub linear_damping: f64,
    pub angular_damping: f64,
}

/// Base state in Bullet's terms: base body (COM, principal axes) pose, COM velocity and angular velocity, world.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct UbtBaseState {
    pub pos: [f64; 3],
    /// `[x, y, z, w]`, base-body-to-world.
    pub quat: [f64; 4],
    pub lin_vel: [f64; 3],
    pub ang_vel: [f64; 3],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct UbtContact {
    pub user_a: i32,
    pub user_b: i32,
    pub point_a: [f64; 3],
    pub point_b: [f64; 3],
    pub normal_on_b: [f64; 3],
    pub distance: f64,
    pub impulse: f64,
}

/// Opaque simulation object of the C++ layer.
#[repr(C)]
#[derive(Debug)]
pub struct UbtSim {
    _private: [u8; 0],
}

extern "C" {
    fn ubt_version() -> i32;
    fn ubt_create(
        cfg: *const UbtConfig,
        bodies: *const UbtBody,
        nbodies: i32,
        shapes: *const UbtShape,
        nshapes: i32,
        out: *mut *mut UbtSim,
        err: *mut c_char,
        errlen: usize,
    ) -> i32;
    fn ubt_destroy(sim: *mut UbtSim);
    fn ubt_reset(
        sim: *mut UbtSim,
        base: *const UbtBaseState,
        q: *const f64,
        qd: *const f64,
        err: *mut c_char,
        errlen: usize,
    ) -> i32;
    fn ubt_get_state(sim: *const UbtSim, base: *mut UbtBaseState, q: *mut f64, qd: *mut f64);
    fn ubt_step(
        sim: *mut UbtSim,
        tau: *const f64,
        base_force: *const f64,
        base_torque: *const f64,
        err: *mut c_char,
        errlen: usize,
    ) -> i32;
    fn ubt_body_poses(sim: *mut UbtSim, pos: *mut f64, quat: *mut f64);
    fn ubt_accelerations(
        sim: *mut UbtSim,
        tau: *const f64,
        base_force: *const f64,
        base_torque: *const f64,
        out: *mut f64,
        err: *mut c_char,
        errlen: usize,
    ) -> i32;
    fn ubt_kinetic_energy(sim: *const UbtSim) -> f64;
    fn ubt_masses(sim: *const UbtSim, out: *mut f64);
    fn ubt_joint_limits(sim: *const UbtSim, lower: *mut f64, upper: *mut f64) -> i32;
    fn ubt_contacts(sim: *const UbtSim, out: *mut UbtContact, cap: i32) -> i32;
}

const ERR_LEN: usize = 512;

fn message(buf: &[c_char; ERR_LEN]) -> String {
    // SAFETY: the buffer is zero-initialised and the C++ side writes at most ERR_LEN - 1 bytes plus a NUL, so
    // a NUL terminator always exists inside the buffer.
    let s = unsafe { CStr::from_ptr(buf.as_ptr()) };
    let s = s.to_string_lossy().into_owned();
    if s.is_empty() {
        "Bullet glue reported an error without a message".into()
    } else {
        s
    }
}

/// Bullet's version as compiled against (`BT_BULLET_VERSION`, e.g. 324).
pub fn version() -> i32 {
    // SAFETY: no arguments, returns a constant.
    unsafe { ubt_version() }
}

/// One Bullet world with one multibody, owned.
#[derive(Debug)]
pub struct Sim {
    ptr: std::ptr::NonNull<UbtSim>,
    nlinks: usize,
}

impl Drop for Sim {
    fn drop(&mut self) {
        // SAFETY: `ptr` came from a successful `ubt_create` and is freed only here.
        unsafe { ubt_destroy(self.ptr.as_ptr()) }
    }
}

impl Sim {
    /// Builds a world. `bodies[0]` is the floating base.
    pub fn new(cfg: &UbtConfig, bodies: &[UbtBody], shapes: &[UbtShape]) -> Result<Self, String> {
        if bodies.is_empty() {
            return Err("no bodies".into());
        }
        let nb = i32::try_from(bodies.len()).map_err(|_| "too many bodies".to_string())?;
        let ns = i32::try_from(shapes.len()).map_err(|_| "too many shapes".to_string())?;
        let mut out: *mut UbtSim = std::ptr::null_mut();
        let mut err = [0 as c_char; ERR_LEN];
        // SAFETY: pointers to live slices with the lengths passed; `out` is a valid out-pointer; the C++ side
        // copies everything it keeps.
        let rc =
            unsafe { ubt_create(cfg, bodies.as_ptr(), nb, shapes.as_ptr(), ns, &mut out, err.as_mut_ptr(), ERR_LEN) };
        if rc != 0 {
            return Err(message(&err));
        }
        let ptr = std::ptr::NonNull::new(out).ok_or_else(|| "Bullet glue returned no simulation".to_string())?;
        Ok(Sim { ptr, nlinks: bodies.len() - 1 })
    }

    /// Number of links (= joints) besides the base.
    pub fn nlinks(&self) -> usize {
        self.nlinks
    }

    fn check(&self, what: &str, n: usize, want: usize) -> Result<(), String> {
        if n != want {
            return Err(format!("{what}: {n} entries, the multibody has {want}"));
        }
        Ok(())
    }

    /// Rebuilds the whole Bullet world (no history survives) and sets the state.
    pub fn reset(&mut self, base: &UbtBaseState, q: &[f64], qd: &[f64]) -> Result<(), String> {
        self.check("joint positions", q.len(), self.nlinks)?;
        self.check("joint velocities", qd.len(), self.nlinks)?;
        let mut err = [0 as c_char; ERR_LEN];
        // SAFETY: valid sim; q and qd hold nlinks entries (checked); base is a valid struct.
        let rc = unsafe { ubt_reset(self.ptr.as_ptr(), base, q.as_ptr(), qd.as_ptr(), err.as_mut_ptr(), ERR_LEN) };
        if rc != 0 {
            return Err(message(&err));
        }
        Ok(())
    }

    /// Base state and joint positions/velocities.
    pub fn state(&self) -> (UbtBaseState, Vec<f64>, Vec<f64>) {
        let mut base = UbtBaseState::default();
        let mut q = vec![0.0; self.nlinks];
        let mut qd = vec![0.0; self.nlinks];
        // SAFETY: valid sim; q and qd have nlinks entries.
        unsafe { ubt_get_state(self.ptr.as_ptr(), &mut base, q.as_mut_ptr(), qd.as_mut_ptr()) };
        (base, q, qd)
    }

    /// One world step with joint torques (one per link) and optionally a base wrench: a force (world, through the
    /// base COM) and a torque (world).
    pub fn step(&mut self, tau: &[f64], base: Option<([f64; 3], [f64; 3])>) -> Result<(), String> {
        self.check("joint torques", tau.len(), self.nlinks)?;
        let mut err = [0 as c_char; ERR_LEN];
        let (force, torque) = match &base {
            Some((f, t)) => (f.as_ptr(), t.as_ptr()),
            None => (std::ptr::null(), std::ptr::null()),
        };
        // SAFETY: valid sim; tau has nlinks entries; force and torque are null or point at 3 doubles that outlive
        // the call (`base` is borrowed for it).
        let rc = unsafe { ubt_step(self.ptr.as_ptr(), tau.as_ptr(), force, torque, err.as_mut_ptr(), ERR_LEN) };
        if rc != 0 {
            return Err(message(&err));
        }
        Ok(())
    }

    /// World poses of every body frame (base first): position and `[x, y, z, w]` quaternion.
    pub fn body_poses(&mut self) -> Vec<([f64; 3], [f64; 4])> {
        let n = self.nlinks + 1;
        let mut pos = vec![0.0; 3 * n];
        let mut quat = vec![0.0; 4 * n];
        // SAFETY: valid sim; buffers of 3n and 4n entries.
        unsafe { ubt_body_poses(self.ptr.as_ptr(), pos.as_mut_ptr(), quat.as_mut_ptr()) };
        (0..n)
            .map(|i| {
                (
                    [pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]],
                    [quat[4 * i], quat[4 * i + 1], quat[4 * i + 2], quat[4 * i + 3]],
                )
            })
            .collect()
    }

    /// Contact-free accelerations `[ω̇ world, v̇_com world, q̈]` under gravity, joint torques and a base wrench
    /// (force world through the base COM, torque world).
    pub fn accelerations(&mut self, tau: &[f64], force: [f64; 3], torque: [f64; 3]) -> Result<Vec<f64>, String> {
        self.check("joint torques", tau.len(), self.nlinks)?;
        let mut out = vec![0.0; 6 + self.nlinks];
        let mut err = [0 as c_char; ERR_LEN];
        // SAFETY: valid sim; tau has nlinks entries, out 6 + nlinks, force/torque 3 each.
        let rc = unsafe {
            ubt_accelerations(
                self.ptr.as_ptr(),
                tau.as_ptr(),
                force.as_ptr(),
                torque.as_ptr(),
                out.as_mut_ptr(),
                err.as_mut_ptr(),
                ERR_LEN,
            )
        };
        if rc != 0 {
            return Err(message(&err));
        }
        Ok(out)
    }

    /// Kinetic energy over Bullet's own bodies.
    pub fn kinetic_energy(&self) -> f64 {
        // SAFETY: valid sim; read-only.
        unsafe { ubt_kinetic_energy(self.ptr.as_ptr()) }
    }

    /// Masses as built, base first.
    pub fn masses(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.nlinks + 1];
        // SAFETY: valid sim; buffer of nlinks + 1 entries.
        unsafe { ubt_masses(self.ptr.as_ptr(), out.as_mut_ptr()) };
        out
    }

    /// Joint limits as built (one per link), or `None` when the world has no limit constraints.
    pub fn joint_limits(&self) -> Option<Vec<(f64, f64)>> {
        let mut lo = vec![0.0; self.nlinks];
        let mut hi = vec![0.0; self.nlinks];
        // SAFETY: valid sim; buffers of nlinks entries.
        let have = unsafe { ubt_joint_limits(self.ptr.as_ptr(), lo.as_mut_ptr(), hi.as_mut_ptr()) };
        (have != 0).then(|| lo.into_iter().zip(hi).collect())
    }

    /// Every contact point of the last step's manifolds.
    pub fn contacts(&self) -> Vec<UbtContact> {
        // SAFETY: valid sim; a null buffer with capacity 0 only counts.
        let n = unsafe { ubt_contacts(self.ptr.as_ptr(), std::ptr::null_mut(), 0) };
        let Ok(cap) = usize::try_from(n) else { return Vec::new() };
        let mut out = vec![UbtContact::default(); cap];
        // SAFETY: buffer of `cap` entries; the manifolds did not change since the count (no call in between).
        let written = unsafe { ubt_contacts(self.ptr.as_ptr(), out.as_mut_ptr(), n) };
        out.truncate(usize::try_from(written).unwrap_or(0).min(cap));
        out
    }
}
