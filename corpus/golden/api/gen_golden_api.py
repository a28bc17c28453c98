#!/usr/bin/env python3
"""Generate the golden CDR corpus of Unitree SDK2's RPC types (unitree_api::msg::dds_).

Run:  /work/main/.venv/bin/python corpus/golden/api/gen_golden_api.py

The RPC types carry every high-level call of Unitree's SDK (LocoClient, SportClient, ...) on
`rt/api/<service>/request|response`: Request_ {header {identity {id, api_id: int64}, lease {id:
int64}, policy {priority: int32, noreply: bool}}, parameter: string, binary: sequence<uint8>} and
Response_ {header {identity, status {code: int32}}, data: string, binary: sequence<uint8>}.

Every value is built with Unitree's own Python classes (unitree_sdk2py.idl.unitree_api) and
serialized by the cyclonedds Python serializer in XCDR1/XCDR2 x little/big endian. Profiles:

  zero      all members zero, strings empty, sequences empty
  typical   random ids, api ids of the loco services, JSON text parameters, random binary
  edge      int64/int32 extremes, true, long and non-ASCII UTF-8 strings, 255-byte binaries
  sdk       Request_ exactly as unitree_sdk2py's own RPC client code builds it
            (rpc.client.Client._Call on an H1 LocoClient declared from Unitree's headers), and
            Response_ exactly as its RPC server code builds it (rpc.server.Server); the DDS
            channel of both is replaced by a recorder, the request id (a monotonic clock in the
            SDK) by a counter, so the output is deterministic.

Self-checks (abort on failure):
  * Unitree's Python classes vs our transcription of the C++ headers
    include/unitree/robot/internal/internal_idl_decl/*_.hpp (names, order, types, typename,
    @final), and the transcription vs the headers when the unitree_sdk2 git mirror is present;
  * every .cdr deserializes (cyclonedds) back to the same value.
Writes <case>.cdr / <case>.json, manifest.json and NOTES.md next to this script (deleting the
previous *.cdr / *.json of this directory first).
"""

from __future__ import annotations

import hashlib
import json
import os
import random
import re
import subprocess
import sys
import types as _pytypes
from importlib import metadata
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple
from unittest import mock

HERE = Path(__file__).resolve().parent

# unitree_sdk2py/__init__.py imports a `b2` subpackage the 1.0.1 wheel does not ship.
sys.modules.setdefault("unitree_sdk2py.b2", _pytypes.ModuleType("unitree_sdk2py.b2"))

import cyclonedds.idl.types as idltypes  # noqa: E402
from cyclonedds.idl._support import Endianness  # noqa: E402
from cyclonedds.idl._type_normalize import get_extended_type_hints  # noqa: E402

import unitree_sdk2py.idl.unitree_api.msg.dds_ as py_api  # noqa: E402
import unitree_sdk2py.rpc.client_base as sdk_client_base  # noqa: E402
import unitree_sdk2py.rpc.server_base as sdk_server_base  # noqa: E402
from unitree_sdk2py.rpc.client import Client as SdkClient  # noqa: E402
from unitree_sdk2py.rpc.server import Server as SdkServer  # noqa: E402

MASTER_SEED = 20261120
HEADER_GIT_DIR = os.environ.get("UNITREE_SDK2_GIT", "/work/.mirror/unitreerobotics+unitree_sdk2/repo")
# Commit of unitreerobotics/unitree_sdk2 the layouts below were transcribed from.
HEADER_COMMIT = "21d0a3b2c46ee48c8fdf2783becb6be3beb0a59b"
HEADER_DIR = "include/unitree/robot/internal/internal_idl_decl"

# Member lists in declaration order (C++ members without their trailing underscore).
API_LAYOUT: Dict[str, List[Tuple[str, str]]] = {
    "RequestIdentity": [("id", "int64"), ("api_id", "int64")],
    "RequestLease": [("id", "int64")],
    "RequestPolicy": [("priority", "int32"), ("noreply", "bool")],
    "RequestHeader": [("identity", "RequestIdentity"), ("lease", "RequestLease"), ("policy", "RequestPolicy")],
    "Request": [("header", "RequestHeader"), ("parameter", "string"), ("binary", "sequence<uint8>")],
    "ResponseStatus": [("code", "int32")],
    "ResponseHeader": [("identity", "RequestIdentity"), ("status", "ResponseStatus")],
    "Response": [("header", "ResponseHeader"), ("data", "string"), ("binary", "sequence<uint8>")],
}
TYPE_ORDER = list(API_LAYOUT)

