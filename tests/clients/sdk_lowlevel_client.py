"""A low-level controller written against Unitree's official Python SDK (unitree_sdk2py), used
to check that a simulator bridge behaves like the robot. It only uses the SDK's public API:
ChannelFactoryInitialize, ChannelSubscriber/ChannelPublisher, the IDL classes and its CRC.

  python sdk_lowlevel_client.py --domain D [--seconds-rate 2] [--dump N]

Prints one JSON object: the LowState stream (CRC validity checked with the SDK's own CRC code,
ticks, the spacing of ticks in simulated milliseconds), joints commanded to targets and where
they ended, and what a corrupted-CRC command did.

Every phase that needs the robot to move lasts a span of SIMULATED time, read from the LowState
tick (milliseconds of the robot's clock), not of wall time: on a loaded machine a simulator may
run slower than real time, and the outcome must not depend on that. Every wait is bounded by a
generous wall-clock limit that only turns a stalled peer into an error, never decides a result.
Exit code 0 unless the SDK itself failed.
"""
import argparse
import dataclasses
import json
import math
import platform
import sys
import threading
import time
import types

# The unitree_sdk2 1.0.1 wheel imports a `b2` subpackage it does not ship.
sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))

from unitree_sdk2py.core.channel import ChannelFactoryInitialize, ChannelPublisher, ChannelSubscriber  # noqa: E402
from unitree_sdk2py.idl.default import unitree_hg_msg_dds__LowCmd_  # noqa: E402
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowCmd_, LowState_  # noqa: E402


def sdk_crc():
    """The SDK's CRC object on its pure-Python path: on Linux the wheel would load a shared
    library it lacks, so construct it while platform.system() reports another OS."""
    from unitree_sdk2py.utils import crc as crc_mod

    real = platform.system
    platform.system = lambda: "Windows"
    try:
        return crc_mod.CRC()
    finally:
        platform.system = real


# Slots (unitree_hg, H1-2): 0-5 left leg, 6-11 right leg, 12 torso, 13-19 left arm, 20-26 right arm.
LEG_KP = [500, 500, 500, 500, 600, 600]
LEG_KD = [5, 5, 5, 6, 10, 10]
ARM_KP, ARM_KD = 120.0, 3.0
MOVES = {16: 0.35, 23: 0.35, 13: -0.3, 20: -0.3}  # elbows and shoulder pitches: offsets (rad)


