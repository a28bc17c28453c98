"""Unit tests of newton_server.py: framing, the contact encoding, the base-velocity conversions and one
INIT/RESET/STEP round trip through a real server process (skipped when Newton is not installed).
Run: `.venv-newton/bin/python -m unittest crates/diff-physics/python/test_newton_server.py`."""
import importlib.util
import io
import json
import math
import os
import struct
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import newton_server as ns  # noqa: E402

HAVE_NEWTON = importlib.util.find_spec("newton") is not None and importlib.util.find_spec("numpy") is not None


class Framing(unittest.TestCase):
    def test_frames_round_trip_and_end_of_stream_is_none(self):
        buf = io.BytesIO()
        ns.write_frame(buf, ns.OK, b"abc")
        ns.write_frame(buf, ns.ERROR, b"")
        buf.seek(0)
        self.assertEqual(ns.read_frame(buf), (ns.OK, b"abc"))
        self.assertEqual(ns.read_frame(buf), (ns.ERROR, b""))
        self.assertIsNone(ns.read_frame(buf))

    def test_truncated_frame_is_none_and_empty_frame_is_an_error(self):
        self.assertIsNone(ns.read_frame(io.BytesIO(struct.pack("<I", 10) + b"\x01ab")))
        with self.assertRaises(ns.InputError):
            ns.read_frame(io.BytesIO(struct.pack("<I", 0)))

    def test_contacts_encoding(self):
        b = ns.contacts_bytes([("ground", "foot", [1, 2, 3], [0, 0, 1], 5.0, 0.001)])
        (n,) = struct.unpack_from("<I", b)
        self.assertEqual(n, 1)
        (la,) = struct.unpack_from("<I", b, 4)
        self.assertEqual(b[8 : 8 + la], b"ground")
        off = 8 + la
        (lb,) = struct.unpack_from("<I", b, off)
        self.assertEqual(b[off + 4 : off + 4 + lb], b"foot")
        vals = struct.unpack_from("<8d", b, off + 4 + lb)
        self.assertEqual(vals, (1, 2, 3, 0, 0, 1, 5.0, 0.001))
        self.assertEqual(len(b), off + 4 + lb + 64)

    def test_rotation_matrix_is_orthonormal_with_the_wxyz_convention(self):
        c, s = math.cos(0.3), math.sin(0.3)
        R = ns.quat_wxyz_to_R([c, 0.0, 0.0, s])  # 0.6 rad about z
        self.assertAlmostEqual(R[0][0], math.cos(0.6))
        self.assertAlmostEqual(R[1][0], math.sin(0.6))
        self.assertAlmostEqual(R[2][2], 1.0)


@unittest.skipUnless(HAVE_NEWTON, "Newton not installed (scripts/setup.sh --newton)")
class Server(unittest.TestCase):
    MJCF = """<mujoco model="m"><worldbody><body name="base" pos="0 0 1">
      <inertial pos="0.1 0 0" mass="2" diaginertia="0.1 0.2 0.3"/><freejoint name="root"/>
      <body name="arm" pos="0 0 0.2"><inertial pos="0 0 0.1" mass="1" diaginertia="0.01 0.01 0.01"/>
        <joint name="j" type="hinge" axis="0 1 0"/></body></body></worldbody></mujoco>"""

    def request(self, p, op, payload=b""):
        p.stdin.write(struct.pack("<IB", len(payload) + 1, op) + payload)
        p.stdin.flush()
        (n,) = struct.unpack("<I", p.stdout.read(4))
        body = p.stdout.read(n)
        return body[0], body[1:]

    def test_reset_state_round_trips_and_free_fall_matches_gravity(self):
        import numpy as np

        here = os.path.dirname(os.path.abspath(__file__))
        p = subprocess.Popen(
            [sys.executable, os.path.join(here, "newton_server.py")],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
        )
        try:
            settings = dict(solver="featherstone", substeps=1, contact_ke=1e5, contact_kd=1e3, contact_kf=1e3,
                            limit_ke=1e4, limit_kd=10.0, angular_damping=0.0, iterations=12,
                            articulation_constraint_max=64, integrator="implicitfast", broad_phase="explicit",
                            contact_report_distance=0.0, acceleration_probe_dt=1e-4)
            common = dict(timestep=0.002, gravity=[0.0, 0.0, -9.81], ground=False, collisions=False, armature=False,
                          joint_damping=False, joint_friction=False, joint_limits=False)
            cfg = dict(mjcf=self.MJCF, settings=settings, common=common, joint_names=["j"],
                       link_names=["base", "arm"], friction=1.0, self_collision=False)
            st, body = self.request(p, ns.OP_INIT, json.dumps(cfg).encode())
            self.assertEqual(st, ns.OK, body)
            self.assertEqual(json.loads(body)["masses"], [2.0, 1.0])
            # A rotating base: the origin velocity and body-frame rate must come back through Newton's
            # COM velocity / world rate (f32 state: 1e-6).
            qpos = [0, 0, 1, math.cos(0.2), 0, math.sin(0.2), 0, 0.3]
            qvel = [0.1, -0.2, 0.3, 0.5, -0.4, 0.7, 1.0]
            st, body = self.request(p, ns.OP_RESET, np.array(qpos + qvel, "<f8").tobytes())
            self.assertEqual(st, ns.OK, body)
            x = np.frombuffer(body[: 8 * 16], "<f8")
            self.assertLess(np.abs(x[:8] - qpos).max(), 1e-6)
            self.assertLess(np.abs(x[8:15] - qvel).max(), 1e-6)
            # Free fall of the whole body: the COM drops by g t²/2 whatever the rotation; check the vertical
            # origin velocity of a non-rotating start instead (exact for semi-implicit Euler: v = -g t).
            still = [0, 0, 1, 1, 0, 0, 0, 0.0] + [0.0] * 7
            self.request(p, ns.OP_RESET, np.array(still, "<f8").tobytes())
            st, body = self.request(p, ns.OP_STEP, np.zeros(10, "<f8").tobytes())
            self.assertEqual(st, ns.OK, body)
            x = np.frombuffer(body[: 8 * 16], "<f8")
            self.assertAlmostEqual(x[10], -9.81 * 0.02, places=4)
            self.assertAlmostEqual(x[15], 0.02, places=9)
            # Wrong sizes come back as error frames; the server keeps serving.
            st, body = self.request(p, ns.OP_STEP, np.zeros(3, "<f8").tobytes()[:20])
            self.assertEqual(st, ns.ERROR)
            st, _ = self.request(p, ns.OP_QUIT)
            self.assertEqual(st, ns.OK)
        finally:
            p.kill()
            p.wait()
            p.stdin.close()
            p.stdout.close()


if __name__ == "__main__":
    unittest.main()
