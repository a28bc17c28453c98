"""Newton (NVIDIA Warp) physics server for ulab's `newton_*` engines (crate diff-physics, feature `newton`).

One robot, one solver, driven over stdin/stdout by the Rust engine (src/newton/). Framing, little endian:
request  = u32 length | u8 opcode | payload           (length counts opcode + payload)
response = u32 length | u8 status | payload           (status 0 ok, 1 error, 2 diverged; error payload = UTF-8)

Every vector crossing the pipe is f64 in the interface's conventions (engine.rs): qpos = [pelvis origin (3),
quaternion wxyz (4), joints in slot order], qvel = [pelvis-origin velocity (world), angular velocity (pelvis
frame), joint rates]. The conversions to Newton's (quaternion xyzw, base velocity = COM velocity and world
angular velocity, joints in Newton's order) happen here, in f64 numpy, next to the f32 Newton state.

Newton and Warp print to stdout; the protocol keeps the original stdout descriptor and points fd 1 at stderr
before importing them, so nothing but frames ever reaches the Rust side.
"""

import json
import os
import struct
import sys
import traceback

OP_INIT, OP_RESET, OP_STEP, OP_STATE, OP_CONTACTS, OP_ENERGY = 1, 2, 3, 4, 5, 6
OP_KINEMATICS, OP_MASS_MATRIX, OP_BIAS, OP_ACCEL, OP_WRENCH, OP_QUIT = 7, 8, 9, 10, 11, 12
OK, ERROR, DIVERGED = 0, 1, 2
SOLVERS = ("featherstone", "steel", "xpbd", "semi_implicit", "mujoco")


class Diverged(Exception):
    pass


class InputError(Exception):
    pass


