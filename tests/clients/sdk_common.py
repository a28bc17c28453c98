"""What the test clients written on Unitree's official Python SDK share: the import the unitree_sdk2 1.0.1 wheel
needs, the SDK's RPC client sending a call again when its response was lost, the H1 locomotion service's name and
version, and the robot's clock (the LowState tick, ms of simulated time).

Imported by the client scripts beside it (`python tests/clients/<client>.py` puts this folder on sys.path).
"""
import sys
import threading
import time
import types

# The unitree_sdk2 1.0.1 wheel imports a `b2` subpackage it does not ship.
sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))

from unitree_sdk2py.core.channel import ChannelSubscriber  # noqa: E402
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowState_  # noqa: E402
from unitree_sdk2py.rpc.client import Client  # noqa: E402

# h1_loco_api.hpp of unitreerobotics/unitree_sdk2
LOCO_SERVICE_NAME = "loco"
LOCO_API_VERSION = "2.0.0.0"
# unitree_sdk2py/rpc/internal.py: the client's own timeout waiting for a response.
RPC_ERR_CLIENT_API_TIMEOUT = 3104
# Sends of one call at most (one plus retries after a lost response).
ATTEMPTS = 4


class RetryingClient(Client):
    """The SDK's client, sending a call again (at most ATTEMPTS times in all) when no response came in time. The SDK
    reads responses with Cyclone's default reader QoS, best-effort, so a response dropped by a busy loopback socket
    (LowState arrives at 500 Hz beside it; on a loaded machine several in a run) is never resent; a program using the
    SDK retries. Every retry is appended to `retries` (the API id), which the client reports. The calls the test
    clients make are idempotent: a repeated release, select, set or velocity command changes nothing more."""

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

    def WaitServer(self, wall_limit):
        """Asks the server's API version until it answers (DDS discovery done both ways) or `wall_limit` seconds of
        wall time have passed; returns [code, version, attempts]."""
        start = time.time()
        attempts = 0
        while True:
            attempts += 1
            code, version = self.GetServerApiVersion()
            if code == 0 or time.time() - start > wall_limit:
                return [code, version, attempts]


class RobotClock:
    """The robot's clock: the latest LowState tick (ms of simulated time). Every wait is bounded by `wall_limit`
    seconds of wall time, which only turns a stalled peer into an error."""

    def __init__(self, wall_limit):
        self.wall_limit = wall_limit
        self.lock = threading.Lock()
        self.tick = None
        self.low = ChannelSubscriber("rt/lowstate", LowState_)
        self.low.Init(self._on_state, 10)

    def _on_state(self, msg):
        with self.lock:
            self.tick = msg.tick

    def now(self):
        with self.lock:
            return self.tick

    def ready(self):
        """Whether everything a wait needs has arrived besides the clock (subclasses add their topics)."""
        return True

    def wait(self, seconds):
        """Waits `seconds` of simulated time, counted from the first tick seen once `ready()` holds."""
        start_wall = time.time()
        start = self.now()
        while start is None or not self.ready():
            if time.time() - start_wall > self.wall_limit:
                raise RuntimeError(f"no LowState from the robot, or it is not ready ({type(self).__name__})")
            time.sleep(0.01)
            start = self.now()
        while (self.now() - start) < seconds * 1000.0:
            if time.time() - start_wall > self.wall_limit:
                raise RuntimeError(f"the robot's clock stalled at {self.now()} ms")
            time.sleep(0.005)
