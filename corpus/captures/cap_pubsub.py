#!/usr/bin/env python3
"""Publisher / subscriber for the live captures, using Unitree's Python SDK.

    cap_pubsub.py sub --seconds 40            # one subscriber for all topics
    cap_pubsub.py pub --phase default         # SDK configuration as shipped
    cap_pubsub.py pub --phase frag            # same, but MaxMessageSize 1456 B

Both use ``ChannelFactoryInitialize(1, "lo")`` (domain 1 on loopback, as the
public simulator bridges do) and ``ChannelPublisher``/``ChannelSubscriber``.
They must run as separate processes: within one participant Cyclone delivers
locally and nothing reaches the wire.

The publisher writes ``MESSAGES_PER_PHASE`` messages on each topic and appends
what it sent (topic, phase, index, its participant GUID prefix, the JSON
document of the value) to ``published.json``.  Values are deterministic (seeded), and the crc of the
LowCmd/LowState messages is set with Unitree's own CRC routine, as a real
client would.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "golden"))

import unitree_env as ue  # noqa: E402  (also stubs unitree_sdk2py.b2)
from gen_golden import ValueGen  # noqa: E402

import unitree_sdk2py.core.channel as sdk_channel  # noqa: E402
from unitree_sdk2py.core.channel import (  # noqa: E402
    ChannelFactoryInitialize, ChannelPublisher, ChannelSubscriber)

DOMAIN = 1
INTERFACE = "lo"
MESSAGES_PER_PHASE = 3
# topic -> corpus type.  hg types on Unitree's real topic names, go types on
# separate topics (a topic has one type).
TOPICS = {
    "rt/lowcmd": "hg/LowCmd",
    "rt/lowstate": "hg/LowState",
    "rt/go2/lowcmd": "go/LowCmd",
    "rt/go2/lowstate": "go/LowState",
}
PHASES = ("default", "frag")
# Value profile of the k-th message of a phase (see gen_golden.ValueGen).
PROFILES = ("typical", "edge", "nonfinite")
# For the 'frag' phase: Cyclone only emits DATA_FRAG when a sample does not fit
# in one RTPS message (MaxMessageSize, default 14720 B), so a 2092 B hg
# LowState goes out as one DATA by default.  Limiting the message size to
# 1456 B (Cyclone's MaxRexmitMessageSize default) makes it fragment the sample
# into FragmentSize (1344 B) pieces.
FRAG_MAX_MESSAGE_SIZE = "1456B"


def message_tree(topic: str, phase: str, k: int):
    t = TOPICS[topic]
    return ValueGen(f"capture:{topic}:{phase}:{k}", PROFILES[k % len(PROFILES)]).fill(t, {})


def init_sdk(phase: str) -> None:
    if phase == "frag":
        # The SDK builds its Cyclone XML from a template string and ignores
        # CYCLONEDDS_URI, so the only way in is the template itself.
        sdk_channel.ChannelConfigHasInterface = sdk_channel.ChannelConfigHasInterface.replace(
            "</Interfaces>",
            f"</Interfaces><MaxMessageSize>{FRAG_MAX_MESSAGE_SIZE}</MaxMessageSize>")
    ChannelFactoryInitialize(DOMAIN, INTERFACE)


def run_pub(phase: str, log_path: Path) -> int:
    init_sdk(phase)
    crc = ue.make_unitree_crc()
    classes = {t: ue.unitree_py_class(t) for t in ue.TYPE_ORDER}
    pubs = {}
    for topic, t in TOPICS.items():
        p = ChannelPublisher(topic, classes[t])
        p.Init()
        pubs[topic] = p
    # GUID prefix of this process's participant: lets the extractor tell our
    # writers from any other DDS traffic on the same domain and interface.
    participant = sdk_channel.ChannelFactory._ChannelFactory__participant
    prefix = participant.guid.bytes[:12].hex()
    log = json.loads(log_path.read_text()) if log_path.exists() else []
    ok = True
    for k in range(MESSAGES_PER_PHASE):
        for topic, t in TOPICS.items():
            tree = message_tree(topic, phase, k)
            msg = ue.build_object(classes, t, tree)
            msg.crc = crc.Crc(ue.crc_input_for_unitree(t, msg))
            tree["crc"] = msg.crc
            # Write() waits (up to the timeout) for a matched reader first.
            sent = pubs[topic].Write(msg, 5.0)
            ok &= bool(sent)
            print(f"[pub {phase}] {topic} #{k} sent={sent}", flush=True)
            log.append({"topic": topic, "phase": phase, "index": k, "guid_prefix": prefix,
                        "doc": {"type": t, "representation": "xcdr1", "endianness": "little",
                                "crc_ok": True, "value": ue.tree_to_json(t, tree)}})
            time.sleep(0.1)
    log_path.write_text(json.dumps(log, allow_nan=False, separators=(",", ":")) + "\n")
    time.sleep(1.0)  # let the last samples and heartbeats go out
    return 0 if ok else 1


def run_sub(seconds: float, expected: int) -> int:
    init_sdk("default")
    counts = {topic: 0 for topic in TOPICS}
    lock = threading.Lock()
    subs = []
    for topic, t in TOPICS.items():
        def handler(msg, topic=topic):
            with lock:
                counts[topic] += 1
        s = ChannelSubscriber(topic, ue.unitree_py_class(t))
        s.Init(handler, 16)
        subs.append(s)
    print("[sub] ready", flush=True)
    deadline = time.time() + seconds
    while time.time() < deadline:
        with lock:
            if all(c >= expected for c in counts.values()):
                break
        time.sleep(0.1)
    print(f"[sub] received {counts}", flush=True)
    return 0 if all(c >= expected for c in counts.values()) else 1


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("role", choices=["pub", "sub"])
    ap.add_argument("--phase", choices=PHASES, default="default")
    ap.add_argument("--log", type=Path, default=HERE / "published.json")
    ap.add_argument("--seconds", type=float, default=40.0)
    args = ap.parse_args()
    if args.role == "pub":
        return run_pub(args.phase, args.log)
    return run_sub(args.seconds, MESSAGES_PER_PHASE * len(PHASES))


if __name__ == "__main__":
    sys.exit(main())
