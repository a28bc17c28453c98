"""Writes one short robot log in every form the official Python `mcap` writer (mcap 1.6) produces, as a user's
own tooling would: chunks compressed with zstd (the writer's default), lz4, uncompressed, and an unchunked file.

    write_mcap.py OUT_DIR [--states N] [--chunk-size BYTES]

Messages are Unitree's hg LowCmd_ (rt/lowcmd, 250 Hz) and LowState_ (rt/lowstate, 500 Hz) serialized by the Cyclone
DDS Python serializer with Unitree's generated types (unitree_sdk2py), so nothing of ulab touches the bytes. The
channels carry only a schema (name = DDS type name, encoding omgidl), no ulab metadata. Prints one JSON object:
per file its path and the expected content (topic, log time, tick, motor_state[0].q / motor_cmd[0].q) that the
readers under test must reproduce.
"""
import argparse
import json
import math
import os
import sys
import types

# The unitree_sdk2py wheel imports a `b2` subpackage it does not ship.
sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))

from mcap.writer import CompressionType, Writer  # noqa: E402
from unitree_sdk2py.idl.default import unitree_hg_msg_dds__LowCmd_, unitree_hg_msg_dds__LowState_  # noqa: E402

LOWCMD = "unitree_hg::msg::dds_::LowCmd_"
LOWSTATE = "unitree_hg::msg::dds_::LowState_"
T0_NS = 1_700_000_000_000_000_000


def state(i):
    s = unitree_hg_msg_dds__LowState_()
    s.tick = 1000 + 2 * i
    s.imu_state.quaternion = [1.0, 0.0, 0.0, 0.0]
    s.imu_state.accelerometer = [0.0, 0.0, 9.81]
    for k in range(35):
        s.motor_state[k].mode = 1
        s.motor_state[k].q = 0.1 * math.sin(0.01 * i + 0.3 * k)
        s.motor_state[k].dq = 0.5 * math.cos(0.01 * i + 0.3 * k)
        s.motor_state[k].tau_est = 2.0 * math.sin(0.02 * i + k)
    return s


def command(i):
    c = unitree_hg_msg_dds__LowCmd_()
    c.mode_machine = 6
    for k in range(35):
        c.motor_cmd[k].mode = 1
        c.motor_cmd[k].q = 0.2 * math.sin(0.02 * i + 0.1 * k)
        c.motor_cmd[k].kp = 100.0
        c.motor_cmd[k].kd = 2.0
    return c


def write(path, compression, chunked, n_states, chunk_size):
    expected = []
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=chunk_size, compression=compression, use_chunking=chunked)
        w.start(profile="", library="python mcap writer (ulab test fixture)")
        ids = {}
        for topic, name in (("rt/lowcmd", LOWCMD), ("rt/lowstate", LOWSTATE)):
            sid = w.register_schema(name=name, encoding="omgidl", data=f"// {name}".encode())
            ids[topic] = w.register_channel(topic=topic, message_encoding="cdr", schema_id=sid)
        for i in range(n_states):
            t = T0_NS + i * 2_000_000
            if i % 2 == 0:
                c = command(i // 2)
                w.add_message(ids["rt/lowcmd"], log_time=t, data=c.serialize(), publish_time=t, sequence=i // 2)
                expected.append({"topic": "rt/lowcmd", "log_time": t, "q0": c.motor_cmd[0].q})
            s = state(i)
            w.add_message(ids["rt/lowstate"], log_time=t + 1000, data=s.serialize(), publish_time=t + 1000, sequence=i)
            expected.append({"topic": "rt/lowstate", "log_time": t + 1000, "tick": s.tick, "q0": s.motor_state[0].q})
        w.finish()
    return expected


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--states", type=int, default=400)
    ap.add_argument("--chunk-size", type=int, default=64 * 1024)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    forms = {
        "zstd": (CompressionType.ZSTD, True),
        "lz4": (CompressionType.LZ4, True),
        "none": (CompressionType.NONE, True),
        "unchunked": (CompressionType.NONE, False),
    }
    out = {}
    for name, (comp, chunked) in forms.items():
        path = os.path.join(a.out, f"{name}.mcap")
        out[name] = {"path": path, "messages": write(path, comp, chunked, a.states, a.chunk_size)}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
