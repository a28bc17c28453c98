"""Reads an MCAP file with the official Python `mcap` reader and prints one JSON object: the compression of every
chunk (from the chunk index), the message count per topic and the log times in file order.

    summarize_mcap.py FILE
"""
import json
import sys

from mcap.reader import make_reader

with open(sys.argv[1], "rb") as f:
    r = make_reader(f)
    summary = r.get_summary()
    out = {
        "library": r.get_header().library,
        "chunk_compressions": sorted({ci.compression for ci in summary.chunk_indexes}),
        "chunks": len(summary.chunk_indexes),
        "topics": {},
    }
    for _schema, channel, message in r.iter_messages(log_time_order=False):
        t = out["topics"].setdefault(channel.topic, {"count": 0, "log_times": []})
        t["count"] += 1
        t["log_times"].append(message.log_time)
print(json.dumps(out))