# H1 locomotion service as Unitree's C++ header declares it (include/unitree/robot/h1/loco/h1_loco_api.hpp):
# the wheel (1.0.1) ships no H1 client, so the "sdk" cases declare one on the SDK's own Client class.
H1_LOCO_SERVICE = "loco"
H1_LOCO_VERSION = "2.0.0.0"
H1_API = {"GET_FSM_ID": 8001, "GET_FSM_MODE": 8002, "SET_FSM_ID": 8101, "SET_STAND_HEIGHT": 8104,
          "SET_VELOCITY": 8105, "GET_ODOM": 8203}
LOCO_API_IDS = [8001, 8002, 8003, 8004, 8005, 8006, 8101, 8102, 8103, 8104, 8105, 8201, 8202, 8203,
                7001, 7002, 7101, 7105, 1, 101, 102]

ENCODINGS = [("xcdr1", "little"), ("xcdr1", "big"), ("xcdr2", "little"), ("xcdr2", "big")]
ENC_SUFFIX = {("xcdr1", "little"): "x1le", ("xcdr1", "big"): "x1be",
              ("xcdr2", "little"): "x2le", ("xcdr2", "big"): "x2be"}
INT_RANGE = {"int32": (-(1 << 31), (1 << 31) - 1), "int64": (-(1 << 63), (1 << 63) - 1), "uint8": (0, 255)}


