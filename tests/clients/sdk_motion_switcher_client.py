"""A motion-switcher client written with Unitree's official Python SDK's own RPC client machinery
(unitree_sdk2py.rpc.client.Client, the class every client of the SDK subclasses), calling a simulator's motion
switcher the way Unitree's low-level examples do before they take the motors.

The unitree_sdk2 1.0.1 wheel does not ship the motion-switcher client, so it is declared here as Unitree declares it
(include/unitree/robot/b2/motion_switcher/motion_switcher_api.hpp of unitreerobotics/unitree_sdk2, and
unitree_sdk2py/comm/motion_switcher/motion_switcher_api.py of unitree_sdk2_python): service "motion_switcher", API
version "1.0.0.1", ids 1001 CheckMode, 1002 SelectMode {"name": n}, 1003 ReleaseMode, 1004 SetSilent
{"silent": b}, 1005 GetSilent. The H1 locomotion API (h1_loco_api.hpp: service "loco", 8001 GetFsmId) tells
which state the robot's locomotion service is in.

  python sdk_motion_switcher_client.py --domain D

Waits until both services answer (discovery), then checks the mode, releases it, checks again, watches the robot for a span of SIMULATED time (LowState ticks) while
reading its pelvis height from rt/sportmodestate, sets and reads the silent flag, selects the mode again and calls
an id the service does not have. Every wait is bounded by a generous wall-clock limit that only turns a stalled
peer into an error. Prints one JSON object; exit code 0 unless the SDK itself failed.
"""
import argparse
import json
import sys
import threading
import time
import types

# The unitree_sdk2 1.0.1 wheel imports a `b2` subpackage it does not ship.
sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))

from unitree_sdk2py.core.channel import ChannelFactoryInitialize, ChannelSubscriber  # noqa: E402
from unitree_sdk2py.idl.unitree_go.msg.dds_ import SportModeState_  # noqa: E402
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowState_  # noqa: E402
from unitree_sdk2py.rpc.client import Client  # noqa: E402

# motion_switcher_api.hpp
MOTION_SWITCHER_SERVICE_NAME = "motion_switcher"
MOTION_SWITCHER_API_VERSION = "1.0.0.1"
MOTION_SWITCHER_API_ID_CHECK_MODE = 1001
MOTION_SWITCHER_API_ID_SELECT_MODE = 1002
MOTION_SWITCHER_API_ID_RELEASE_MODE = 1003
MOTION_SWITCHER_API_ID_SET_SILENT = 1004
MOTION_SWITCHER_API_ID_GET_SILENT = 1005
# Not an id of the service: registered on the client so that the request goes out.
UNKNOWN_API_ID = 1006
# h1_loco_api.hpp
LOCO_SERVICE_NAME = "loco"
LOCO_API_VERSION = "2.0.0.0"
ROBOT_API_ID_LOCO_GET_FSM_ID = 8001
WALL_LIMIT = 120.0
# Sends of one call at most (one plus retries after a lost response).
ATTEMPTS = 4
# Seconds the SDK client waits for a response: the simulator answers within a physics step (2 ms of its loop), so
# this only has to outlast a loaded machine's scheduling stalls.
CALL_TIMEOUT = 5.0
# unitree_sdk2py/rpc/internal.py: the client's own timeout waiting for a response.
RPC_ERR_CLIENT_API_TIMEOUT = 3104


class RetryingClient(Client):
    """The SDK's client, sending a call again (at most ATTEMPTS times in all) when no response came in time. The SDK
    reads responses with Cyclone's default reader QoS, best-effort, so a response dropped by a busy loopback socket
    (LowState arrives at 500 Hz beside it; on a loaded machine several in a run) is never resent; a program using the
    SDK retries. Every retry is reported. (Every call made here is idempotent: a repeated release, select or set
    changes nothing more.)"""

    def __init__(self, service, retries):
        super().__init__(service, False)
        self.retries = retries

    def _Call(self, api, parameter):
        code, data = super()._Call(api, parameter)
        for _ in range(ATTEMPTS - 1):
            if code != RPC_ERR_CLIENT_API_TIMEOUT:
                break
            self.retries.append(api)
            code, data = super()._Call(api, parameter)
        return code, data

    def WaitServer(self):
        """Asks the server's API version until it answers (DDS discovery done both ways), within WALL_LIMIT;
        returns [code, version, attempts]."""
        start = time.time()
        attempts = 0
        while True:
            attempts += 1
            code, version = self.GetServerApiVersion()
            if code == 0 or time.time() - start > WALL_LIMIT:
                return [code, version, attempts]


