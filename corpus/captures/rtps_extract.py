#!/usr/bin/env python3
"""Extract serialized DDS samples from a pcap of Cyclone DDS (RTPS/UDP) traffic.

    rtps_extract.py capture.pcap [--published published.json] [--out DIR]

Our own minimal parser (no Wireshark):
  * pcap (classic, µs or ns) with Ethernet, Linux cooked (SLL/SLL2), BSD
    loopback or raw-IP link types; IPv4/IPv6 + UDP (no IP reassembly: on lo
    the MTU is 64 KiB);
  * RTPS header, submessages INFO_SRC (0x0c), DATA (0x15), DATA_FRAG (0x16);
    everything else is skipped using octetsToNextHeader;
  * inline QoS skipped (parameter list up to PID_SENTINEL);
  * DATA_FRAG reassembly keyed by (writer GUID, sequence number);
  * SEDP publication announcements (builtin writer 0x000003c2) give the topic
    and type name of every user writer GUID.

For every user topic, the samples (ordered by writer first appearance, then
sequence number) are written as ``<topic>_<n>.cdr`` (encapsulation header +
CDR, exactly as on the wire) with ``<topic>_<n>.json`` = the value the
publisher logged for it, and ``index.json`` describing each file.  With
``--published`` each payload is also compared with the cyclonedds
serialization (XCDR1 LE) of the logged value.
"""

from __future__ import annotations

import argparse
import json
import struct
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Tuple

SUB_INFO_SRC = 0x0C
SUB_DATA = 0x15
SUB_DATA_FRAG = 0x16
PID_SENTINEL = 0x0001
PID_TOPIC_NAME = 0x0005
PID_TYPE_NAME = 0x0007
PID_ENDPOINT_GUID = 0x005A
SEDP_PUBLICATIONS_WRITER = bytes.fromhex("000003c2")


# --------------------------------------------------------------------------
# pcap -> UDP payloads
# --------------------------------------------------------------------------

def pcap_udp_payloads(path: Path):
    """Yield (packet index, UDP payload) for every UDP datagram in the file."""
    data = path.read_bytes()
    magic = data[:4]
    if magic in (b"\xd4\xc3\xb2\xa1", b"\x4d\x3c\xb2\xa1"):
        end = "<"
    elif magic in (b"\xa1\xb2\xc3\xd4", b"\xa1\xb2\x3c\x4d"):
        end = ">"
    else:
        raise ValueError("not a classic pcap file (pcapng is not supported)")
    linktype = struct.unpack(end + "I", data[20:24])[0]
    off, idx = 24, 0
    while off + 16 <= len(data):
        _, _, incl, _ = struct.unpack(end + "IIII", data[off:off + 16])
        frame = data[off + 16: off + 16 + incl]
        off += 16 + incl
        idx += 1
        ip = link_to_ip(linktype, frame)
        if ip is None:
            continue
        udp = ip_to_udp(ip)
        if udp is not None:
            yield idx, udp


def link_to_ip(linktype: int, frame: bytes) -> Optional[bytes]:
    if linktype == 1:                       # Ethernet (tcpdump on lo uses this)
        etype, p = struct.unpack(">H", frame[12:14])[0], 14
        while etype in (0x8100, 0x88A8):    # VLAN tags
            etype, p = struct.unpack(">H", frame[p + 2:p + 4])[0], p + 4
        return frame[p:] if etype in (0x0800, 0x86DD) else None
    if linktype == 113:                     # Linux cooked v1
        return frame[16:] if struct.unpack(">H", frame[14:16])[0] in (0x0800, 0x86DD) else None
    if linktype == 276:                     # Linux cooked v2
        return frame[20:] if struct.unpack(">H", frame[0:2])[0] in (0x0800, 0x86DD) else None
    if linktype == 0:                       # BSD loopback (4-byte family, host order)
        return frame[4:]
    if linktype in (101, 12, 228, 229):     # raw IP
        return frame
    return None


def ip_to_udp(ip: bytes) -> Optional[bytes]:
    version = ip[0] >> 4
    if version == 4:
        ihl = (ip[0] & 0x0F) * 4
        total = struct.unpack(">H", ip[2:4])[0]
        flags_frag = struct.unpack(">H", ip[6:8])[0]
        if ip[9] != 17 or flags_frag & 0x3FFF:   # not UDP, or an IP fragment
            return None
        seg = ip[ihl:total]
    elif version == 6:
        if ip[6] != 17:                           # no extension headers handled
            return None
        seg = ip[40:40 + struct.unpack(">H", ip[4:6])[0]]
    else:
        return None
    length = struct.unpack(">H", seg[4:6])[0]
    return seg[8:length]


# --------------------------------------------------------------------------
# RTPS
# --------------------------------------------------------------------------

@dataclass
class Sample:
    writer_guid: bytes
    seq: int
    payload: bytes
    first_packet: int
    kind: str                  # "DATA" or "DATA_FRAG"
    fragments: int = 1
    fragment_size: int = 0


