"""The one table of ROS field types that every converter of rosbridge.codec reads: the built-in types, their
ranges and defaults, how ROS serializes each (struct codes), and how a message's slot type is parsed."""

import re

import genpy

INT_RANGES = {
    "int8": (-(2**7), 2**7 - 1),
    "uint8": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}
FLOAT_TYPES = ("float32", "float64")
# How ROS serializes the fixed-size fields (little-endian struct codes; a bool packs as '?', one byte 0 or 1, and
# any non-zero byte reads as true, as genpy's bool()), and each of the two parts of a time or duration.
STRUCT_CODES = {
    "bool": "?",
    "int8": "b",
    "uint8": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}
TIME_PART_CODES = {"time": "I", "duration": "i"}
TIME_TYPES = {"time": genpy.Time, "duration": genpy.Duration}
# ROS 1 aliases: byte is signed, char is unsigned.
_ALIASES = {"byte": "int8", "char": "uint8"}
BUILTIN_TYPES = {"bool", "string", *INT_RANGES, *FLOAT_TYPES, *TIME_TYPES}

_SLOT_TYPE = re.compile(r"([^\[\]]+)(?:\[(\d*)\])?")


def parse_slot_type(slot_type):
    """'float64[9]' -> ('float64', True, 9); 'uint8[]' -> ('uint8', True, None); 'char' -> ('uint8', False, None)."""
    match = _SLOT_TYPE.fullmatch(slot_type)
    if not match:
        raise ValueError(f"unsupported field type {slot_type!r}")
    base, size = match.groups()
    is_array = size is not None
    return _ALIASES.get(base, base), is_array, int(size) if size else None


# what a field a client leaves out is (a message's own fields: their defaults, recursively)
DEFAULTS = {"bool": False, "string": "", "float32": 0.0, "float64": 0.0, **{base: 0 for base in INT_RANGES}}