class MotionSwitcherClient(RetryingClient):
    """unitree::robot::b2::MotionSwitcherClient, on the SDK's Python RPC client."""

    def __init__(self, retries):
        super().__init__(MOTION_SWITCHER_SERVICE_NAME, retries)

    def Init(self):
        self._SetApiVerson(MOTION_SWITCHER_API_VERSION)
        for api in (MOTION_SWITCHER_API_ID_CHECK_MODE, MOTION_SWITCHER_API_ID_SELECT_MODE,
                    MOTION_SWITCHER_API_ID_RELEASE_MODE, MOTION_SWITCHER_API_ID_SET_SILENT,
                    MOTION_SWITCHER_API_ID_GET_SILENT, UNKNOWN_API_ID):
            self._RegistApi(api, 0)

    def CheckMode(self):
        code, data = self._Call(MOTION_SWITCHER_API_ID_CHECK_MODE, json.dumps({}))
        return [code, json.loads(data) if code == 0 else None]

    def SelectMode(self, name):
        return self._Call(MOTION_SWITCHER_API_ID_SELECT_MODE, json.dumps({"name": name}))[0]

    def ReleaseMode(self):
        return self._Call(MOTION_SWITCHER_API_ID_RELEASE_MODE, json.dumps({}))[0]

    def SetSilent(self, flag):
        return self._Call(MOTION_SWITCHER_API_ID_SET_SILENT, json.dumps({"silent": flag}))[0]

    def GetSilent(self):
        code, data = self._Call(MOTION_SWITCHER_API_ID_GET_SILENT, json.dumps({}))
        return [code, json.loads(data) if code == 0 else None]

    def Unknown(self):
        return self._Call(UNKNOWN_API_ID, json.dumps({}))[0]


class LocoClient(RetryingClient):
    """The H1 LocoClient's GetFsmId."""

    def __init__(self, retries):
        super().__init__(LOCO_SERVICE_NAME, retries)

    def Init(self):
        self._SetApiVerson(LOCO_API_VERSION)
        self._RegistApi(ROBOT_API_ID_LOCO_GET_FSM_ID, 0)

    def GetFsmId(self):
        code, data = self._Call(ROBOT_API_ID_LOCO_GET_FSM_ID, "")
        return [code, json.loads(data)["data"] if code == 0 and data else None]


class Robot:
    """The robot's clock (the latest LowState tick, ms of simulated time) and its pelvis height (rt/sportmodestate,
    the simulator's ground truth)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.tick = None
        self.height = None
        self.low = ChannelSubscriber("rt/lowstate", LowState_)
        self.low.Init(self.on_state, 10)
        self.sport = ChannelSubscriber("rt/sportmodestate", SportModeState_)
        self.sport.Init(self.on_sport, 10)

    def on_state(self, msg):
        with self.lock:
            self.tick = msg.tick

    def on_sport(self, msg):
        with self.lock:
            self.height = float(msg.position[2])

    def now(self):
        with self.lock:
            return self.tick

    def pelvis_height(self):
        with self.lock:
            return self.height

    def wait(self, seconds):
        """Waits `seconds` of simulated time, until a pelvis height has been seen too."""
        start_wall = time.time()
        start = self.now()
        while start is None or self.pelvis_height() is None:
            if time.time() - start_wall > WALL_LIMIT:
                raise RuntimeError("no LowState or SportModeState from the robot")
            time.sleep(0.01)
            start = self.now()
        while (self.now() - start) < seconds * 1000.0:
            if time.time() - start_wall > WALL_LIMIT:
                raise RuntimeError(f"the robot's clock stalled at {self.now()} ms")
            time.sleep(0.005)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--released-seconds", type=float, default=3.0)
    args = ap.parse_args()
    if args.domain == 0:
        sys.exit("refusing domain 0")
    ChannelFactoryInitialize(args.domain, "lo")
    robot = Robot()
    retries = []
    msc = MotionSwitcherClient(retries)
    msc.SetTimeout(CALL_TIMEOUT)
    msc.Init()
    loco = LocoClient(retries)
    loco.SetTimeout(CALL_TIMEOUT)
    loco.Init()
    out = {}
    try:
        robot.wait(0.2)
        out["api_version"] = msc.WaitServer()
        out["loco_api_version"] = loco.WaitServer()
        out["check_initial"] = msc.CheckMode()
        out["fsm_initial"] = loco.GetFsmId()
        out["height_initial"] = robot.pelvis_height()
        out["release"] = msc.ReleaseMode()
        out["check_released"] = msc.CheckMode()
        out["fsm_released"] = loco.GetFsmId()
        robot.wait(args.released_seconds)
        out["height_released"] = robot.pelvis_height()
        out["silent_initial"] = msc.GetSilent()
        out["set_silent_true"] = msc.SetSilent(True)
        out["silent_true"] = msc.GetSilent()
        out["set_silent_false"] = msc.SetSilent(False)
        out["silent_false"] = msc.GetSilent()
        out["select_unsupported"] = msc.SelectMode("normal")
        out["check_after_unsupported"] = msc.CheckMode()
        out["select"] = msc.SelectMode("ai")
        out["check_selected"] = msc.CheckMode()
        out["fsm_selected"] = loco.GetFsmId()
        out["unknown"] = msc.Unknown()
    except Exception as e:  # noqa: BLE001 (reported, the test decides)
        out["error"] = repr(e)
    out["retried_apis"] = retries
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