@dataclass
class FragBuffer:
    size: int
    frag_size: int
    first_packet: int
    buf: bytearray = field(default_factory=bytearray)
    have: set = field(default_factory=set)        # fragment numbers received
    n_sub: int = 0                                 # DATA_FRAG submessages seen

    def complete(self) -> bool:
        nfrags = (self.size + self.frag_size - 1) // self.frag_size
        return len(self.have) == nfrags


def skip_parameter_list(body: bytes, p: int, end: str) -> int:
    """Return the offset after a parameter list (inline QoS) ending in PID_SENTINEL."""
    while True:
        pid, plen = struct.unpack(end + "HH", body[p:p + 4])
        p += 4 + plen
        if pid == PID_SENTINEL:
            return p


def parse_rtps(datagram: bytes, packet: int, samples: Dict[Tuple[bytes, int], Sample],
               frags: Dict[Tuple[bytes, int], FragBuffer]) -> None:
    if len(datagram) < 20 or datagram[:4] != b"RTPS":
        return
    src_prefix = datagram[8:20]
    p = 20
    while p + 4 <= len(datagram):
        sid, flags = datagram[p], datagram[p + 1]
        end = "<" if flags & 0x01 else ">"
        octets = struct.unpack(end + "H", datagram[p + 2:p + 4])[0]
        body_start = p + 4
        # octetsToNextHeader == 0 means "to the end of the message" (except PAD/INFO_TS)
        body_end = len(datagram) if octets == 0 and sid not in (0x01, 0x09) else body_start + octets
        body = datagram[body_start:body_end]
        p = body_end
        if sid == SUB_INFO_SRC:
            src_prefix = body[8:20]
        elif sid == SUB_DATA:
            # extraFlags(2) octetsToInlineQos(2) readerId(4) writerId(4) writerSN(8)
            otiq = struct.unpack(end + "H", body[2:4])[0]
            writer_id = body[8:12]
            hi, lo = struct.unpack(end + "iI", body[12:20])
            q = 4 + otiq
            if flags & 0x02:                 # Q: inline QoS present
                q = skip_parameter_list(body, q, end)
            if not flags & 0x04:             # D clear: no data (e.g. dispose/unregister)
                continue
            key = (src_prefix + writer_id, (hi << 32) | lo)
            if key not in samples:
                samples[key] = Sample(key[0], key[1], bytes(body[q:]), packet, "DATA")
        elif sid == SUB_DATA_FRAG:
            # extraFlags(2) octetsToInlineQos(2) readerId(4) writerId(4) writerSN(8)
            # fragmentStartingNum(4) fragmentsInSubmessage(2) fragmentSize(2) sampleSize(4)
            otiq = struct.unpack(end + "H", body[2:4])[0]
            writer_id = body[8:12]
            hi, lo = struct.unpack(end + "iI", body[12:20])
            start, nsub, fsize, ssize = struct.unpack(end + "IHHI", body[20:32])
            q = 4 + otiq
            if flags & 0x02:
                q = skip_parameter_list(body, q, end)
            key = (src_prefix + writer_id, (hi << 32) | lo)
            if key in samples:
                continue                      # already reassembled (duplicate)
            fb = frags.setdefault(key, FragBuffer(ssize, fsize, packet, bytearray(ssize)))
            fb.n_sub += 1
            data = body[q:]
            for i in range(nsub):
                num = start + i                      # fragment numbers are 1-based
                a = (num - 1) * fsize
                b = min(a + fsize, ssize)
                fb.buf[a:b] = data[i * fsize: i * fsize + (b - a)]
                fb.have.add(num)
            if fb.complete():
                samples[key] = Sample(key[0], key[1], bytes(fb.buf), fb.first_packet,
                                      "DATA_FRAG", len(fb.have), fsize)
                del frags[key]


def parse_sedp_publication(payload: bytes) -> Dict[str, object]:
    """Topic name, type name and endpoint GUID from a PL_CDR SEDP sample."""
    enc = payload[:2]
    end = "<" if enc in (b"\x00\x03", b"\x00\x01") else ">"
    p, out = 4, {}
    while p + 4 <= len(payload):
        pid, plen = struct.unpack(end + "HH", payload[p:p + 4])
        val = payload[p + 4:p + 4 + plen]
        p += 4 + plen
        pid &= 0x3FFF                       # strip vendor/must-understand bits
        if pid == PID_SENTINEL:
            break
        if pid in (PID_TOPIC_NAME, PID_TYPE_NAME):
            n = struct.unpack(end + "I", val[:4])[0]
            out["topic" if pid == PID_TOPIC_NAME else "type"] = val[4:4 + n].rstrip(b"\0").decode()
        elif pid == PID_ENDPOINT_GUID:
            out["guid"] = bytes(val[:16])
    return out


# --------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------

