"""A high-level locomotion client written with Unitree's official Python SDK's own RPC client machinery
(unitree_sdk2py.rpc.client.Client, the class every LocoClient of the SDK subclasses), used to drive a
simulator's locomotion service the way a user's program would.

The unitree_sdk2 1.0.1 wheel ships only the Go2 clients, so the H1 client is declared here exactly as
Unitree's C++ header declares it (include/unitree/robot/h1/loco/h1_loco_api.hpp and h1_loco_client.hpp of
unitreerobotics/unitree_sdk2, commit 21d0a3b2c46ee48c8fdf2783becb6be3beb0a59b): service "loco", API version
"2.0.0.0", ROBOT_API_ID_LOCO_* ids, JSON parameters {"data": n} and {"velocity": [vx, vy, omega],
"duration": d}, Move(continous_move=True) = a duration of 864000 s, StopMove() = SetVelocity(0, 0, 0).

  python sdk_loco_client.py --domain D [--speed 0.5] [--yaw-rate 0.5]

Walks forward, turns on the spot and stops, reading the robot's odometry (GetOdom) at the start and end of a
measured window of each phase and the LowState tick (the robot's clock, ms) with it. Every phase lasts a span
of SIMULATED time (ticks), never of wall time; every wait is bounded by a generous wall-clock limit that only
turns a stalled peer into an error. Prints one JSON object; exit code 0 unless the SDK itself failed.
"""
import argparse
import json
import sys

from sdk_common import LOCO_API_VERSION, LOCO_SERVICE_NAME, RetryingClient, RobotClock
from unitree_sdk2py.core.channel import ChannelFactoryInitialize

# h1_loco_api.hpp
ROBOT_API_ID_LOCO_GET_FSM_ID = 8001
ROBOT_API_ID_LOCO_GET_FSM_MODE = 8002
ROBOT_API_ID_LOCO_GET_BALANCE_MODE = 8003
ROBOT_API_ID_LOCO_SET_FSM_ID = 8101
ROBOT_API_ID_LOCO_SET_BALANCE_MODE = 8102
ROBOT_API_ID_LOCO_SET_STAND_HEIGHT = 8104
ROBOT_API_ID_LOCO_SET_VELOCITY = 8105
ROBOT_API_ID_LOCO_ENABLE_ODOM = 8201
ROBOT_API_ID_LOCO_DISABLE_ODOM = 8202
ROBOT_API_ID_LOCO_GET_ODOM = 8203
WALL_LIMIT = 240.0


class H1LocoClient(RetryingClient):
    """unitree::robot::h1::LocoClient, on the SDK's Python RPC client (sending a call again after a lost response)."""

    def __init__(self):
        super().__init__(LOCO_SERVICE_NAME, [])

    def Init(self):
        self._SetApiVerson(LOCO_API_VERSION)
        for api in (ROBOT_API_ID_LOCO_GET_FSM_ID, ROBOT_API_ID_LOCO_GET_FSM_MODE, ROBOT_API_ID_LOCO_GET_BALANCE_MODE,
                    ROBOT_API_ID_LOCO_SET_FSM_ID, ROBOT_API_ID_LOCO_SET_BALANCE_MODE,
                    ROBOT_API_ID_LOCO_SET_STAND_HEIGHT, ROBOT_API_ID_LOCO_SET_VELOCITY,
                    ROBOT_API_ID_LOCO_ENABLE_ODOM, ROBOT_API_ID_LOCO_DISABLE_ODOM, ROBOT_API_ID_LOCO_GET_ODOM):
            self._RegistApi(api, 0)

    def _get(self, api):
        code, data = self._Call(api, "")
        return code, (json.loads(data) if code == 0 and data else None)

    def GetFsmId(self):
        code, data = self._get(ROBOT_API_ID_LOCO_GET_FSM_ID)
        return code, (data or {}).get("data")

    def GetFsmMode(self):
        code, data = self._get(ROBOT_API_ID_LOCO_GET_FSM_MODE)
        return code, (data or {}).get("data")

    def GetOdom(self):
        code, data = self._get(ROBOT_API_ID_LOCO_GET_ODOM)
        return code, (None if data is None else [data["x"], data["y"], data["z"]])

    def SetFsmId(self, fsm_id):
        return self._Call(ROBOT_API_ID_LOCO_SET_FSM_ID, json.dumps({"data": fsm_id}))[0]

    def SetStandHeight(self, height):
        return self._Call(ROBOT_API_ID_LOCO_SET_STAND_HEIGHT, json.dumps({"data": height}))[0]

    def SetVelocity(self, vx, vy, omega, duration=1.0):
        return self._Call(ROBOT_API_ID_LOCO_SET_VELOCITY,
                          json.dumps({"velocity": [vx, vy, omega], "duration": duration}))[0]

    def EnableOdom(self):
        return self._Call(ROBOT_API_ID_LOCO_ENABLE_ODOM, "")[0]

    def Damp(self):
        return self.SetFsmId(1)

    def Start(self):
        return self.SetFsmId(204)

    def StandUp(self):
        return self.SetFsmId(2)

    def StopMove(self):
        return self.SetVelocity(0.0, 0.0, 0.0)

    def Move(self, vx, vy, vyaw, continous_move=False):
        return self.SetVelocity(vx, vy, vyaw, 864000.0 if continous_move else 1.0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--speed", type=float, default=0.5)
    ap.add_argument("--yaw-rate", type=float, default=0.5)
    args = ap.parse_args()
    if args.domain == 0:
        sys.exit("refusing domain 0")
    ChannelFactoryInitialize(args.domain, "lo")
    clock = RobotClock(WALL_LIMIT)
    client = H1LocoClient()
    client.SetTimeout(10.0)
    client.Init()
    out = {"codes": {}}
    try:
        clock.wait(0.1)
        code, version = client.GetServerApiVersion()
        out["api_version"] = [code, version]
        out["codes"]["fsm_initial"] = client.GetFsmId()
        out["codes"]["move_before_start"] = client.Move(args.speed, 0.0, 0.0, True)
        out["codes"]["enable_odom"] = client.EnableOdom()
        out["codes"]["start"] = client.Start()
        out["codes"]["fsm_walking"] = client.GetFsmId()
        clock.wait(1.0)

        def window(name, command, settle, measure):
            out["codes"][name] = command()
            clock.wait(settle)
            a = (client.GetOdom(), clock.now())
            clock.wait(measure)
            b = (client.GetOdom(), clock.now())
            out[name] = {"odom": [a[0][1], b[0][1]], "codes": [a[0][0], b[0][0]], "ticks": [a[1], b[1]]}

        window("forward", lambda: client.Move(args.speed, 0.0, 0.0, True), 2.0, 3.0)
        out["codes"]["fsm_mode_moving"] = client.GetFsmMode()
        window("turn", lambda: client.Move(0.0, 0.0, args.yaw_rate, True), 2.0, 3.0)
        window("stop", client.StopMove, 2.0, 2.0)
        out["codes"]["stand_height"] = client.SetStandHeight(1.0)
        out["codes"]["damp"] = client.Damp()
        out["codes"]["fsm_damped"] = client.GetFsmId()
        out["codes"]["invalid_fsm"] = client.SetFsmId(7)
    except Exception as e:  # noqa: BLE001 (reported, the test decides)
        out["error"] = repr(e)
    out["retried_apis"] = client.retries
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
