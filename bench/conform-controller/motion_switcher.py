"""The robot's motion-switcher service, as far as Unitree's low-level examples use it, for runs against
`ulab conform controller` (which plays LowState/LowCmd only).

Unitree's H1-2 Python low-level example asks the motion switcher which motion service holds the motors (CheckMode)
and releases it until none does, before it publishes a command. Without an answer its CheckMode returns no data
and the example stops with a TypeError before its first command. This service answers as a robot whose motion
services are already released: CheckMode gives an empty name, ReleaseMode succeeds.

`ulab sim` answers the motion switcher itself (`sim_bridge::motion_switcher`: CheckMode names its locomotion
service "ai", ReleaseMode damps the robot); this stand-in is still needed beside `ulab conform controller`, whose
judge plays LowState/LowCmd only and serves no RPC.

  PYTHONPATH=$UNITREE_SDK2_PYTHON_DIR python motion_switcher.py [DOMAIN [INTERFACE]]   (defaults: 0 lo)

Uses the SDK's own RPC server classes from the copy on PYTHONPATH; runs until killed.
"""
import json
import sys
import time

from unitree_sdk2py.comm.motion_switcher.motion_switcher_api import (
    MOTION_SWITCHER_API_ID_CHECK_MODE,
    MOTION_SWITCHER_API_ID_GET_SILENT,
    MOTION_SWITCHER_API_ID_RELEASE_MODE,
    MOTION_SWITCHER_API_ID_SELECT_MODE,
    MOTION_SWITCHER_API_ID_SET_SILENT,
    MOTION_SWITCHER_API_VERSION,
    MOTION_SWITCHER_SERVICE_NAME,
)
from unitree_sdk2py.core.channel import ChannelFactoryInitialize
from unitree_sdk2py.rpc.server import Server


class ReleasedMotionSwitcher(Server):
    """Every motion service released: nothing competes with the controller for the motors."""

    def __init__(self):
        super().__init__(MOTION_SWITCHER_SERVICE_NAME)
        self.calls = {}

    def Init(self):
        self._SetApiVersion(MOTION_SWITCHER_API_VERSION)
        for api, reply in [
            (MOTION_SWITCHER_API_ID_CHECK_MODE, {"form": "0", "name": ""}),
            (MOTION_SWITCHER_API_ID_SELECT_MODE, {}),
            (MOTION_SWITCHER_API_ID_RELEASE_MODE, {}),
            (MOTION_SWITCHER_API_ID_SET_SILENT, {}),
            (MOTION_SWITCHER_API_ID_GET_SILENT, {"silent": False}),
        ]:
            self._RegistHandler(api, self._answer(api, json.dumps(reply)), False)

    def _answer(self, api, data):
        def handler(_parameter):
            self.calls[api] = self.calls.get(api, 0) + 1
            print(f"motion_switcher: api {api} answered", file=sys.stderr, flush=True)
            return 0, data

        return handler


def main():
    domain = int(sys.argv[1]) if len(sys.argv) > 1 else 0
    interface = sys.argv[2] if len(sys.argv) > 2 else "lo"
    ChannelFactoryInitialize(domain, interface)
    server = ReleasedMotionSwitcher()
    server.Init()
    server.Start(False)
    print(f"motion_switcher: serving on domain {domain} / {interface}", file=sys.stderr, flush=True)
    while True:
        time.sleep(1)


if __name__ == "__main__":
    main()
