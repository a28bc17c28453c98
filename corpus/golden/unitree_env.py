"""Shared helpers for the golden-data and capture scripts.

* imports Unitree's Python SDK (``unitree_sdk2py``) despite the quirks of its
  1.0.1 wheel (missing ``b2`` subpackage, missing CRC shared library on Linux);
* holds our own transcription of the C++ IDL headers of Unitree SDK2 (the
  authority on member names, order and types) and builds cyclonedds
  ``IdlStruct`` classes from it;
* converts IDL objects to the JSON ``value`` documents of the corpus.

Nothing here is copied from Unitree's code; the layouts are transcribed from
``include/unitree/idl/{hg,go2}/*_.hpp`` of unitreerobotics/unitree_sdk2.
"""

from __future__ import annotations

import copy
import math
import re
import struct
import subprocess
import sys
import types as _pytypes
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Tuple
from unittest import mock

# --------------------------------------------------------------------------
# Importing Unitree's SDK
# --------------------------------------------------------------------------

# unitree_sdk2py/__init__.py imports a ``b2`` subpackage that the 1.0.1 wheel
# does not ship.  An empty placeholder module is enough for everything we use.
sys.modules.setdefault("unitree_sdk2py.b2", _pytypes.ModuleType("unitree_sdk2py.b2"))

import cyclonedds.idl as idl  # noqa: E402
import cyclonedds.idl.annotations as annotate  # noqa: E402
import cyclonedds.idl.types as idltypes  # noqa: E402
from cyclonedds.idl._type_normalize import get_extended_type_hints  # noqa: E402

import unitree_sdk2py  # noqa: E402,F401
import unitree_sdk2py.idl.unitree_go.msg.dds_ as py_go  # noqa: E402
import unitree_sdk2py.idl.unitree_hg.msg.dds_ as py_hg  # noqa: E402
import unitree_sdk2py.utils.crc as unitree_crc_module  # noqa: E402


def make_unitree_crc():
    """Return Unitree's ``CRC`` object forced onto its pure-Python path.

    ``CRC.__init__`` loads ``lib/crc_amd64.so`` when ``platform.system()`` is
    "Linux" and then always uses that library; the wheel does not ship it.  On
    any other platform name it keeps ``self.platform`` and ``__Crc32`` calls
    the pure-Python ``_crc_py``.  So we construct it while ``platform.system``
    reports a non-Linux name.  (CRC is a Singleton: construct it only here.)
    """
    with mock.patch.object(unitree_crc_module.platform, "system", return_value="NotLinux"):
        engine = unitree_crc_module.CRC()
    assert engine.platform != "Linux", "Unitree CRC would use the ctypes library"
    return engine


# --------------------------------------------------------------------------
# C++ header transcription (the authority)
# --------------------------------------------------------------------------

# Commit of unitreerobotics/unitree_sdk2 the table below was transcribed from.
HEADER_COMMIT = "21d0a3b2c46ee48c8fdf2783becb6be3beb0a59b"

