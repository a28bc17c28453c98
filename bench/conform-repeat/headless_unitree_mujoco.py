"""Runs Unitree's Python MuJoCo bridge (`simulate_python/unitree_mujoco.py` of unitreerobotics/unitree_mujoco, from a
local clone given by --repo and never copied into this project) headless, as a peer for `ulab conform`.

Their code runs as it is. This file supplies only what a headless run without a gamepad lacks: the `config` module
their script imports (robot, scene, domain, interface; their own values otherwise), a passive viewer that never opens a
window and reports "running" for --seconds, an empty `pygame` when it is not installed (imported, unused without a
gamepad), and the `unitree_sdk2py.b2` package the SDK wheel imports but does not ship.

  python headless_unitree_mujoco.py --repo DIR --domain D [--interface lo] [--seconds 120]
"""
import argparse
import importlib.util
import os
import runpy
import sys
import time
import types


class HeadlessViewer:
    """What their script uses of `mujoco.viewer.launch_passive`'s handle."""

    def __init__(self, seconds):
        self.until = time.monotonic() + seconds

    def is_running(self):
        return time.monotonic() < self.until

    def sync(self):
        pass


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repo", required=True, help="a local clone of unitreerobotics/unitree_mujoco")
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--interface", default="lo")
    ap.add_argument("--seconds", type=float, default=120.0)
    ap.add_argument("--scene", help="default: the clone's unitree_robots/h1_2/scene.xml")
    a = ap.parse_args()
    sim = os.path.join(os.path.abspath(a.repo), "simulate_python")
    scene = a.scene or os.path.join(os.path.abspath(a.repo), "unitree_robots", "h1_2", "scene.xml")
    if not os.path.isfile(os.path.join(sim, "unitree_mujoco.py")) or not os.path.isfile(scene):
        sys.exit(f"headless_unitree_mujoco: {a.repo} has no simulate_python/unitree_mujoco.py or no {scene}")

    config = types.ModuleType("config")
    # The bridge picks the unitree_hg messages (the H1-2's) only for ROBOT == "g1"; the robot itself is the scene's.
    config.ROBOT = "g1"
    config.ROBOT_SCENE = scene
    config.DOMAIN_ID = a.domain
    config.INTERFACE = a.interface
    config.USE_JOYSTICK = 0
    config.JOYSTICK_TYPE = "xbox"
    config.JOYSTICK_DEVICE = 0
    config.PRINT_SCENE_INFORMATION = False
    config.ENABLE_ELASTIC_BAND = False
    config.SIMULATE_DT = 0.005
    config.VIEWER_DT = 0.02
    sys.modules["config"] = config
    sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))
    if importlib.util.find_spec("pygame") is None:
        sys.modules["pygame"] = types.ModuleType("pygame")

    import mujoco.viewer

    mujoco.viewer.launch_passive = lambda *args, **kwargs: HeadlessViewer(a.seconds)
    sys.path.insert(0, sim)
    os.chdir(sim)
    runpy.run_path(os.path.join(sim, "unitree_mujoco.py"), run_name="__main__")


if __name__ == "__main__":
    main()
