"""Interop probe of `ulab conform` on Cyclone DDS 11 through its Python binding, as Unitree's Python SDK
(unitree_sdk2py) uses it: the domain configured by unitree_sdk2py's own ChannelFactoryInitialize(DOMAIN, INTERFACE),
rt/lowstate read with unitree_sdk2py's generated hg LowState_ type (a typed topic: it announces XTypes type
information, which Cyclone DDS 0.10 peers are known to crash on).

usage: python cyclone11_probe.py DOMAIN INTERFACE SECONDS MIN_SAMPLES

Imports first, then waits for one line on stdin before it joins the domain (so that the caller decides when). Prints
one JSON line: {"version": ..., "matched_writers": N, "samples": N, "first_sample_ms": T, "elapsed_ms": T}, or
{"error": ...} with exit 4 when a module is missing.
"""
import json
import sys
import time
import types

try:
    # The unitree_sdk2py wheel imports a `b2` subpackage it does not ship.
    sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))
    import importlib.metadata
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from unitree_sdk2py.core.channel import ChannelFactoryInitialize
    from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowState_
except Exception as e:  # noqa: BLE001 (report any import failure)
    print(json.dumps({"error": f"{type(e).__name__}: {e}"}), flush=True)
    sys.exit(4)


def main():
    try:
        version = importlib.metadata.version("cyclonedds")
    except Exception:  # noqa: BLE001
        version = "unknown"
    domain, iface, seconds, min_samples = int(sys.argv[1]), sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
    print("READY", flush=True)
    sys.stdin.readline()
    start = time.time()
    ChannelFactoryInitialize(domain, iface)
    dp = DomainParticipant(domain)
    reader = DataReader(dp, Topic(dp, "rt/lowstate", LowState_))
    samples, first, matched = 0, None, 0
    while time.time() - start < seconds and samples < min_samples:
        for s in reader.take(N=64):
            if hasattr(s, "motor_state"):
                samples += 1
                first = first or time.time()
        try:
            matched = max(matched, len(reader.get_matched_publications()))
        except Exception:  # noqa: BLE001 (older bindings)
            pass
        time.sleep(0.002)
    print(json.dumps({
        "version": version,
        "matched_writers": matched,
        "samples": samples,
        "first_sample_ms": round((first - start) * 1e3, 1) if first else -1.0,
        "elapsed_ms": round((time.time() - start) * 1e3, 1),
    }), flush=True)


if __name__ == "__main__":
    main()