# Member lists in declaration order. Type grammar:
#   primitive            uint8 int8 uint16 int16 uint32 int32 float32
#   "ns/Name"            nested struct (e.g. "hg/MotorCmd")
#   "T[N]"               fixed array of N elements
#   "sequence<T>"        unbounded sequence
CPP_LAYOUT: Dict[str, List[Tuple[str, str]]] = {
    "hg/MotorCmd": [
        ("mode", "uint8"), ("q", "float32"), ("dq", "float32"), ("tau", "float32"),
        ("kp", "float32"), ("kd", "float32"), ("reserve", "uint32"),
    ],
    "hg/LowCmd": [
        ("mode_pr", "uint8"), ("mode_machine", "uint8"),
        ("motor_cmd", "hg/MotorCmd[35]"), ("reserve", "uint32[4]"), ("crc", "uint32"),
    ],
    "hg/IMUState": [
        ("quaternion", "float32[4]"), ("gyroscope", "float32[3]"),
        ("accelerometer", "float32[3]"), ("rpy", "float32[3]"), ("temperature", "int16"),
    ],
    "hg/MotorState": [
        ("mode", "uint8"), ("q", "float32"), ("dq", "float32"), ("ddq", "float32"),
        ("tau_est", "float32"), ("temperature", "int16[2]"), ("vol", "float32"),
        ("sensor", "uint32[2]"), ("motorstate", "uint32"), ("reserve", "uint32[4]"),
    ],
    "hg/LowState": [
        ("version", "uint32[2]"), ("mode_pr", "uint8"), ("mode_machine", "uint8"),
        ("tick", "uint32"), ("imu_state", "hg/IMUState"),
        ("motor_state", "hg/MotorState[35]"), ("wireless_remote", "uint8[40]"),
        ("reserve", "uint32[4]"), ("crc", "uint32"),
    ],
    "hg/HandCmd": [
        ("motor_cmd", "sequence<hg/MotorCmd>"), ("reserve", "uint32[4]"),
    ],
    "hg/PressSensorState": [
        ("pressure", "float32[12]"), ("temperature", "float32[12]"),
        ("lost", "uint32"), ("reserve", "uint32"),
    ],
    "hg/HandState": [
        ("motor_state", "sequence<hg/MotorState>"),
        ("press_sensor_state", "sequence<hg/PressSensorState>"),
        ("imu_state", "hg/IMUState"), ("power_v", "float32"), ("power_a", "float32"),
        ("system_v", "float32"), ("device_v", "float32"), ("error", "uint32[2]"),
        ("reserve", "uint32[2]"),
    ],
    "hg/BmsCmd": [("cmd", "uint8"), ("reserve", "uint8[40]")],
    "hg/BmsState": [
        ("version_high", "uint8"), ("version_low", "uint8"), ("fn", "uint8"),
        ("cell_vol", "uint16[40]"), ("bmsvoltage", "uint32[3]"), ("current", "int32"),
        ("soc", "uint8"), ("soh", "uint8"), ("temperature", "int16[12]"),
        ("cycle", "uint16"), ("manufacturer_date", "uint16"), ("bmsstate", "uint32[5]"),
        ("reserve", "uint32[3]"),
    ],
    "hg/MainBoardState": [
        ("fan_state", "uint16[6]"), ("temperature", "int16[6]"),
        ("value", "float32[6]"), ("state", "uint32[6]"),
    ],
    "go/MotorCmd": [
        ("mode", "uint8"), ("q", "float32"), ("dq", "float32"), ("tau", "float32"),
        ("kp", "float32"), ("kd", "float32"), ("reserve", "uint32[3]"),
    ],
    "go/BmsCmd": [("off", "uint8"), ("reserve", "uint8[3]")],
    "go/LowCmd": [
        ("head", "uint8[2]"), ("level_flag", "uint8"), ("frame_reserve", "uint8"),
        ("sn", "uint32[2]"), ("version", "uint32[2]"), ("bandwidth", "uint16"),
        ("motor_cmd", "go/MotorCmd[20]"), ("bms_cmd", "go/BmsCmd"),
        ("wireless_remote", "uint8[40]"), ("led", "uint8[12]"), ("fan", "uint8[2]"),
        ("gpio", "uint8"), ("reserve", "uint32"), ("crc", "uint32"),
    ],
    "go/IMUState": [
        ("quaternion", "float32[4]"), ("gyroscope", "float32[3]"),
        ("accelerometer", "float32[3]"), ("rpy", "float32[3]"), ("temperature", "uint8"),
    ],
    "go/MotorState": [
        ("mode", "uint8"), ("q", "float32"), ("dq", "float32"), ("ddq", "float32"),
        ("tau_est", "float32"), ("q_raw", "float32"), ("dq_raw", "float32"),
        ("ddq_raw", "float32"), ("temperature", "uint8"), ("lost", "uint32"),
        ("reserve", "uint32[2]"),
    ],
    "go/BmsState": [
        ("version_high", "uint8"), ("version_low", "uint8"), ("status", "uint8"),
        ("soc", "uint8"), ("current", "int32"), ("cycle", "uint16"),
        ("bq_ntc", "uint8[2]"), ("mcu_ntc", "uint8[2]"), ("cell_vol", "uint16[15]"),
    ],
    "go/LowState": [
        ("head", "uint8[2]"), ("level_flag", "uint8"), ("frame_reserve", "uint8"),
        ("sn", "uint32[2]"), ("version", "uint32[2]"), ("bandwidth", "uint16"),
        ("imu_state", "go/IMUState"), ("motor_state", "go/MotorState[20]"),
        ("bms_state", "go/BmsState"), ("foot_force", "int16[4]"),
        ("foot_force_est", "int16[4]"), ("tick", "uint32"),
        ("wireless_remote", "uint8[40]"), ("bit_flag", "uint8"), ("adc_reel", "float32"),
        ("temperature_ntc1", "uint8"), ("temperature_ntc2", "uint8"),
        ("power_v", "float32"), ("power_a", "float32"), ("fan_frequency", "uint16[4]"),
        ("reserve", "uint32"), ("crc", "uint32"),
    ],
    # Sport-mode state (`rt/sportmodestate`), which Unitree's MuJoCo bridge also publishes.
    "go/TimeSpec": [("sec", "int32"), ("nanosec", "uint32")],
    "go/PathPoint": [
        ("t_from_start", "float32"), ("x", "float32"), ("y", "float32"), ("yaw", "float32"),
        ("vx", "float32"), ("vy", "float32"), ("vyaw", "float32"),
    ],
    "go/SportModeState": [
        ("stamp", "go/TimeSpec"), ("error_code", "uint32"), ("imu_state", "go/IMUState"),
        ("mode", "uint8"), ("progress", "float32"), ("gait_type", "uint8"),
        ("foot_raise_height", "float32"), ("position", "float32[3]"), ("body_height", "float32"),
        ("velocity", "float32[3]"), ("yaw_speed", "float32"), ("range_obstacle", "float32[4]"),
        ("foot_force", "int16[4]"), ("foot_position_body", "float32[12]"),
        ("foot_speed_body", "float32[12]"), ("path_point", "go/PathPoint[10]"),
    ],
}