def fail(msg: str) -> None:
    print(f"FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def py_class(t: str):
    return getattr(py_api, t + "_")


def dds_type_name(t: str) -> str:
    return f"unitree_api::msg::dds_::{t}_"


# --------------------------------------------------------------------------
# Python classes and C++ headers vs the transcription
# --------------------------------------------------------------------------

def describe_py_type(tp) -> str:
    import typing
    if isinstance(tp, idltypes.sequence):
        return f"sequence<{describe_py_type(tp.subtype)}>"
    if isinstance(tp, type) and hasattr(tp, "__idl_typename__"):
        m = re.fullmatch(r"unitree_api\.msg\.dds_\.(\w+)_", tp.__idl_typename__)
        return m.group(1) if m else tp.__idl_typename__
    if tp is str:
        return "string"
    if tp is bool:
        return "bool"
    args = typing.get_args(tp)
    if len(args) == 2 and isinstance(args[1], str):
        return args[1]
    return repr(tp)


def compare_py_to_cpp(t: str) -> List[str]:
    cls = py_class(t)
    diffs = []
    if cls.__idl_typename__.replace(".", "::") != dds_type_name(t):
        diffs.append(f"typename {cls.__idl_typename__}")
    if cls.__idl_annotations__.get("extensibility") != "final":
        diffs.append(f"extensibility {cls.__idl_annotations__.get('extensibility')}")
    py = [(n, describe_py_type(tp)) for n, tp in get_extended_type_hints(cls).items()]
    if py != API_LAYOUT[t]:
        diffs.append(f"members {py} != {API_LAYOUT[t]}")
    return diffs


_CPP_TYPES = {"int64_t": "int64", "int32_t": "int32", "bool": "bool", "std::string": "string",
              "std::vector<uint8_t>": "sequence<uint8>"}


def read_header_layout(t: str) -> Tuple[List[Tuple[str, str]], str]:
    text = subprocess.run(["git", "-C", HEADER_GIT_DIR, "show", f"HEAD:{HEADER_DIR}/{t}_.hpp"],
                          capture_output=True, text=True, check=True).stdout
    body = text.split(f"class {t}_", 1)[1].split("public:", 1)[0]
    layout = []
    for ty, name in re.findall(r"^\s*([:\w<>]+)\s+(\w+)_(?:\s*=\s*[^;]+)?;", body, re.M):
        m = re.fullmatch(r"::unitree_api::msg::dds_::(\w+)_", ty)
        layout.append((name, m.group(1) if m else _CPP_TYPES[ty]))
    tn = re.search(r'getTypeName\(\)\s*\{\s*return "([^"]+)"', text)
    return layout, tn.group(1) if tn else ""


def check_header_transcription() -> Optional[str]:
    if not Path(HEADER_GIT_DIR).exists():
        print(f"note: {HEADER_GIT_DIR} absent; header cross-check skipped")
        return None
    head = subprocess.run(["git", "-C", HEADER_GIT_DIR, "rev-parse", "HEAD"],
                          capture_output=True, text=True, check=True).stdout.strip()
    for t in TYPE_ORDER:
        layout, tn = read_header_layout(t)
        if layout != API_LAYOUT[t]:
            fail(f"{t}: transcription differs from the header at {head}:\n  {layout}\n  {API_LAYOUT[t]}")
        if tn != dds_type_name(t):
            fail(f"{t}: header typename {tn!r}")
    print(f"header transcription matches unitree_sdk2 {head} for all {len(TYPE_ORDER)} types")
    return head


# --------------------------------------------------------------------------
# Values
# --------------------------------------------------------------------------

EDGE_STRINGS = [
    "",
    '{"data":204}',
    "x" * 300,
    "h\u00e9llo \u2713 \u6b65\u884c \U0001f916",  # 2-, 3- and 4-byte UTF-8
    '{"velocity":[0.5,0.0,-0.25],"duration":864000.0}',
]


class ValueGen:
    def __init__(self, seed_text: str, profile: str):
        seed = int.from_bytes(hashlib.sha256(f"{MASTER_SEED}:{seed_text}".encode()).digest()[:8], "big")
        self.rng = random.Random(seed)
        self.profile = profile

    def prim(self, member: str, name: str):
        r, p = self.rng, self.profile
        if p == "zero":
            return {"bool": False, "string": ""}.get(name, 0)
        if name == "bool":
            return True if p == "edge" else r.random() < 0.5
        if name == "string":
            if p == "edge":
                return r.choice(EDGE_STRINGS[2:])
            vx, vy, wz = (round(r.uniform(-1, 1), 3) for _ in range(3))
            return r.choice([
                "", "{}", json.dumps({"data": r.choice([0, 1, 2, 204])}),
                json.dumps({"velocity": [vx, vy, wz], "duration": round(r.uniform(0.1, 5), 2)}),
                json.dumps({"name": f"host/loco/{r.randint(1, 99999)}"}),
            ])
        lo, hi = INT_RANGE[name]
        if p == "edge":
            return r.choice([lo, hi, -1, lo + 1, hi - 1])
        if member == "api_id":
            return r.choice(LOCO_API_IDS)
        if member == "code":
            return r.choice([0, 3102, 3104, 3203, 3204, 8301, 8302])
        return r.randint(lo, hi)

    def fill(self, t: str) -> Dict[str, Any]:
        out = {}
        for n, ty in API_LAYOUT[t]:
            if ty in API_LAYOUT:
                out[n] = self.fill(ty)
            elif ty.startswith("sequence<"):
                if self.profile == "zero":
                    out[n] = []
                elif self.profile == "edge":
                    out[n] = [self.rng.choice([0, 255, 1, 254]) for _ in range(255)]
                else:
                    out[n] = [self.rng.randint(0, 255) for _ in range(self.rng.randint(1, 40))]
            else:
                out[n] = self.prim(n, ty)
        return out


def build(t: str, tree: Dict[str, Any]):
    kwargs = {}
    for n, ty in API_LAYOUT[t]:
        kwargs[n] = build(ty, tree[n]) if ty in API_LAYOUT else tree[n]
    return py_class(t)(**kwargs)


def to_tree(t: str, obj) -> Dict[str, Any]:
    out = {}
    for n, ty in API_LAYOUT[t]:
        v = getattr(obj, n)
        out[n] = to_tree(ty, v) if ty in API_LAYOUT else (list(v) if ty.startswith("sequence<") else v)
    return out


# --------------------------------------------------------------------------
# The SDK's own request and response construction
# --------------------------------------------------------------------------

class _RecordingChannel:
    """Stands in for the SDK's DDS stubs: keeps what the SDK would have written."""

    written: List[Any] = []

    def __init__(self, *_args, **_kwargs):
        pass

    def Init(self, *_args, **_kwargs):
        pass

    def SendRequest(self, request, _timeout):
        _RecordingChannel.written.append(request)
        return None  # no future: the client returns RPC_ERR_CLIENT_SEND, having built the request

    def Send(self, message, _timeout):
        _RecordingChannel.written.append(message)
        return True

    def RemoveFuture(self, _id):
        pass


def sdk_requests() -> List[Tuple[str, Any]]:
    """Request_ objects built by unitree_sdk2py's Client for H1 LocoClient calls."""
    counter = iter(range(10**12, 10**12 + 1000, 7))
    with mock.patch.object(sdk_client_base, "ClientStub", _RecordingChannel), \
            mock.patch.object(sdk_client_base.time, "monotonic_ns", lambda: next(counter)):
        client = SdkClient(H1_LOCO_SERVICE, False)
        client._SetApiVerson(H1_LOCO_VERSION)
        for api_id in H1_API.values():
            client._RegistApi(api_id, 0)
        _RecordingChannel.written.clear()
        calls = [
            ("set_velocity", H1_API["SET_VELOCITY"], json.dumps({"velocity": [0.5, 0.0, 0.0], "duration": 1.0})),
            ("move_continuous", H1_API["SET_VELOCITY"],
             json.dumps({"velocity": [0.3, -0.1, 0.2], "duration": 864000.0})),
            ("damp", H1_API["SET_FSM_ID"], json.dumps({"data": 1})),
            ("start", H1_API["SET_FSM_ID"], json.dumps({"data": 204})),
            ("high_stand", H1_API["SET_STAND_HEIGHT"], json.dumps({"data": (1 << 32) - 1})),
            ("get_fsm_id", H1_API["GET_FSM_ID"], ""),
        ]
        for _name, api_id, parameter in calls:
            client._Call(api_id, parameter)
        client._CallNoReply(H1_API["SET_VELOCITY"], json.dumps({"velocity": [0.0, 0.0, 0.0], "duration": 1.0}))
        client._CallBinary(H1_API["GET_ODOM"], [1, 2, 3, 250])
        client.GetServerApiVersion()
        names = [c[0] for c in calls] + ["stop_noreply", "binary_call", "api_version"]
        return list(zip(names, list(_RecordingChannel.written)))


def sdk_responses(requests: List[Tuple[str, Any]]) -> List[Tuple[str, Any]]:
    """Response_ objects built by unitree_sdk2py's Server answering some of those requests."""
    with mock.patch.object(sdk_server_base, "ServerStub", _RecordingChannel):
        server = SdkServer(H1_LOCO_SERVICE)
        server._SetApiVersion(H1_LOCO_VERSION)
        server._RegistHandler(H1_API["GET_FSM_ID"], lambda _p: (0, json.dumps({"data": 204})), False)
        server._RegistHandler(H1_API["SET_VELOCITY"], lambda _p: (0, ""), False)
        server._RegistHandler(H1_API["SET_FSM_ID"], lambda _p: (8302, "ignored when the code is not 0"), False)
        _RecordingChannel.written.clear()
        names = []
        for name, request in requests:
            if name in ("get_fsm_id", "set_velocity", "damp", "api_version", "high_stand"):
                server._Server__ServerRequestHandler(request)
                names.append(name)
        return list(zip(names, list(_RecordingChannel.written)))


# --------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------

def main() -> None:
    versions = {"cyclonedds": metadata.version("cyclonedds"), "unitree_sdk2": metadata.version("unitree_sdk2"),
                "python": "%d.%d" % sys.version_info[:2]}
    print("versions:", versions)
    head = check_header_transcription()
    for t in TYPE_ORDER:
        d = compare_py_to_cpp(t)
        if d:
            fail(f"{t}: Unitree's Python class differs from the header: {d}")
    print(f"Unitree's Python classes agree with the headers for all {len(TYPE_ORDER)} types")

    cases: List[Tuple[str, str, Any]] = []  # (type, case name, object)
    for t in TYPE_ORDER:
        for p in ("zero", "typical", "edge"):
            cases.append((t, p, build(t, ValueGen(f"{t}:{p}", p).fill(t))))
    requests = sdk_requests()
    if len(requests) != 9:
        fail(f"the SDK client wrote {len(requests)} requests, expected 9")
    for name, req in requests:
        cases.append(("Request", f"sdk_{name}", req))
    responses = sdk_responses(requests)
    for name, resp in responses:
        cases.append(("Response", f"sdk_{name}", resp))
    # What the SDK's server code is expected to have done (its behaviour, checked so that a
    # different wheel cannot silently change the corpus' meaning).
    by_name = dict(responses)
    if by_name["api_version"].data != H1_LOCO_VERSION or by_name["high_stand"].header.status.code != 3203:
        fail("the SDK server did not answer the version / unregistered-api calls as expected")
    if by_name["damp"].header.status.code != 8302 or by_name["damp"].data != "":
        fail("the SDK server did not clear the data of a failed call")

    for p in list(HERE.glob("*.cdr")) + list(HERE.glob("*.json")):
        p.unlink()
    manifest = []
    for t, name, obj in cases:
        tree = to_tree(t, obj)
        for rep, endian in ENCODINGS:
            e = Endianness.Little if endian == "little" else Endianness.Big
            data = obj.serialize(endianness=e, use_version_2=(rep == "xcdr2"))
            back = py_class(t).deserialize(data)
            if to_tree(t, back) != tree:
                fail(f"{t}/{name}/{rep}/{endian}: round trip changed the value")
            stem = f"api_{t.lower()}_{name}_{ENC_SUFFIX[(rep, endian)]}"
            doc = {"type": f"api/{t}", "representation": rep, "endianness": endian, "crc_ok": None, "value": tree}
            (HERE / f"{stem}.cdr").write_bytes(data)
            (HERE / f"{stem}.json").write_text(json.dumps(doc, ensure_ascii=False, separators=(",", ":")) + "\n")
            manifest.append({"case": stem, "type": f"api/{t}", "representation": rep, "endianness": endian,
                             "size": len(data)})
    (HERE / "manifest.json").write_text(json.dumps({
        "description": "Golden CDR corpus of Unitree SDK2's RPC types (unitree_api); generated by gen_golden_api.py",
        "seed": MASTER_SEED, "versions": versions, "header_commit": head or HEADER_COMMIT, "cases": manifest,
    }, indent=1) + "\n")
    write_notes(head)
    print(f"wrote {len(manifest)} cases ({len(cases)} values x {len(ENCODINGS)} encodings)")


def write_notes(head: Optional[str]) -> None:
    checked = f"checked against the headers at `{head}`" if head else "headers not available: not re-checked"
    text = f"""# RPC types: Unitree's Python classes vs the C++ headers

Generated by `gen_golden_api.py` (do not edit by hand).

Authority: `{HEADER_DIR}/*_.hpp` of unitreerobotics/unitree_sdk2 (transcribed in
`gen_golden_api.py` from commit `{HEADER_COMMIT}`; {checked}).
Compared: the 8 classes of `unitree_sdk2py.idl.unitree_api.msg.dds_` (unitree_sdk2
{metadata.version("unitree_sdk2")} wheel): member names, order, types, typename (`.` mapped to
`::`) and extensibility (@final). They agree field by field; the corpus uses Unitree's classes.

| type | members |
|---|---|
""" + "".join(f"| `{dds_type_name(t)}` | " + ", ".join(f"{n}: {ty}" for n, ty in API_LAYOUT[t]) + " |\n"
              for t in TYPE_ORDER) + """
Wire facts the corpus shows (cyclonedds-python serializer): `string` is a uint32 length counting
the terminating NUL, the UTF-8 bytes and the NUL, with no DHEADER in XCDR2 (an empty string is
`01 00 00 00 00`); `sequence<uint8>` is a uint32 count and the bytes, no DHEADER in XCDR2;
`boolean` is one byte 0/1; `int64` is 8-aligned in XCDR1 and 4-aligned in XCDR2 (every int64 of
these types sits at an 8-aligned payload offset, so both give the same bytes here); the
serializer declares no end padding in the encapsulation options.

`sdk_*` cases are the requests unitree_sdk2py's `rpc.client.Client` builds for an H1
`LocoClient` declared from `h1_loco_api.hpp` (service `loco`, version `2.0.0.0`; the 1.0.1 wheel
has no H1 client) and the responses its `rpc.server.Server` builds: the API version answered to
`ROBOT_API_ID_INTERNAL_API_VERSION` (1), `UT_ROBOT_ERR_SERVER_API_NOT_IMPL` (3203) for an
unregistered id with empty `data`, and a failing handler's status with its `data` cleared.
"""
    (HERE / "NOTES.md").write_text(text)


if __name__ == "__main__":
    main()
