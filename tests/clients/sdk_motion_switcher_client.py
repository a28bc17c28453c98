"""A motion-switcher client written with Unitree's official Python SDK's own RPC client machinery
(unitree_sdk2py.rpc.client.Client, the class every client of the SDK subclasses), calling a simulator's motion
switcher the way Unitree's low-level examples do before they take the motors.

The unitree_sdk2 1.0.1 wheel does not ship the motion-switcher client, so it is declared here as Unitree declares it
(include/unitree/robot/b2/motion_switcher/motion_switcher_api.hpp of unitreerobotics/unitree_sdk2, and
unitree_sdk2py/comm/motion_switcher/motion_switcher_api.py of unitree_sdk2_python): service "motion_switcher", API
version "1.0.0.1", ids 1001 CheckMode, 1002 SelectMode {"name": n}, 1003 ReleaseMode, 1004 SetSilent
{"silent": b}, 1005 GetSilent. The H1 locomotion API (h1_loco_api.hpp: service "loco", 8001 GetFsmId) tells
which state the robot's locomotion service is in.

  python sdk_motion_switcher_client.py --domain D [--absent]

Waits until both services answer (discovery), then checks the mode, releases it, checks again, watches the robot for a span of SIMULATED time (LowState ticks) while
reading its pelvis height from rt/sportmodestate, sets and reads the silent flag, selects the mode again and calls
an id the service does not have. Every wait is bounded by a generous wall-clock limit that only turns a stalled
peer into an error. With --absent it only checks that the locomotion service answers and the motion switcher does
not. Prints one JSON object; exit code 0 unless the SDK itself failed.
"""
import argparse
import json
import sys

from sdk_common import LOCO_API_VERSION, LOCO_SERVICE_NAME, RetryingClient, RobotClock
from unitree_sdk2py.core.channel import ChannelFactoryInitialize, ChannelSubscriber
from unitree_sdk2py.idl.unitree_go.msg.dds_ import SportModeState_

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
ROBOT_API_ID_LOCO_GET_FSM_ID = 8001
WALL_LIMIT = 120.0
# Seconds the SDK client waits for a response: the simulator answers within a physics step (2 ms of its loop), so
# this only has to outlast a loaded machine's scheduling stalls.
CALL_TIMEOUT = 5.0
# With --absent: seconds the SDK waits for a reader of the request topic before it gives up sending (3102,
# RPC_ERR_CLIENT_SEND), and then for a response (3104). The simulator's locomotion service is already discovered by
# then, so a motion switcher on the same participant would be matched within milliseconds.
ABSENT_CALL_TIMEOUT = 2.0


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


class Robot(RobotClock):
    """The robot's clock and its pelvis height (rt/sportmodestate, the simulator's ground truth); a wait starts once
    a height has been seen."""

    def __init__(self):
        super().__init__(WALL_LIMIT)
        self.height = None
        self.sport = ChannelSubscriber("rt/sportmodestate", SportModeState_)
        self.sport.Init(self.on_sport, 10)

    def on_sport(self, msg):
        with self.lock:
            self.height = float(msg.position[2])

    def pelvis_height(self):
        with self.lock:
            return self.height

    def ready(self):
        return self.pelvis_height() is not None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--released-seconds", type=float, default=3.0)
    ap.add_argument("--absent", action="store_true",
                    help="only check that no motion switcher answers while the locomotion service does")
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
        if args.absent:
            # The locomotion service answering is the positive control: the simulator's participant is discovered
            # and serves RPC, so a CheckMode that finds no reader of its request topic has no server.
            out["loco_api_version"] = loco.WaitServer(WALL_LIMIT)
            msc.SetTimeout(ABSENT_CALL_TIMEOUT)
            out["check_absent"] = msc.CheckMode()
            out["retried_apis"] = retries
            print(json.dumps(out), flush=True)
            return
        out["api_version"] = msc.WaitServer(WALL_LIMIT)
        out["loco_api_version"] = loco.WaitServer(WALL_LIMIT)
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