# The 21 types of the corpus, in a fixed order (dependencies first).
TYPE_ORDER = [
    "hg/MotorCmd", "hg/LowCmd", "hg/IMUState", "hg/MotorState", "hg/LowState",
    "hg/HandCmd", "hg/PressSensorState", "hg/HandState", "hg/BmsCmd", "hg/BmsState",
    "hg/MainBoardState",
    "go/MotorCmd", "go/BmsCmd", "go/LowCmd", "go/IMUState", "go/MotorState",
    "go/BmsState", "go/LowState", "go/TimeSpec", "go/PathPoint", "go/SportModeState",
]
assert sorted(TYPE_ORDER) == sorted(CPP_LAYOUT)

CRC_TYPES = ("hg/LowCmd", "hg/LowState", "go/LowCmd", "go/LowState")

NS_MODULE = {"hg": "unitree_hg", "go": "unitree_go"}
NS_HEADER_DIR = {"hg": "hg", "go": "go2"}
PY_MODULES = {"hg": py_hg, "go": py_go}

PRIMITIVES = {
    # name: (struct code, size, python kind)
    "uint8": ("B", 1, "int"), "int8": ("b", 1, "int"),
    "uint16": ("H", 2, "int"), "int16": ("h", 2, "int"),
    "uint32": ("I", 4, "int"), "int32": ("i", 4, "int"),
    "float32": ("f", 4, "float"),
}


def dds_type_name(t: str) -> str:
    """'hg/LowCmd' -> 'unitree_hg::msg::dds_::LowCmd_' (the C++ getTypeName())."""
    ns, name = t.split("/")
    return f"{NS_MODULE[ns]}::msg::dds_::{name}_"