def topic_stem(topic: str) -> str:
    return topic.strip("/").replace("/", "_")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("pcap", type=Path, nargs="+")
    ap.add_argument("--published", type=Path, help="publisher log (published.json)")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent)
    args = ap.parse_args()

    samples: Dict[Tuple[bytes, int], Sample] = {}
    frags: Dict[Tuple[bytes, int], FragBuffer] = {}
    for pcap in args.pcap:
        for idx, udp in pcap_udp_payloads(pcap):
            parse_rtps(udp, idx, samples, frags)
    if frags:
        print(f"warning: {len(frags)} incomplete fragmented samples", file=sys.stderr)

    # Writer GUID -> (topic, type) from SEDP.
    writers: Dict[bytes, Dict[str, object]] = {}
    for s in samples.values():
        if s.writer_guid[12:] == SEDP_PUBLICATIONS_WRITER:
            info = parse_sedp_publication(s.payload)
            if "guid" in info and "topic" in info:
                writers[info["guid"]] = info

    published = json.loads(args.published.read_text()) if args.published else []
    # (guid prefix, topic, index) -> published doc; guid prefix -> phase
    sent = {(e["guid_prefix"], e["topic"], e["index"]): e["doc"] for e in published}
    phase_of = {e["guid_prefix"]: e["phase"] for e in published}
    phase_rank = {ph: i for i, ph in enumerate(dict.fromkeys(e["phase"] for e in published))}

    # Group user samples per topic.  With a publisher log, keep only samples of
    # the logged participants (other DDS applications may share domain and
    # interface), ordered by phase then sequence number; without one, keep
    # every writer, in order of first appearance.
    per_topic: Dict[str, List[Sample]] = {}
    first_seen: Dict[bytes, int] = {}
    foreign = 0
    for s in sorted(samples.values(), key=lambda s: (s.first_packet, s.seq)):
        if s.writer_guid not in writers:
            continue
        if published and s.writer_guid[:12].hex() not in phase_of:
            foreign += 1
            continue
        first_seen.setdefault(s.writer_guid, s.first_packet)
        per_topic.setdefault(writers[s.writer_guid]["topic"], []).append(s)
    if foreign:
        print(f"note: ignored {foreign} user samples from participants not in the publisher log")

    def order(s: Sample):
        if published:
            return (phase_rank[phase_of[s.writer_guid[:12].hex()]], s.seq)
        return (first_seen[s.writer_guid], s.seq)

    if published:
        sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "golden"))
        import unitree_env as ue  # noqa: E402
        from cyclonedds.idl._support import Endianness  # noqa: E402
        classes = {t: ue.unitree_py_class(t) for t in ue.TYPE_ORDER}

        def serialize(doc):
            tree = json_to_tree(doc["value"])
            return ue.build_object(classes, doc["type"], tree).serialize(
                endianness=Endianness.Little, use_version_2=False)

    index, mismatches = [], 0
    for topic in sorted(per_topic):
        lst = sorted(per_topic[topic], key=order)
        for n, s in enumerate(lst):
            stem = f"{topic_stem(topic)}_{n}"
            (args.out / f"{stem}.cdr").write_bytes(s.payload)
            entry = {"file": f"{stem}.cdr", "topic": topic,
                     "type_name": writers[s.writer_guid].get("type"),
                     "writer_guid": s.writer_guid.hex(), "seq": s.seq,
                     "size": len(s.payload), "submessage": s.kind,
                     "fragments": s.fragments, "fragment_size": s.fragment_size or None}
            prefix = s.writer_guid[:12].hex()
            doc = sent.get((prefix, topic, s.seq - 1))
            if doc is not None:
                entry["phase"] = phase_of[prefix]
                entry["published_index"] = s.seq - 1
                (args.out / f"{stem}.json").write_text(
                    json.dumps(doc, allow_nan=False, separators=(",", ":")) + "\n")
                ref = serialize(doc)
                entry["identical_to_cyclonedds_serialization"] = ref == s.payload
                if ref != s.payload:
                    mismatches += 1
                    diff = [i for i in range(min(len(ref), len(s.payload))) if ref[i] != s.payload[i]]
                    entry["first_difference"] = diff[0] if diff else min(len(ref), len(s.payload))
            index.append(entry)
            print(f"{stem}: {s.kind} x{s.fragments} {len(s.payload)} B seq {s.seq}"
                  + ("" if doc is None else
                     f"  identical={entry['identical_to_cyclonedds_serialization']}"))
    (args.out / "index.json").write_text(json.dumps(index, indent=1) + "\n")
    n_frag = sum(1 for e in index if e["submessage"] == "DATA_FRAG")
    print(f"{len(index)} samples ({n_frag} reassembled from DATA_FRAG), {mismatches} mismatches")
    if published and len([e for e in index if "phase" in e]) != len(published):
        print("error: not every published message was captured", file=sys.stderr)
        return 1
    return 1 if mismatches else 0


def json_to_tree(v):
    """Inverse of unitree_env.json_number on a whole JSON value."""
    if isinstance(v, dict):
        return {k: json_to_tree(x) for k, x in v.items()}
    if isinstance(v, list):
        return [json_to_tree(x) for x in v]
    if v == "NaN":
        return float("nan")
    if v == "Infinity":
        return float("inf")
    if v == "-Infinity":
        return float("-inf")
    return v


if __name__ == "__main__":
    sys.exit(main())
