#!/usr/bin/env python3
"""Generate the golden CDR corpus for Unitree SDK2 low-level messages.

Run:  /work/main/.venv/bin/python corpus/golden/gen_golden.py

For each of the 21 hg/go types this builds a few messages with deterministic
pseudo-random values (plus edge cases), sets the ``crc`` of the four
CRC-carrying types with Unitree's own Python CRC routine (pure-Python path),
serializes them with the cyclonedds Python serializer in XCDR1/XCDR2 x
little/big endian, and writes ``<case>.cdr`` (encapsulation header + CDR) and
``<case>.json`` next to this script, plus ``manifest.json`` and ``NOTES.md``.

Self-checks (the script aborts on any failure):
  * Unitree's Python IDL classes vs our transcription of the C++ headers
    (and, if the unitree_sdk2 git mirror is available, the transcription vs
    the headers themselves);
  * classes built from the header layout serialize byte-identically to
    Unitree's classes wherever the two agree;
  * payload sizes of the four top-level messages vs the reference figures;
  * every .cdr deserializes back (cyclonedds) to the same value;
  * Unitree's CRC == an independent CRC-32/MPEG-2 over our own C struct image,
    Unitree's packer output == our C image, and the all-zero CRC constants.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import random
import re
import struct
import sys
from importlib import metadata
from pathlib import Path
from typing import Any, Dict, List, Optional

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import unitree_env as ue  # noqa: E402
from cyclonedds.idl._support import Endianness  # noqa: E402

OUT_DIR = HERE
MASTER_SEED = 20260522
HEADER_GIT_DIR = os.environ.get(
    "UNITREE_SDK2_GIT", "/work/.mirror/unitreerobotics+unitree_sdk2/repo")

# Reference payload sizes (bytes after the 4-byte encapsulation header).
EXPECTED_PAYLOAD = {
    ("hg/LowCmd", "xcdr1"): 1000, ("hg/LowState", "xcdr1"): 2088,
    ("go/LowCmd", "xcdr1"): 808, ("go/LowState", "xcdr1"): 1176,
    ("hg/LowCmd", "xcdr2"): 1008, ("hg/LowState", "xcdr2"): 2096,
    ("go/LowCmd", "xcdr2"): 816, ("go/LowState", "xcdr2"): 1184,
}
# Reference C image sizes and CRC of an all-zero image.
EXPECTED_C_SIZE = {"hg/LowCmd": 1004, "hg/LowState": 2092, "go/LowCmd": 812, "go/LowState": 1180}
EXPECTED_ZERO_CRC = {"hg/LowCmd": 0xFE172F9F, "hg/LowState": 0xD64BB04A,
                     "go/LowCmd": 0x4B5A4880, "go/LowState": 0x85F11EA6}
# Unitree's private packer / format attribute names per CRC type.
UNITREE_PACKER = {"hg/LowCmd": "HGLowCmd", "hg/LowState": "HGLowState",
                  "go/LowCmd": "LowCmd", "go/LowState": "LowState"}

ENCODINGS = [  # (representation, endianness)
    ("xcdr1", "little"), ("xcdr1", "big"), ("xcdr2", "little"), ("xcdr2", "big"),
]
ENC_SUFFIX = {("xcdr1", "little"): "x1le", ("xcdr1", "big"): "x1be",
              ("xcdr2", "little"): "x2le", ("xcdr2", "big"): "x2be"}


def fail(msg: str) -> None:
    print(f"FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def f32(x: float) -> float:
    """Round to the nearest float32 and return it as an exact Python float."""
    with np.errstate(over="ignore"):
        return float(np.float32(x))


def f32_bits(x: float) -> int:
    return struct.unpack("<I", struct.pack("<f", x))[0]


# --------------------------------------------------------------------------
# Deterministic value generation
# --------------------------------------------------------------------------

F32_MAX = f32(3.4028234663852886e38)
F32_EDGES = [
    0.0, -0.0, 1.0, -1.0,
    2.0 ** -149, -(2.0 ** -149),             # smallest subnormals
    2.0 ** -126 - 2.0 ** -149,               # largest subnormal
    f32(3.3e-42),                            # a mid-range subnormal
    2.0 ** -126, -(2.0 ** -126),             # smallest normals
    F32_MAX, -F32_MAX,                       # largest finite
    f32(1e-30), f32(-7.5e25), f32(1e30),     # large / small magnitudes
    f32(math.pi), f32(1.0 / 3.0), f32(0.1), f32(16777217.0),
]
F32_NONFINITE = [float("nan"), float("inf"), float("-inf")]

INT_RANGE = {
    "uint8": (0, 0xFF), "int8": (-0x80, 0x7F), "uint16": (0, 0xFFFF),
    "int16": (-0x8000, 0x7FFF), "uint32": (0, 0xFFFFFFFF), "int32": (-0x80000000, 0x7FFFFFFF),
}

# Sequence lengths per value profile (hg HandCmd/HandState only).
SEQ_LEN = {"zero": 0, "typical": 7, "edge": 1, "nonfinite": 3}
PRESS_LEN = {"zero": 0, "typical": 9, "edge": 0, "nonfinite": 2}


class ValueGen:
    """Fills a type from CPP_LAYOUT according to a profile:

    zero       all members zero, sequences empty
    typical    plausible magnitudes, full-range integers
    edge       ~60% of scalars drawn from edge pools (extremes, -0.0, subnormals)
    nonfinite  like typical, ~12% of floats NaN/+inf/-inf, some edges
    """

    def __init__(self, seed_text: str, profile: str):
        seed = int.from_bytes(hashlib.sha256(f"{MASTER_SEED}:{seed_text}".encode()).digest()[:8], "big")
        self.rng = random.Random(seed)
        self.profile = profile

    def prim(self, name: str):
        r, p = self.rng, self.profile
        if p == "zero":
            return 0.0 if name == "float32" else 0
        if name == "float32":
            if p == "edge" and r.random() < 0.6:
                return r.choice(F32_EDGES)
            if p == "nonfinite":
                u = r.random()
                if u < 0.12:
                    return r.choice(F32_NONFINITE)
                if u < 0.25:
                    return r.choice(F32_EDGES)
            # log-uniform magnitude between 1e-3 and 1e3, random sign
            mag = 10.0 ** r.uniform(-3, 3)
            return f32(mag if r.random() < 0.5 else -mag)
        lo, hi = INT_RANGE[name]
        if p == "edge" and r.random() < 0.6:
            return r.choice([lo, hi, 0, 1, hi - 1, lo + 1 if lo else 2])
        return r.randint(lo, hi)

    def fill(self, t: str, seq_len: Dict[str, int]) -> Dict[str, Any]:
        def val(member: str, tr: ue.TypeRef):
            if tr.kind == "prim":
                return self.prim(tr.name)
            if tr.kind == "struct":
                return self.fill(tr.name, seq_len)
            if tr.kind == "array":
                return [val(member, tr.elem) for _ in range(tr.length)]
            return [val(member, tr.elem) for _ in range(seq_len[member])]
        return {n: val(n, tr) for n, tr in ue.members(t)}


def has_float(t: str) -> bool:
    def walk(tr: ue.TypeRef) -> bool:
        if tr.kind == "prim":
            return tr.name == "float32"
        if tr.kind == "struct":
            return any(walk(m) for _, m in ue.members(tr.name))
        return walk(tr.elem)
    return any(walk(m) for _, m in ue.members(t))


def realistic_go_lowcmd() -> Dict[str, Any]:
    """go LowCmd as Unitree's Go2 examples initialise it: head FE EF,
    level_flag 0xFF, motors in servo mode 0x01 with the 'stop' sentinels
    (PosStopF = 2.146e9, VelStopF = 16000.0), then a PD target on joint 2."""
    v = ValueGen("go/LowCmd:realistic", "zero").fill("go/LowCmd", {})
    v["head"] = [0xFE, 0xEF]
    v["level_flag"] = 0xFF
    for m in v["motor_cmd"]:
        m.update(mode=0x01, q=f32(2.146e9), dq=f32(16000.0), kp=0.0, kd=0.0, tau=0.0)
    v["motor_cmd"][2].update(q=f32(-1.5), dq=0.0, kp=f32(60.0), kd=f32(5.0), tau=f32(0.5))
    return v


def realistic_hg_lowcmd() -> Dict[str, Any]:
    """hg LowCmd for an H1-2 stance: 27 enabled joints with SDK-example gains."""
    v = ValueGen("hg/LowCmd:realistic", "zero").fill("hg/LowCmd", {})
    v["mode_pr"], v["mode_machine"] = 0, 6
    leg_kp, leg_kd = [100, 100, 100, 200, 80, 80], [3, 3, 3, 5, 2, 2]
    q0 = [0.0, -0.16, 0.0, 0.36, -0.2, 0.0]
    for i, m in enumerate(v["motor_cmd"][:27]):
        if i < 12:
            kp, kd, q = leg_kp[i % 6], leg_kd[i % 6], q0[i % 6]
        elif i == 12:
            kp, kd, q = 100, 3, 0.0
        else:
            kp, kd, q = 80, 2, 0.0
        m.update(mode=1, q=f32(q), dq=0.0, tau=0.0, kp=f32(kp), kd=f32(kd))
    return v


# --------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------

def check_header_transcription() -> Optional[str]:
    """Compare CPP_LAYOUT with the C++ headers, if the git mirror is present."""
    if not Path(HEADER_GIT_DIR).exists():
        print(f"note: {HEADER_GIT_DIR} absent; header cross-check skipped")
        return None
    import subprocess
    head = subprocess.run(["git", "-C", HEADER_GIT_DIR, "rev-parse", "HEAD"],
                          capture_output=True, text=True, check=True).stdout.strip()
    for t in ue.TYPE_ORDER:
        layout, tn = ue.read_header_layout(HEADER_GIT_DIR, t)
        if layout != ue.CPP_LAYOUT[t]:
            fail(f"{t}: transcription differs from header at {head}:\n  {layout}\n  {ue.CPP_LAYOUT[t]}")
        if tn != ue.dds_type_name(t):
            fail(f"{t}: header typename {tn!r} != {ue.dds_type_name(t)!r}")
    print(f"header transcription matches unitree_sdk2 {head} for all {len(ue.TYPE_ORDER)} types")
    return head


def check_crc_packer_formats() -> List[Dict[str, str]]:
    """Compare the struct formats of Unitree's Python CRC packer with the C layout.

    Returns one entry per member (array indices collapsed) whose struct code
    differs from the code of its IDL type.
    """
    engine = ue.make_unitree_crc()
    out: List[Dict[str, str]] = []
    for t in ue.CRC_TYPES:
        fmt = getattr(engine, f"_CRC__packFmt{UNITREE_PACKER[t]}")
        codes = [c for c in ue.expand_struct_format(fmt) if c != "x"]
        fields = ue.flat_c_fields(t)
        if struct.calcsize(fmt) != ue.c_sizeof(t) or len(codes) != len(fields):
            fail(f"{t}: Unitree CRC format {fmt!r} does not cover the C image")
        seen = set()
        for code, (path, prim) in zip(codes, fields):
            want = ue.PRIMITIVES[prim][0]
            if code != want:
                generic = re.sub(r"\[\d+\]", "[]", path)
                if generic not in seen:
                    seen.add(generic)
                    out.append({"type": t, "field": generic, "packer": code,
                                "idl": prim, "idl_code": want})
    return out


def main() -> None:
    versions = {
        "cyclonedds": metadata.version("cyclonedds"),
        "unitree_sdk2": metadata.version("unitree_sdk2"),
        "numpy": metadata.version("numpy"),
        "python": "%d.%d" % sys.version_info[:2],
    }
    print("versions:", versions)

    # ---- 1. IDL comparison ------------------------------------------------
    check_header_transcription()
    disagreements: Dict[str, List[Dict[str, str]]] = {}
    for t in ue.TYPE_ORDER:
        d = ue.compare_py_to_cpp(t)
        if d:
            disagreements[t] = d
    print(f"Python-vs-C++ IDL disagreements: {sum(map(len, disagreements.values()))}")
    for t, ds in disagreements.items():
        for d in ds:
            print(f"  {t}.{d['field']}: python {d['python']} / C++ {d['cpp']}")
    packer_diffs = check_crc_packer_formats()

    # Class choice: Unitree's class when it and every type it contains agree
    # with the headers; otherwise the class built from the header layout.
    spec = ue.build_spec_classes()

    def clean(t: str) -> bool:
        if t in disagreements:
            return False
        def walk(tr):
            if tr.kind == "struct":
                return clean(tr.name)
            if tr.kind in ("array", "sequence"):
                return walk(tr.elem)
            return True
        return all(walk(m) for _, m in ue.members(t))
    classes = {t: (ue.unitree_py_class(t) if clean(t) else spec[t]) for t in ue.TYPE_ORDER}
    class_source = {t: ("unitree_sdk2py" if clean(t) else "corrected (C++ layout)") for t in ue.TYPE_ORDER}

    crc_engine = ue.make_unitree_crc()

    # ---- 2. All-zero CRC constants -----------------------------------------
    zero_crc = {}
    for t in ue.CRC_TYPES:
        zero_tree = ValueGen("zero", "zero").fill(t, {})
        c = crc_engine.Crc(ue.build_object(classes, t, zero_tree))
        image = ue.c_image(t, zero_tree)
        if len(image) != EXPECTED_C_SIZE[t]:
            fail(f"{t}: C image {len(image)} B, expected {EXPECTED_C_SIZE[t]}")
        if c != EXPECTED_ZERO_CRC[t] or ue.independent_crc(image) != c:
            fail(f"{t}: zero CRC {c:#010x}, expected {EXPECTED_ZERO_CRC[t]:#010x}")
        zero_crc[t] = c
    print("all-zero CRCs match the reference:", {t: f"{c:#010x}" for t, c in zero_crc.items()})

    # ---- 3. Cases ---------------------------------------------------------
    cases: List[Dict[str, Any]] = []   # value cases before encoding
    for t in ue.TYPE_ORDER:
        profiles = ["zero", "typical", "edge"] + (["nonfinite"] if has_float(t) else [])
        for p in profiles:
            seq = {"motor_cmd": SEQ_LEN[p], "motor_state": SEQ_LEN[p],
                   "press_sensor_state": PRESS_LEN[p]}
            cases.append({"type": t, "name": p, "tree": ValueGen(f"{t}:{p}", p).fill(t, seq),
                          "bad_crc": False})
        if t in ue.CRC_TYPES:
            bad = ValueGen(f"{t}:badcrc", "typical").fill(t, {})
            cases.append({"type": t, "name": "badcrc", "tree": bad, "bad_crc": True})
    cases.append({"type": "go/LowCmd", "name": "realistic", "tree": realistic_go_lowcmd(), "bad_crc": False})
    cases.append({"type": "hg/LowCmd", "name": "realistic", "tree": realistic_hg_lowcmd(), "bad_crc": False})

    # Remove previous output so stale cases cannot linger.
    for p in list(OUT_DIR.glob("*.cdr")) + list(OUT_DIR.glob("*.json")):
        p.unlink()

    manifest_cases = []
    total_bytes = 0
    for case in cases:
        t, tree = case["type"], case["tree"]
        crc_value = None
        crc_ok = None
        if t in ue.CRC_TYPES:
            obj = ue.build_object(classes, t, tree)
            crc_value = crc_engine.Crc(ue.crc_input_for_unitree(t, obj))
            image = ue.c_image(t, tree)
            # Unitree's packer must produce our C image (zero padding) ...
            packer = getattr(crc_engine, f"_CRC__Pack{UNITREE_PACKER[t]}")
            words = packer(ue.crc_input_for_unitree(t, obj))
            if struct.pack(f"<{len(words)}I", *words) != image[:-4]:
                fail(f"{t}/{case['name']}: Unitree's packed image differs from the C image")
            # ... and its CRC must equal the independent CRC-32/MPEG-2.
            if ue.independent_crc(image) != crc_value:
                fail(f"{t}/{case['name']}: Unitree CRC {crc_value:#x} != independent CRC")
            stored = crc_value
            if case["bad_crc"]:
                # two kinds of corruption: LowCmd low bit flipped, LowState top byte + 1
                stored = (crc_value ^ 0x1 if t.endswith("LowCmd")
                          else (crc_value + 0x01000000) & 0xFFFFFFFF)
            tree["crc"] = stored
            crc_ok = stored == crc_value
            # sanity: stored crc is the last word of the image and is not hashed
            if crc_engine.Crc(ue.crc_input_for_unitree(t, ue.build_object(classes, t, tree))) != crc_value:
                fail(f"{t}: CRC depends on the crc member")

        obj = ue.build_object(classes, t, tree)
        # Unitree's and header-built classes must serialize identically when they agree.
        spec_obj = ue.build_object(spec, t, tree)
        for rep, endian in ENCODINGS:
            e = Endianness.Little if endian == "little" else Endianness.Big
            data = obj.serialize(endianness=e, use_version_2=(rep == "xcdr2"))
            if classes[t] is not spec[t]:
                alt = spec_obj.serialize(endianness=e, use_version_2=(rep == "xcdr2"))
                if alt != data:
                    fail(f"{t}/{case['name']}/{rep}/{endian}: header-built class serializes differently")
            # encapsulation header: 0x0000/0x0001 XCDR1 BE/LE, 0x0006/0x0007 XCDR2 BE/LE (final)
            want_hdr = {("xcdr1", "big"): b"\0\0\0\0", ("xcdr1", "little"): b"\0\1\0\0",
                        ("xcdr2", "big"): b"\0\6\0\0", ("xcdr2", "little"): b"\0\7\0\0"}[(rep, endian)]
            if data[:4] != want_hdr:
                fail(f"{t}: unexpected encapsulation header {data[:4].hex()}")
            exp = EXPECTED_PAYLOAD.get((t, rep))
            if exp is not None and len(data) - 4 != exp:
                fail(f"{t} {rep}: payload {len(data) - 4} B, reference says {exp} B")
            # Round trip through the cyclonedds deserializer.
            back = classes[t].deserialize(data)
            back_json = json.dumps(ue.tree_to_json(t, ue.object_to_tree(t, back)))
            if back_json != json.dumps(ue.tree_to_json(t, tree)):
                fail(f"{t}/{case['name']}/{rep}/{endian}: round trip changed the value")

            stem = f"{t.replace('/', '_').lower()}_{case['name']}_{ENC_SUFFIX[(rep, endian)]}"
            doc = {"type": t, "representation": rep, "endianness": endian,
                   "crc_ok": crc_ok, "value": ue.tree_to_json(t, tree)}
            text = json.dumps(doc, allow_nan=False, separators=(",", ":")) + "\n"
            (OUT_DIR / f"{stem}.cdr").write_bytes(data)
            (OUT_DIR / f"{stem}.json").write_text(text)
            total_bytes += len(data) + len(text)
            entry = {"case": stem, "type": t, "representation": rep, "endianness": endian,
                     "size": len(data), "crc_ok": crc_ok}
            if crc_value is not None:
                entry["crc"] = crc_value
                entry["stored_crc"] = tree["crc"]
            manifest_cases.append(entry)

    # Spot checks of CDR offsets quoted in the reference (XCDR1 LE, payload offsets).
    t = "hg/LowCmd"
    d = (OUT_DIR / "hg_lowcmd_typical_x1le.cdr").read_bytes()[4:]
    tr = json.loads((OUT_DIR / "hg_lowcmd_typical_x1le.json").read_text())["value"]
    if d[2] != tr["motor_cmd"][0]["mode"]:
        fail("hg LowCmd: first MotorCmd.mode not at payload offset 2")
    d = (OUT_DIR / "hg_lowstate_typical_x1le.cdr").read_bytes()[4:]
    tr = json.loads((OUT_DIR / "hg_lowstate_typical_x1le.json").read_text())["value"]
    if d[70] != tr["motor_state"][0]["mode"]:
        fail("hg LowState: first MotorState.mode not at payload offset 70")

    manifest = {
        "description": "Golden CDR corpus for Unitree SDK2 hg/go low-level messages "
                       "(see README.md); generated by gen_golden.py",
        "seed": MASTER_SEED,
        "versions": versions,
        "classes": class_source,
        "zero_image_crc": {t: c for t, c in zero_crc.items()},
        "cases": manifest_cases,
    }
    (OUT_DIR / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    write_notes(disagreements, packer_diffs, class_source)
    total_bytes += (OUT_DIR / "manifest.json").stat().st_size
    print(f"wrote {len(manifest_cases)} cases ({len(cases)} values x encodings), "
          f"{total_bytes / 1024:.0f} KiB")


# --------------------------------------------------------------------------
# NOTES.md
# --------------------------------------------------------------------------

def xcdr1_fixed_size(type_str: str, off: int = 0, python_layouts=None) -> Optional[int]:
    """End offset of a member of type type_str placed at payload offset off
    under XCDR1 rules (primitives aligned to their size, no struct padding);
    None for sequences or unknown types."""
    tr = type_str.strip()
    m = __import__("re").fullmatch(r"(.+)\[(\d+)\]", tr)
    if m:
        for _ in range(int(m.group(2))):
            off = xcdr1_fixed_size(m.group(1), off, python_layouts)
            if off is None:
                return None
        return off
    if tr in ue.PRIMITIVES:
        size = ue.PRIMITIVES[tr][1]
        return (off + size - 1) // size * size + size
    layout = (python_layouts or {}).get(tr, ue.CPP_LAYOUT.get(tr))
    if layout is None:
        return None
    for _, mt in layout:
        off = xcdr1_fixed_size(mt, off, python_layouts)
        if off is None:
            return None
    return off


def wire_consequence(t: str, d: Dict[str, str]) -> str:
    """One-line description of what a Python/C++ disagreement does on the wire."""
    py_layouts = {k: ue.describe_py_class(ue.unitree_py_class(k)) for k in ue.TYPE_ORDER}
    if d["field"] == "(typename)":
        return "different DDS type name: readers and writers do not match"
    if d["field"] == "(extensibility)":
        return "different encapsulation / DHEADERs in XCDR2"
    py_size = xcdr1_fixed_size(t, 0, py_layouts)
    cpp_size = xcdr1_fixed_size(t, 0)
    if py_size is None or cpp_size is None:
        sizes = "variable-size type"
    else:
        sizes = f"XCDR1 size of {t}: Python {py_size} B, C++ {cpp_size} B"
    if py_size == cpp_size and d["python"] not in ("(missing)", "(absent)"):
        return f"same size ({sizes}); the bytes are read with a different type"
    return f"{sizes}; members after `{d['field']}` are misaligned"


def write_notes(disagreements, packer_diffs, class_source) -> None:
    L: List[str] = []
    L.append("# IDL notes: Unitree's Python classes vs the C++ headers\n")
    L.append("Generated by `gen_golden.py` (do not edit by hand).\n")
    L.append(f"Authority: the C++ IDL headers `include/unitree/idl/{{hg,go2}}/*_.hpp` of "
             f"unitreerobotics/unitree_sdk2 (transcribed in `unitree_env.py` from commit "
             f"`{ue.HEADER_COMMIT}`; the script re-reads the headers and checks the "
             f"transcription when the git mirror is available).")
    L.append("Compared: every class of `unitree_sdk2py.idl.unitree_hg` / `unitree_go` used by "
             "the corpus (unitree_sdk2 " + metadata.version("unitree_sdk2") + " wheel): member "
             "names, order, primitive types, array lengths, sequence bounds, typename "
             "(`.` mapped to `::`) and extensibility (@final).\n")
    L.append("## IDL class disagreements\n")
    if not disagreements:
        L.append(f"None. All {len(ue.TYPE_ORDER)} Python classes agree with the headers field by field "
                 "(names, order, types, array lengths, typename `unitree_xx::msg::dds_::X_`, "
                 "@final). In particular this wheel already has go `LowState.temperature_ntc1`/"
                 "`temperature_ntc2` (uint8, between `adc_reel` and `power_v`), go "
                 "`IMUState.temperature` uint8 and hg `IMUState.temperature` int16, as the "
                 "headers do. The corpus is therefore generated with Unitree's own classes; "
                 "the header-built classes are still constructed and the script asserts they "
                 "serialize byte-identically for every case and encoding.\n")
    else:
        L.append("| type | field | Python says | C++ says | consequence on the wire |")
        L.append("|---|---|---|---|---|")
        for t, ds in disagreements.items():
            for d in ds:
                L.append(f"| {t} | {d['field']} | {d['python']} | {d['cpp']} | "
                         f"{wire_consequence(t, d)} |")
        L.append("")
    L.append("Classes used per type: " + ", ".join(f"{t}: {s}" for t, s in class_source.items()) + ".\n")

    L.append("## Unitree's Python CRC packer (`unitree_sdk2py/utils/crc.py`)\n")
    L.append("The CRC routine packs each message into the C struct image with `struct.pack` "
             "format strings (natural alignment, `x` pad bytes = zero) and hashes all 32-bit "
             "words except the trailing `crc`. The script checks, for every CRC case, that the "
             "packed words equal our own C image with zeroed padding, and that Unitree's "
             "bitwise CRC equals an independent table-driven CRC-32/MPEG-2 over the image with "
             "each word byte-swapped. Its format strings use these struct codes where the IDL "
             "member has a different signedness:\n")
    if packer_diffs:
        L.append("| type | member | packer code | IDL type (code) | consequence |")
        L.append("|---|---|---|---|---|")
        for d in packer_diffs:
            L.append(f"| {d['type']} | {d['field']} | `{d['packer']}` | {d['idl']} (`{d['idl_code']}`) | "
                     f"`struct.error` for values above {127 if d['idl'] == 'uint8' else 32767}; "
                     "same bytes otherwise |")
        L.append("")
        L.append("Bytes are unaffected (two's complement), so the CRC value is still right for "
                 "in-range values; but Unitree's Python `CRC().Crc()` raises `struct.error` for a "
                 "go LowState whose unsigned temperature/ntc bytes exceed 127 or whose "
                 "`fan_frequency` exceeds 32767. To cover the full range, `gen_golden.py` feeds "
                 "Unitree's routine a copy with those values replaced by their signed "
                 "two's-complement equivalents (identical packed bytes) and cross-checks the "
                 "result with the independent CRC.\n")
    else:
        L.append("No signedness mismatches.\n")
    L.append("Other observations: the CRC covers the C image, not the CDR stream (they differ "
             "in padding: CDR aligns relative to the payload start and has no struct tail "
             "padding). All-zero image CRCs reproduced: hg LowCmd 0xFE172F9F, hg LowState "
             "0xD64BB04A, go LowCmd 0x4B5A4880, go LowState 0x85F11EA6. The CRC treats NaN "
             "floats as their bit pattern (Python packs float('nan') as 0x7FC00000). The 1.0.1 "
             "wheel's default (Linux) path loads `lib/crc_amd64.so`, which the wheel lacks; we "
             "force the pure-Python `_crc_py` path by constructing `CRC()` while "
             "`platform.system()` reports a non-Linux name.\n")
    (OUT_DIR / "NOTES.md").write_text("\n".join(L))


if __name__ == "__main__":
    main()