def py_typename(t: str) -> str:
    """The dotted typename cyclonedds-python uses ('.' becomes '::' on the wire)."""
    return dds_type_name(t).replace("::", ".")


@dataclass(frozen=True)
class TypeRef:
    """Parsed member type: kind is 'prim', 'struct', 'array' or 'sequence'."""
    kind: str
    name: str = ""               # primitive name or struct key ("hg/MotorCmd")
    elem: Optional["TypeRef"] = None
    length: int = 0

    def __str__(self) -> str:
        if self.kind in ("prim", "struct"):
            return self.name
        if self.kind == "array":
            return f"{self.elem}[{self.length}]"
        return f"sequence<{self.elem}>"


def parse_type(s: str) -> TypeRef:
    s = s.strip()
    m = re.fullmatch(r"sequence<(.+)>", s)
    if m:
        return TypeRef("sequence", elem=parse_type(m.group(1)))
    m = re.fullmatch(r"(.+)\[(\d+)\]", s)
    if m:
        return TypeRef("array", elem=parse_type(m.group(1)), length=int(m.group(2)))
    if s in PRIMITIVES:
        return TypeRef("prim", name=s)
    if s in CPP_LAYOUT:
        return TypeRef("struct", name=s)
    raise ValueError(f"unknown type {s!r}")


def members(t: str) -> List[Tuple[str, TypeRef]]:
    return [(n, parse_type(ty)) for n, ty in CPP_LAYOUT[t]]


# --------------------------------------------------------------------------
# Reading the C++ headers (optional cross-check of the transcription)
# --------------------------------------------------------------------------

_CPP_PRIM = {
    "uint8_t": "uint8", "int8_t": "int8", "uint16_t": "uint16", "int16_t": "int16",
    "uint32_t": "uint32", "int32_t": "int32", "float": "float32",
}


def _cpp_type(s: str) -> str:
    s = s.strip()
    m = re.fullmatch(r"std::array<(.+),\s*(\d+)>", s)
    if m:
        return f"{_cpp_type(m.group(1))}[{m.group(2)}]"
    m = re.fullmatch(r"std::vector<(.+)>", s)
    if m:
        return f"sequence<{_cpp_type(m.group(1))}>"
    m = re.fullmatch(r"::unitree_(hg|go)::msg::dds_::(\w+)_", s)
    if m:
        return f"{m.group(1)}/{m.group(2)}"
    return _CPP_PRIM[s]


def read_header_layout(git_dir: str, t: str) -> Tuple[List[Tuple[str, str]], str]:
    """Parse the private members and getTypeName() of one C++ IDL header."""
    ns, name = t.split("/")
    path = f"include/unitree/idl/{NS_HEADER_DIR[ns]}/{name}_.hpp"
    text = subprocess.run(["git", "-C", git_dir, "show", f"HEAD:{path}"],
                          check=True, capture_output=True, text=True).stdout
    cls = re.search(r"class \w+_\s*\{\s*private:(.*?)public:", text, re.S)
    if not cls:
        raise ValueError(f"cannot find class body in {path}")
    layout = []
    for line in cls.group(1).splitlines():
        m = re.match(r"\s*(.+?)\s+(\w+)_\s*(=.*)?;\s*$", line)
        if m:
            layout.append((m.group(2), _cpp_type(m.group(1))))
    tn = re.search(r"getTypeName\(\)\s*\{\s*return \"([^\"]+)\"", text)
    return layout, tn.group(1) if tn else ""


# --------------------------------------------------------------------------
# Describing Unitree's Python classes in the same grammar
# --------------------------------------------------------------------------

def _struct_key_of(cls) -> str:
    m = re.fullmatch(r"unitree_(hg|go)\.msg\.dds_\.(\w+)_", cls.__idl_typename__)
    return f"{m.group(1)}/{m.group(2)}" if m else cls.__idl_typename__