class Client:
    def __init__(self, domain):
        ChannelFactoryInitialize(domain, "lo")
        self.crc = sdk_crc()
        self.lock = threading.Lock()
        self.states = []  # (receive time, crc ok, tick, q[27])
        self.sub = ChannelSubscriber("rt/lowstate", LowState_)
        self.sub.Init(self.on_state, 10)
        self.pub = ChannelPublisher("rt/lowcmd", LowCmd_)
        self.pub.Init()

    def on_state(self, msg):
        # Keep the callback cheap (the SDK's pure-Python CRC takes milliseconds): check later.
        with self.lock:
            self.states.append((time.monotonic(), msg, msg.tick, [m.q for m in msg.motor_state[:27]], msg.mode_machine))

    def latest(self):
        with self.lock:
            return self.states[-1] if self.states else None

    def make_command(self, targets, mode_machine, corrupt=False):
        cmd = unitree_hg_msg_dds__LowCmd_()
        cmd.mode_pr = 0
        cmd.mode_machine = mode_machine
        for i in range(27):
            m = cmd.motor_cmd[i]
            m.mode = 1
            m.q = float(targets[i])
            m.dq = 0.0
            m.tau = 0.0
            if i < 12:
                m.kp, m.kd = float(LEG_KP[i % 6]), float(LEG_KD[i % 6])
            elif i == 12:
                m.kp, m.kd = 300.0, 5.0
            else:
                m.kp, m.kd = ARM_KP, ARM_KD
        cmd.crc = self.crc.Crc(cmd)
        if corrupt:
            cmd.crc ^= 0x1
        return cmd

    def drive(self, send, sim_seconds, period=0.002, wall_limit=120.0, until=None, max_sim_seconds=None):
        """Calls send() every `period` of wall time until the robot's clock (LowState tick) has
        advanced by `sim_seconds` and, if given, `until(q)` holds for the latest joint positions
        or the clock has advanced by `max_sim_seconds`. Returns the simulated seconds covered
        (less only if the peer stalled past `wall_limit`).

        `until` exists because this client observes the robot with a delay: on a loaded machine
        its Python reader falls behind the 500 Hz stream, so the newest state it has processed
        can be seconds of simulated time older than the state the bridge applies commands to.
        A span counted from that stale clock would end before the commands had acted."""
        tick0 = self.latest()[2]
        give_up = time.monotonic() + wall_limit

        def more():
            covered = self.latest()[2] - tick0
            if covered < sim_seconds * 1000.0:
                return True
            if until is None or until(self.latest()[3]):
                return False
            return covered < (max_sim_seconds or sim_seconds) * 1000.0

        nxt = time.monotonic()
        while more() and time.monotonic() < give_up:
            send()
            nxt += period
            time.sleep(max(0.0, nxt - time.monotonic()))
        return (self.latest()[2] - tick0) / 1000.0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int, required=True)
    ap.add_argument("--seconds-rate", type=float, default=2.0)
    ap.add_argument("--connect-timeout", type=float, default=20.0)
    ap.add_argument("--dump", type=int, default=0, help="also print N received LowState samples as decoded by Python")
    args = ap.parse_args()
    out = {}
    c = Client(args.domain)

    # 1. State stream: wait for the first sample, then collect a window of samples.
    deadline = time.monotonic() + args.connect_timeout
    while c.latest() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    if c.latest() is None:
        print(json.dumps({"error": "no LowState received"}), flush=True)
        return
    time.sleep(0.3)
    with c.lock:
        n0 = len(c.states)
    t0 = time.monotonic()
    time.sleep(args.seconds_rate)
    with c.lock:
        window = c.states[n0:]
    elapsed = time.monotonic() - t0
    # Wall-clock rate: a benchmark figure (reported, never judged).
    out["rate_hz"] = len(window) / elapsed
    out["states"] = len(window)
    out["crc_ok"] = sum(1 for s in window if c.crc.Crc(s[1]) == s[1].crc)
    ticks = [s[2] for s in window]
    out["ticks_increasing"] = all(b > a for a, b in zip(ticks, ticks[1:]))
    # The spacing of states on the robot's clock: with one state per period and none lost, every
    # delta is the period; lost samples give multiples of it. Their gcd is the publication period
    # in simulated milliseconds, whatever the machine's speed.
    deltas = [b - a for a, b in zip(ticks, ticks[1:])]
    out["tick_gcd_ms"] = math.gcd(*deltas) if deltas else None
    out["tick_min_ms"] = min(deltas) if deltas else None
    out["tick_span_ms"] = ticks[-1] - ticks[0] if ticks else 0
    mode_machine = c.latest()[4]
    out["mode_machine"] = mode_machine
    if args.dump:
        step = max(1, len(window) // args.dump)
        out["samples"] = [dataclasses.asdict(s[1]) for s in window[::step][: args.dump]]

    # 2. Hold the current pose, move a few joints to targets.
    start_q = list(c.latest()[3])
    targets = list(start_q)
    for slot, delta in MOVES.items():
        targets[slot] = start_q[slot] + delta
    hold = c.make_command(targets, mode_machine)
    # At least 2.5 s of simulated time, then until every moved joint is near its target as this
    # client sees it (at most 10 s): the test judges the final positions with its own bound.
    def reached(q):
        return all(abs(q[s] - targets[s]) < 0.05 for s in MOVES)

    out["hold_sim_seconds"] = c.drive(lambda: c.pub.Write(hold), 2.5, until=reached, max_sim_seconds=10.0)
    final_q = c.latest()[3]
    out["rpy_after_moves"] = list(c.latest()[1].imu_state.rpy)
    out["moves"] = [{"slot": s, "start": start_q[s], "target": targets[s], "final": final_q[s]} for s in MOVES]

    # 3. Keep holding with valid commands while also sending a corrupted-CRC command that would
    #    move the left elbow far away: the bridge must ignore it.
    bad = list(targets)
    bad[16] = targets[16] - 0.8

    corrupt = c.make_command(bad, mode_machine, corrupt=True)

    def both():
        c.pub.Write(hold)
        c.pub.Write(corrupt)

    out["corrupt_sim_seconds"] = c.drive(both, 1.5, period=0.004)
    out["corrupted"] = {"slot": 16, "held_target": targets[16], "corrupt_target": bad[16], "final": c.latest()[3][16]}
    # Received octet arrays come back as bytes: print them as lists of integers.
    print(json.dumps(out, default=list), flush=True)


if __name__ == "__main__":
    main()
