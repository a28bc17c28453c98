"""Counts the messages of a possibly unfinished MCAP file with the official Python `mcap` package's streaming reader
(chunks decompressed and CRC-checked, no summary needed), stopping at the first error. Prints one JSON line:
{"messages": N, "per_topic": {...}, "readable_bytes": offset after the last whole top-level record,
"error": "..." or null}."""
import json
import sys

from mcap.records import Channel, Message
from mcap.stream_reader import StreamReader

topics, per_topic, n, error, readable = {}, {}, 0, None, 0
with open(sys.argv[1], "rb") as f:
    try:
        for record in StreamReader(f, validate_crcs=True).records:
            readable = f.tell()
            if isinstance(record, Channel):
                topics[record.id] = record.topic
            elif isinstance(record, Message):
                n += 1
                t = topics.get(record.channel_id, "?")
                per_topic[t] = per_topic.get(t, 0) + 1
    except Exception as e:  # noqa: BLE001 - any failure ends the readable part
        error = f"{type(e).__name__}: {e}"
print(json.dumps({"messages": n, "per_topic": per_topic, "readable_bytes": readable, "error": error}))