def describe_py_type(tp) -> str:
    """Normalised cyclonedds type hint -> our type grammar."""
    import typing
    if isinstance(tp, idltypes.array):
        return f"{describe_py_type(tp.subtype)}[{tp.length}]"
    if isinstance(tp, idltypes.sequence):
        if tp.max_length:
            return f"sequence<{describe_py_type(tp.subtype)},{tp.max_length}>"
        return f"sequence<{describe_py_type(tp.subtype)}>"
    if isinstance(tp, type) and issubclass(tp, idl.IdlStruct):
        return _struct_key_of(tp)
    args = typing.get_args(tp)
    if len(args) == 2 and isinstance(args[1], str):
        return args[1]
    return repr(tp)


def describe_py_class(cls) -> List[Tuple[str, str]]:
    hints = get_extended_type_hints(cls)
    return [(n, describe_py_type(tp)) for n, tp in hints.items()]


def unitree_py_class(t: str):
    ns, name = t.split("/")
    return getattr(PY_MODULES[ns], name + "_")


def compare_py_to_cpp(t: str) -> List[Dict[str, str]]:
    """Field-by-field differences between Unitree's Python class and CPP_LAYOUT."""
    cls = unitree_py_class(t)
    diffs: List[Dict[str, str]] = []
    if cls.__idl_typename__.replace(".", "::") != dds_type_name(t):
        diffs.append({"field": "(typename)", "python": cls.__idl_typename__,
                      "cpp": dds_type_name(t)})
    ext = cls.__idl_annotations__.get("extensibility")
    if ext != "final":
        diffs.append({"field": "(extensibility)", "python": str(ext), "cpp": "final"})
    py = describe_py_class(cls)
    cpp = CPP_LAYOUT[t]
    py_names = [n for n, _ in py]
    cpp_names = [n for n, _ in cpp]
    for n, ty in cpp:
        if n not in py_names:
            diffs.append({"field": n, "python": "(missing)", "cpp": ty})
    for n, ty in py:
        if n not in cpp_names:
            diffs.append({"field": n, "python": ty, "cpp": "(absent)"})
    common_py = [n for n in py_names if n in cpp_names]
    common_cpp = [n for n in cpp_names if n in py_names]
    if common_py != common_cpp:
        diffs.append({"field": "(member order)", "python": ", ".join(common_py),
                      "cpp": ", ".join(common_cpp)})
    pyd, cppd = dict(py), dict(cpp)
    for n in common_cpp:
        if pyd[n] != cppd[n]:
            diffs.append({"field": n, "python": pyd[n], "cpp": cppd[n]})
    return diffs


# --------------------------------------------------------------------------
# Building cyclonedds classes from the C++ layout
# --------------------------------------------------------------------------

_PRIM_HINT = {
    "uint8": idltypes.uint8, "int8": idltypes.int8, "uint16": idltypes.uint16,
    "int16": idltypes.int16, "uint32": idltypes.uint32, "int32": idltypes.int32,
    "float32": idltypes.float32,
}


def build_spec_classes() -> Dict[str, type]:
    """IdlStruct classes with exactly the header layout and Unitree's typenames.

    Every class is @final like Unitree's generated code; nested members refer
    to the other spec classes (never to Unitree's), so a correction in an
    inner type propagates to the types containing it.
    """
    out: Dict[str, type] = {}

    def hint(tr: TypeRef):
        if tr.kind == "prim":
            return _PRIM_HINT[tr.name]
        if tr.kind == "struct":
            return out[tr.name]
        if tr.kind == "array":
            return idltypes.array[hint(tr.elem), tr.length]
        return idltypes.sequence[hint(tr.elem)]

    for t in TYPE_ORDER:
        ns, name = t.split("/")
        fields = {n: hint(tr) for n, tr in members(t)}
        cls = idl.make_idl_struct(f"{ns}_{name}_", py_typename(t), fields)
        cls = annotate.autoid("sequential")(annotate.final(cls))
        out[t] = cls
    return out