def read_exact(f, n):
    buf = b""
    while len(buf) < n:
        chunk = f.read(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return buf


def read_frame(f):
    head = read_exact(f, 4)
    if head is None:
        return None
    (n,) = struct.unpack("<I", head)
    if n < 1:
        raise InputError("empty frame")
    body = read_exact(f, n)
    if body is None:
        return None
    return body[0], body[1:]


def write_frame(f, status, payload=b""):
    f.write(struct.pack("<IB", len(payload) + 1, status) + payload)
    f.flush()


def f64s(arr):
    import numpy as np

    return np.asarray(arr, dtype="<f8").tobytes()


def skew(v):
    import numpy as np

    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def quat_wxyz_to_R(q):
    import numpy as np

    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


class Sim:
    """The robot in one Newton solver."""

    def __init__(self, cfg):
        import numpy as np
        import warp as wp

        wp.config.quiet = True
        wp.init()
        import newton

        self.np, self.wp, self.newton = np, wp, newton
        s = cfg["settings"]
        c = cfg["common"]
        self.solver_name = s["solver"]
        if self.solver_name not in SOLVERS:
            raise InputError(f"unknown solver {self.solver_name!r} (known: {', '.join(SOLVERS)})")
        self.dt = float(c["timestep"])
        self.substeps = max(1, int(s["substeps"]))
        self.s = s
        b = newton.ModelBuilder()
        # Newton's shape defaults are ke 2.5e3 N/m, kd 100, kf 1e3: far too soft for a 67 kg robot; the
        # settings' values go on every shape (the MJCF's solref/solimp are MuJoCo's and do not map onto them).
        sc = b.default_shape_cfg
        sc.ke, sc.kd, sc.kf, sc.mu = s["contact_ke"], s["contact_kd"], s["contact_kf"], cfg["friction"]
        sc.restitution = 0.0
        b.add_mjcf(
            cfg["mjcf"],
            enable_self_collisions=bool(cfg["self_collision"]),
            parse_visuals=False,
        )
        if c["ground"]:
            # The ground is Newton's own plane: an MJCF floor geom (contype 1 / conaffinity 2) produced no
            # contacts with the robot's geoms in Newton 1.8.0, so the MJCF comes without one.
            b.add_ground_plane(cfg=sc)
        self.model = m = b.finalize(device="cpu")
        m.set_gravity(tuple(float(g) for g in c["gravity"]))
        # Joint effects as the common settings say (each one is a normalisation listed in the report).
        jd = m.joint_dof_count
        nj = len(cfg["joint_names"])
        if jd != 6 + nj:
            raise InputError(f"Newton built {jd} dofs, the model has {6 + nj}")
        if not c["armature"]:
            m.joint_armature.assign(np.zeros(jd, dtype=np.float32))
        if not c["joint_damping"]:
            m.joint_damping.assign(np.zeros(jd, dtype=np.float32))
        if not c["joint_friction"]:
            m.joint_friction.assign(np.zeros(jd, dtype=np.float32))
        lower = m.joint_limit_lower.numpy().astype(np.float64)
        upper = m.joint_limit_upper.numpy().astype(np.float64)
        if not c["joint_limits"]:
            m.joint_limit_ke.assign(np.zeros(jd, dtype=np.float32))
            m.joint_limit_kd.assign(np.zeros(jd, dtype=np.float32))
        else:
            m.joint_limit_ke.assign(np.full(jd, s["limit_ke"], dtype=np.float32))
            m.joint_limit_kd.assign(np.full(jd, s["limit_kd"], dtype=np.float32))
        self.limits_on = bool(c["joint_limits"])

        # Name maps: joints and bodies by the last component of Newton's labels.
        jl = [lab.rsplit("/", 1)[-1] for lab in m.joint_label]
        bl = [lab.rsplit("/", 1)[-1] for lab in m.body_label]
        q_start = m.joint_q_start.numpy()
        qd_start = m.joint_qd_start.numpy()
        self.jq, self.jd, self.jidx = [], [], []
        for name in cfg["joint_names"]:
            if name not in jl:
                raise InputError(f"joint {name} not in Newton's model")
            j = jl.index(name)
            self.jidx.append(j)
            self.jq.append(int(q_start[j]))
            self.jd.append(int(qd_start[j]))
        self.bodies = []
        for name in cfg["link_names"]:
            if name not in bl:
                raise InputError(f"body {name} not in Newton's model")
            self.bodies.append(bl.index(name))
        self.base = self.bodies[0]
        self.nj = nj
        self.nv = 6 + nj
        self.mass = m.body_mass.numpy().astype(np.float64)
        self.body_com = m.body_com.numpy().astype(np.float64)
        self.lower = [float(lower[d]) for d in self.jd]
        self.upper = [float(upper[d]) for d in self.jd]
        self.gravity = np.array(c["gravity"], dtype=np.float64)
        self.shape_body = m.shape_body.numpy()
        self.shape_ke = s["contact_ke"]
        self.shape_kd = s["contact_kd"]
        self.contact_state = None
        self.shape_margin = 0.0

        self.state0, self.state1 = m.state(), m.state()
        self.control = m.control()
        self.pipeline = newton.CollisionPipeline(m, broad_phase=s["broad_phase"]) if c["collisions"] else None
        self.contacts = self.pipeline.contacts() if self.pipeline is not None else None
        self.wrench = np.zeros(6)
        self.time = 0.0
        self.solver = self._make_solver()
        self.observables = None
        if self.solver_name == "steel" and self.contacts is not None:
            self.observables = self.solver.observables(["contact_f"], contacts=self.contacts)
        self.last_contacts = []

    def _make_solver(self):
        S = self.newton.solvers
        s, m = self.s, self.model
        if self.solver_name == "featherstone":
            return S.SolverFeatherstone(m, angular_damping=s["angular_damping"])
        if self.solver_name == "steel":
            return S.SolverSteel(
                m,
                iterations=s["iterations"],
                enable_joint_limits=self.limits_on,
                articulation_constraint_max=s["articulation_constraint_max"],
                enable_restitution=False,
            )
        if self.solver_name == "xpbd":
            return S.SolverXPBD(m, iterations=s["iterations"], angular_damping=s["angular_damping"])
        if self.solver_name == "semi_implicit":
            return S.SolverSemiImplicit(m, angular_damping=s["angular_damping"])
        return S.SolverMuJoCo(m, use_mujoco_cpu=False, iterations=s["iterations"], integrator=s["integrator"])

    # ---- conversions (f64) ----
    def _base_R_c(self, qpos):
        R = quat_wxyz_to_R(qpos[3:7])
        return R, R @ self.body_com[self.base]

    def to_newton(self, qpos, qvel):
        np = self.np
        q = self.model.joint_q.numpy().astype(np.float64)
        qd = np.zeros(self.model.joint_dof_count)
        q[0:3] = qpos[0:3]
        w, x, y, z = qpos[3:7]
        q[3:7] = [x, y, z, w]
        R, rc = self._base_R_c(qpos)
        om_w = R @ qvel[3:6]
        qd[0:3] = qvel[0:3] + np.cross(om_w, rc)
        qd[3:6] = om_w
        for i in range(self.nj):
            q[self.jq[i]] = qpos[7 + i]
            qd[self.jd[i]] = qvel[6 + i]
        return q, qd

    def from_newton(self, state):
        np = self.np
        q = state.joint_q.numpy().astype(np.float64)
        qd = state.joint_qd.numpy().astype(np.float64)
        x, y, z, w = q[3:7]
        qpos = np.concatenate([q[0:3], [w, x, y, z], [q[a] for a in self.jq]])
        R, rc = self._base_R_c(qpos)
        om_w = qd[3:6]
        qvel = np.concatenate([qd[0:3] - np.cross(om_w, rc), R.T @ om_w, [qd[d] for d in self.jd]])
        return qpos, qvel

    def T(self, qpos):
        """Newton qd = T · (our v), base block and dof permutation."""
        np = self.np
        R, rc = self._base_R_c(qpos)
        T = np.zeros((self.model.joint_dof_count, self.nv))
        T[0:3, 0:3] = np.eye(3)
        T[0:3, 3:6] = -skew(rc) @ R
        T[3:6, 3:6] = R
        for i in range(self.nj):
            T[self.jd[i], 6 + i] = 1.0
        return T

    # ---- requests ----
    def reset(self, qpos, qvel):
        np, wp = self.np, self.wp
        q, qd = self.to_newton(qpos, qvel)
        self.state0, self.state1 = self.model.state(), self.model.state()
        self.state0.joint_q.assign(q.astype(np.float32))
        self.state0.joint_qd.assign(qd.astype(np.float32))
        self.newton.eval_fk(self.model, self.state0.joint_q, self.state0.joint_qd, self.state0)
        self.wrench = np.zeros(6)
        self.time = 0.0
        # A fresh solver: no warm start, contact matching or cached factorisation survives a reset.
        self.solver = self._make_solver()
        if self.observables is not None:
            self.observables = self.solver.observables(["contact_f"], contacts=self.contacts)
        self.contact_state = None
        if self.contacts is not None:
            self.contacts.clear()
        self.last_contacts = self._collide_and_read(forces=False)
        _ = wp

    def _collide_and_read(self, forces):
        if self.pipeline is None:
            return []
        self.pipeline.collide(self.state0, self.contacts)
        return self._read_contacts(forces)

    def _read_contacts(self, forces):
        np = self.np
        c = self.contacts
        n = int(c.rigid_contact_count.numpy()[0])
        if n == 0:
            return []
        s0 = c.rigid_contact_shape0.numpy()[:n]
        s1 = c.rigid_contact_shape1.numpy()[:n]
        p0 = c.rigid_contact_point0.numpy()[:n].astype(np.float64)
        p1 = c.rigid_contact_point1.numpy()[:n].astype(np.float64)
        nrm = c.rigid_contact_normal.numpy()[:n].astype(np.float64)
        m0 = c.rigid_contact_margin0.numpy()[:n].astype(np.float64)
        m1 = c.rigid_contact_margin1.numpy()[:n].astype(np.float64)
        if forces and self.contact_state is not None:
            body_q, body_qd = self.contact_state
        else:
            body_q = self.state0.body_q.numpy().astype(np.float64)
            body_qd = self.state0.body_qd.numpy().astype(np.float64)
        stiff = c.rigid_contact_stiffness.numpy()[:n] if c.rigid_contact_stiffness is not None else None
        damp = c.rigid_contact_damping.numpy()[:n] if c.rigid_contact_damping is not None else None
        body_com = self.body_com
        f = None
        if forces and self.observables is not None:
            f = self.observables.contact_f.numpy()[:n].astype(np.float64)
        out = []
        for k in range(n):
            b0 = int(self.shape_body[s0[k]]) if s0[k] >= 0 else -1
            b1 = int(self.shape_body[s1[k]]) if s1[k] >= 0 else -1

            def world(b, p):
                if b < 0:
                    return p
                t = body_q[b]
                R = quat_wxyz_to_R([t[6], t[3], t[4], t[5]])
                return t[0:3] + R @ p

            w0, w1 = world(b0, p0[k]), world(b1, p1[k])
            # Newton's normal points from shape 0 to shape 1; the margins are the shapes' surface offsets.
            dist = float(np.dot(nrm[k], w1 - w0) - m0[k] - m1[k])
            depth = -dist
            if f is not None:
                # Steel solves speculative contacts too: a row carrying force counts even while separated.
                fn = abs(float(np.dot(f[k][0:3], nrm[k])))
                if dist > self.s["contact_report_distance"] and fn == 0.0:
                    continue
            elif dist > self.s["contact_report_distance"]:
                continue
            if f is None:
                # Featherstone/SemiImplicit: Newton's penalty law on the state the step started from,
                # ke · penetration + kd · approach speed (per-contact ke/kd when the pipeline sets them).
                ke = float(stiff[k]) if stiff is not None and stiff[k] > 0 else self.shape_ke
                kd = float(damp[k]) if damp is not None and damp[k] > 0 else self.shape_kd

                def vel(b, w):
                    if b < 0:
                        return np.zeros(3)
                    t = body_q[b]
                    R = quat_wxyz_to_R([t[6], t[3], t[4], t[5]])
                    r = w - (t[0:3] + R @ body_com[b])
                    return body_qd[b][0:3] + np.cross(body_qd[b][3:6], r)

                vn = float(np.dot(nrm[k], vel(b1, w1) - vel(b0, w0)))
                fn = ke * max(depth, 0.0) + (kd * max(-vn, 0.0) if depth > 0 else 0.0)
            normal = nrm[k]
            name = lambda b: "ground" if b < 0 or b not in self.bodies else self.link_name(b)  # noqa: E731
            a, bb = name(b0), name(b1)
            point = 0.5 * (w0 + w1)
            if bb == "ground" and a != "ground":
                a, bb = bb, a
                normal = -normal
            out.append((a, bb, point.tolist(), normal.tolist(), fn, depth))
        return out

    def link_name(self, b):
        return self.link_names[self.bodies.index(b)]

    def step(self, taus):
        np = self.np
        qpos, _ = self.from_newton(self.state0)
        for tau in taus:
            qpos, _ = self.from_newton(self.state0)
            f = np.zeros(self.model.joint_dof_count)
            for i in range(self.nj):
                f[self.jd[i]] = tau[i]
            f[0:6] = self._base_wrench_newton(qpos)
            self.control.joint_f.assign(f.astype(np.float32))
            for _ in range(self.substeps):
                if self.pipeline is not None:
                    self.pipeline.collide(self.state0, self.contacts)
                h = self.dt / self.substeps
                # The contacts of the last sub-step are read against the state they were applied at.
                self.contact_state = (self.state0.body_q.numpy().astype(np.float64), self.state0.body_qd.numpy().astype(np.float64))
                if self.observables is not None:
                    self.solver.step(self.state0, self.state1, self.control, self.contacts, h, observables=self.observables)
                else:
                    self.solver.step(self.state0, self.state1, self.control, self.contacts, h)
                self.state0, self.state1 = self.state1, self.state0
            self.time += self.dt
            q = self.state0.joint_q.numpy()
            qd = self.state0.joint_qd.numpy()
            if not (np.isfinite(q).all() and np.isfinite(qd).all()):
                raise Diverged(f"non-finite state at t = {self.time:.6f} s")
        if self.pipeline is not None:
            self.last_contacts = self._read_contacts(forces=True)

    def _base_wrench_newton(self, qpos):
        """Our base wrench (world force at the pelvis origin, world torque) as Newton's free-joint joint_f: a
        world force at the COM and the world torque about the COM."""
        np = self.np
        _, rc = self._base_R_c(qpos)
        f = self.wrench[0:3]
        t = self.wrench[3:6] - np.cross(rc, f)
        return np.concatenate([f, t])

    def state_vec(self):
        qpos, qvel = self.from_newton(self.state0)
        return self.np.concatenate([qpos, qvel, [self.time]])

    def kinematics(self):
        np = self.np
        self.newton.eval_fk(self.model, self.state0.joint_q, self.state0.joint_qd, self.state0)
        body_q = self.state0.body_q.numpy().astype(np.float64)
        poses, com, mtot = [], np.zeros(3), 0.0
        for b in self.bodies:
            t = body_q[b]
            quat = [t[6], t[3], t[4], t[5]]
            poses.extend(list(t[0:3]) + quat)
        for b in range(self.model.body_count):
            t = body_q[b]
            R = quat_wxyz_to_R([t[6], t[3], t[4], t[5]])
            com += self.mass[b] * (t[0:3] + R @ self.body_com[b])
            mtot += self.mass[b]
        axes = []
        X_c = self.model.joint_X_c.numpy().astype(np.float64)
        child = self.model.joint_child.numpy()
        ax = self.model.joint_axis.numpy().astype(np.float64) if hasattr(self.model, "joint_axis") else None
        qd_start = self.model.joint_qd_start.numpy()
        for j in self.jidx:
            t = body_q[child[j]]
            Rb = quat_wxyz_to_R([t[6], t[3], t[4], t[5]])
            xc = X_c[j]
            Rc = quat_wxyz_to_R([xc[6], xc[3], xc[4], xc[5]])
            a = ax[qd_start[j]] if ax is not None else np.array([0.0, 0.0, 1.0])
            axes.extend(list(Rb @ Rc @ a))
        return np.concatenate([poses, com / mtot, axes])

    def mass_matrix_newton(self):
        np = self.np
        self.newton.eval_fk(self.model, self.state0.joint_q, self.state0.joint_qd, self.state0)
        H = self.newton.eval_mass_matrix(self.model, self.state0)
        n = self.model.joint_dof_count
        return H.numpy()[0][:n, :n].astype(np.float64)

    def mass_matrix(self):
        qpos, _ = self.from_newton(self.state0)
        T = self.T(qpos)
        return T.T @ self.mass_matrix_newton() @ T

    def bias(self):
        np, wp = self.np, self.wp
        n = self.model.joint_dof_count
        self.newton.eval_fk(self.model, self.state0.joint_q, self.state0.joint_qd, self.state0)
        g = wp.zeros(n, dtype=wp.float32, device="cpu")
        cf = wp.zeros(n, dtype=wp.float32, device="cpu")
        self.newton.eval_inverse_dynamics_passive(self.model, self.state0, gravity_force=g, coriolis_force=cf)
        bN = g.numpy().astype(np.float64) + cf.numpy().astype(np.float64)
        qpos, qvel = self.from_newton(self.state0)
        T = self.T(qpos)
        R, rc = self._base_R_c(qpos)
        om_w = R @ qvel[3:6]
        tdot_v = np.zeros(n)
        tdot_v[0:3] = np.cross(om_w, np.cross(om_w, rc))
        return T.T @ (bN + self.mass_matrix_newton() @ tdot_v)

    def energy(self):
        np = self.np
        qd = self.state0.joint_qd.numpy().astype(np.float64)
        ke = 0.5 * qd @ self.mass_matrix_newton() @ qd
        k = self.kinematics()
        nl = len(self.bodies)
        com = k[7 * nl : 7 * nl + 3]
        pe = -float(self.mass.sum()) * float(np.dot(self.gravity, com))
        return np.array([ke, pe])

    def acceleration(self, f):
        """One contact-free solver step from the current state under the generalized force f (ours); the state
        is restored afterwards."""
        np = self.np
        qpos, qvel = self.from_newton(self.state0)
        saved_q = self.state0.joint_q.numpy().copy()
        saved_qd = self.state0.joint_qd.numpy().copy()
        T = self.T(qpos)
        fN = np.linalg.solve(T.T, f)
        h = self.s["acceleration_probe_dt"]

        def probe(qd, force):
            probe_in, probe_out = self.model.state(), self.model.state()
            probe_in.joint_q.assign(saved_q)
            probe_in.joint_qd.assign(qd)
            self.newton.eval_fk(self.model, probe_in.joint_q, probe_in.joint_qd, probe_in)
            ctrl = self.model.control()
            ctrl.joint_f.assign(force.astype(np.float32))
            self._make_solver().step(probe_in, probe_out, ctrl, None, h)
            _, v1 = self.from_newton(probe_out)
            if not np.isfinite(v1).all():
                raise Diverged("non-finite acceleration probe")
            return v1

        # The dynamics are affine in the applied force: a(f) = a(0) + M⁻¹f. a(0) from the state itself; M⁻¹f
        # from rest without gravity, where the probe's velocity is M⁻¹f·h alone (relative f32 rounding u instead
        # of u·|v|/h, which swamps the small columns of M⁻¹ in a finite difference around a moving state).
        a0 = (probe(saved_qd, np.zeros_like(fN)) - qvel) / h
        g = self.model.gravity.numpy().copy()
        self.model.set_gravity((0.0, 0.0, 0.0))
        try:
            am = probe(np.zeros_like(saved_qd), fN) / h
        finally:
            self.model.set_gravity(tuple(float(x) for x in g[0]))
        return a0 + am


def main():
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    inp = sys.stdin.buffer
    sim = None
    import numpy as np

    while True:
        try:
            fr = read_frame(inp)
        except InputError as e:
            write_frame(out, ERROR, str(e).encode())
            return 1
        if fr is None:
            return 0
        op, payload = fr
        try:
            if op == OP_QUIT:
                write_frame(out, OK)
                return 0
            if op == OP_INIT:
                cfg = json.loads(payload.decode())
                sim = Sim(cfg)
                sim.link_names = cfg["link_names"]
                import newton
                import warp

                info = {
                    "newton": newton.__version__,
                    "warp": warp.config.version,
                    "masses": [float(sim.mass[b]) for b in sim.bodies],
                    "limits": [[lo, up] for lo, up in zip(sim.lower, sim.upper)],
                }
                write_frame(out, OK, json.dumps(info).encode())
                continue
            if sim is None:
                raise InputError("no INIT before the first request")
            x = np.frombuffer(payload, dtype="<f8")
            if op == OP_RESET:
                nq = 7 + sim.nj
                if len(x) != nq + sim.nv:
                    raise InputError(f"reset needs {nq + sim.nv} values, got {len(x)}")
                sim.reset(x[:nq], x[nq:])
                write_frame(out, OK, f64s(sim.state_vec()) + contacts_bytes(sim.last_contacts))
            elif op == OP_STEP:
                if len(x) == 0 or len(x) % sim.nj != 0:
                    raise InputError(f"step needs a multiple of {sim.nj} torques, got {len(x)}")
                sim.step(x.reshape(-1, sim.nj))
                write_frame(out, OK, f64s(sim.state_vec()) + contacts_bytes(sim.last_contacts))
            elif op == OP_STATE:
                write_frame(out, OK, f64s(sim.state_vec()))
            elif op == OP_CONTACTS:
                write_frame(out, OK, contacts_bytes(sim.last_contacts))
            elif op == OP_ENERGY:
                write_frame(out, OK, f64s(sim.energy()))
            elif op == OP_KINEMATICS:
                write_frame(out, OK, f64s(sim.kinematics()))
            elif op == OP_MASS_MATRIX:
                write_frame(out, OK, f64s(sim.mass_matrix().reshape(-1)))
            elif op == OP_BIAS:
                write_frame(out, OK, f64s(sim.bias()))
            elif op == OP_ACCEL:
                if len(x) != sim.nv:
                    raise InputError(f"acceleration needs {sim.nv} forces, got {len(x)}")
                write_frame(out, OK, f64s(sim.acceleration(x)))
            elif op == OP_WRENCH:
                if len(x) != 6:
                    raise InputError("wrench needs 6 values")
                sim.wrench = x.astype(np.float64).copy()
                write_frame(out, OK)
            else:
                raise InputError(f"unknown opcode {op}")
        except Diverged as e:
            write_frame(out, DIVERGED, str(e).encode())
        except Exception as e:  # noqa: BLE001 - every failure goes back as a typed error frame
            traceback.print_exc(file=sys.stderr)
            write_frame(out, ERROR, f"{type(e).__name__}: {e}".encode())


def contacts_bytes(cs):
    """u32 count, then per contact: two length-prefixed UTF-8 names and 8 f64 (point, normal, force, depth)."""
    out = [struct.pack("<I", len(cs))]
    for a, b, p, n, f, d in cs:
        for s in (a, b):
            e = s.encode()
            out.append(struct.pack("<I", len(e)) + e)
        out.append(struct.pack("<8d", *p, *n, f, d))
    return b"".join(out)


if __name__ == "__main__":
    sys.exit(main())
