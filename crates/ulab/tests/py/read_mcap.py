"""Reads an MCAP file with the official Python `mcap` package and decodes every hg message with
the Cyclone DDS Python serializer (Unitree's generated types). Prints one JSON summary."""
import json
import sys
import types

sys.modules.setdefault("unitree_sdk2py.b2", types.ModuleType("unitree_sdk2py.b2"))
from mcap.reader import make_reader  # noqa: E402
from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowCmd_, LowState_  # noqa: E402

TYPES = {"unitree_hg::msg::dds_::LowCmd_": LowCmd_, "unitree_hg::msg::dds_::LowState_": LowState_}

out = {"schemas": {}, "channels": {}, "topics": {}, "errors": []}
with open(sys.argv[1], "rb") as f:
    r = make_reader(f)
    summary = r.get_summary()
    for sc in summary.schemas.values():
        out["schemas"][sc.name] = {"encoding": sc.encoding, "idl": sc.data.decode()}
    for ch in summary.channels.values():
        out["channels"][ch.topic] = {"encoding": ch.message_encoding, "metadata": dict(ch.metadata)}
    out["message_count"] = summary.statistics.message_count
    for schema, channel, message in r.iter_messages():
        t = out["topics"].setdefault(channel.topic, {"count": 0, "ticks": [], "crcs": [], "log_times": [], "publish_le_log": True})
        t["count"] += 1
        t["log_times"].append(message.log_time)
        if message.publish_time > message.log_time:
            t["publish_le_log"] = False
        cls = TYPES.get(channel.metadata.get("dds_type_name", ""))
        if cls is None:
            continue
        try:
            v = cls.deserialize(message.data)
        except Exception as e:  # noqa: BLE001
            out["errors"].append(f"{channel.topic}: {e}")
            continue
        t["crcs"].append(v.crc)
        if hasattr(v, "tick"):
            t["ticks"].append(v.tick)
    out["metadata"] = {m.name: dict(m.metadata) for m in r.iter_metadata()}
print(json.dumps(out))