# --------------------------------------------------------------------------
# Values: construction, JSON form, C struct image
# --------------------------------------------------------------------------

def build_object(classes: Dict[str, type], t: str, value: Dict[str, Any]):
    """Instantiate classes[t] from a plain dict tree (our JSON-like form)."""
    def conv(tr: TypeRef, v):
        if tr.kind == "prim":
            return v
        if tr.kind == "struct":
            return build_object(classes, tr.name, v)
        return [conv(tr.elem, x) for x in v]
    kwargs = {n: conv(tr, value[n]) for n, tr in members(t)}
    return classes[t](**kwargs)


def object_to_tree(t: str, obj) -> Dict[str, Any]:
    """IDL object -> plain dict tree in member order (floats stay Python floats)."""
    def conv(tr: TypeRef, v):
        if tr.kind == "prim":
            return float(v) if tr.name == "float32" else int(v)
        if tr.kind == "struct":
            return object_to_tree(tr.name, v)
        return [conv(tr.elem, x) for x in v]
    return {n: conv(tr, getattr(obj, n)) for n, tr in members(t)}


def json_number(x: float):
    """A float32 value for JSON: exact decimal text, or the non-finite strings."""
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "Infinity" if x > 0 else "-Infinity"
    # x is already exactly representable as float32; repr() of the Python float
    # is the shortest decimal that round-trips, hence converts back exactly.
    return x


def tree_to_json(t: str, tree: Dict[str, Any]) -> Dict[str, Any]:
    def conv(tr: TypeRef, v):
        if tr.kind == "prim":
            return json_number(v) if tr.name == "float32" else v
        if tr.kind == "struct":
            return tree_to_json(tr.name, v)
        return [conv(tr.elem, x) for x in v]
    return {n: conv(tr, tree[n]) for n, tr in members(t)}


def _align(off: int, a: int) -> int:
    return (off + a - 1) // a * a


def c_alignment(tr: TypeRef) -> int:
    if tr.kind == "prim":
        return PRIMITIVES[tr.name][1]
    if tr.kind == "array":
        return c_alignment(tr.elem)
    if tr.kind == "struct":
        return max(c_alignment(m) for _, m in members(tr.name))
    raise ValueError("sequences have no fixed C image")


def c_image(t: str, tree: Dict[str, Any]) -> bytes:
    """The C struct image (natural alignment, zeroed padding, little-endian)."""
    buf = bytearray()

    def put(tr: TypeRef, v):
        nonlocal buf
        if tr.kind == "prim":
            code, size, _ = PRIMITIVES[tr.name]
            buf += b"\0" * (_align(len(buf), size) - len(buf))
            buf += struct.pack("<" + code, v)
        elif tr.kind == "array":
            for x in v:
                put(tr.elem, x)
        elif tr.kind == "struct":
            a = c_alignment(tr)
            buf += b"\0" * (_align(len(buf), a) - len(buf))
            start = len(buf)
            for n, m in members(tr.name):
                put(m, v[n])
            end = _align(len(buf), a)          # tail padding
            buf += b"\0" * (end - len(buf))
            assert end - start == c_sizeof(tr.name)
        else:
            raise ValueError("sequences have no fixed C image")

    put(TypeRef("struct", name=t), tree)
    return bytes(buf)


def c_sizeof(t: str) -> int:
    off = 0
    for _, m in members(t):
        a = c_alignment(m)
        off = _align(off, a)
        if m.kind == "prim":
            off += PRIMITIVES[m.name][1]
        elif m.kind == "struct":
            off += c_sizeof(m.name)
        elif m.kind == "array":
            e = m.elem
            esz = PRIMITIVES[e.name][1] if e.kind == "prim" else c_sizeof(e.name)
            off += esz * m.length
    return _align(off, max(c_alignment(m) for _, m in members(t)))


# Table-driven CRC-32/MPEG-2 (poly 0x04C11DB7, init 0xFFFFFFFF, no reflection,
# no final xor).  Our own independent implementation, used only to cross-check
# Unitree's bitwise routine.
_MPEG2_TABLE = []
for _i in range(256):
    _c = _i << 24
    for _ in range(8):
        _c = ((_c << 1) ^ 0x04C11DB7) if _c & 0x80000000 else (_c << 1)
    _MPEG2_TABLE.append(_c & 0xFFFFFFFF)


def crc32_mpeg2(data: bytes) -> int:
    crc = 0xFFFFFFFF
    for b in data:
        crc = ((crc << 8) & 0xFFFFFFFF) ^ _MPEG2_TABLE[(crc >> 24) ^ b]
    return crc


def independent_crc(image: bytes) -> int:
    """Unitree's CRC as stated in the reference: the C image minus the trailing
    crc word, as 32-bit little-endian words fed MSB first == CRC-32/MPEG-2 over
    the image with every 4-byte word byte-swapped."""
    body = image[:-4]
    assert len(body) % 4 == 0
    swapped = b"".join(body[i:i + 4][::-1] for i in range(0, len(body), 4))
    return crc32_mpeg2(swapped)


# Fields that Unitree's Python CRC packer (utils/crc.py) packs with a *signed*
# struct code although the IDL member is unsigned (see NOTES.md).  struct.pack
# rejects values above the signed maximum, so before calling Unitree's CRC we
# hand it a copy where such values are replaced by their two's-complement
# signed equivalent: the packed bytes -- and hence the CRC -- are identical.
_SIGNED_PACKED_UNSIGNED = {
    "go/LowState": [
        ("imu_state.temperature", 8), ("motor_state[].temperature", 8),
        ("bms_state.bq_ntc[]", 8), ("bms_state.mcu_ntc[]", 8),
        ("temperature_ntc1", 8), ("temperature_ntc2", 8), ("fan_frequency[]", 16),
    ],
}


def _to_signed(v: int, bits: int) -> int:
    return v - (1 << bits) if v >= 1 << (bits - 1) else v


def crc_input_for_unitree(t: str, obj):
    """Copy of obj that Unitree's CRC packer accepts (same packed bytes)."""
    fixes = _SIGNED_PACKED_UNSIGNED.get(t)
    if not fixes:
        return obj
    shadow = copy.deepcopy(obj)
    for path, bits in fixes:
        parts = path.split(".")

        def apply(o, parts):
            head, rest = parts[0], parts[1:]
            if head.endswith("[]"):
                seq = getattr(o, head[:-2])
                if rest:
                    for el in seq:
                        apply(el, rest)
                else:
                    setattr(o, head[:-2], [_to_signed(x, bits) for x in seq])
            elif rest:
                apply(getattr(o, head), rest)
            else:
                setattr(o, head, _to_signed(getattr(o, head), bits))
        apply(shadow, parts)
    return shadow


def flat_c_fields(t: str) -> List[Tuple[str, str]]:
    """(path, primitive) of every scalar of the C image, in memory order."""
    out: List[Tuple[str, str]] = []

    def walk(prefix: str, tr: TypeRef):
        if tr.kind == "prim":
            out.append((prefix, tr.name))
        elif tr.kind == "array":
            for i in range(tr.length):
                walk(f"{prefix}[{i}]", tr.elem)
        elif tr.kind == "struct":
            for n, m in members(tr.name):
                walk(f"{prefix}.{n}" if prefix else n, m)
    walk("", TypeRef("struct", name=t))
    return out


def expand_struct_format(fmt: str) -> List[str]:
    """'<2B2xI' -> ['B', 'B', 'x', 'x', 'I'] (byte order prefix dropped)."""
    out: List[str] = []
    for count, code in re.findall(r"(\d*)([xcbB?hHiIlLqQnNefdspP])", fmt.lstrip("<>=!@")):
        out += [code] * (int(count) if count else 1)
    return out
