"""Parsed JSON (what a client publishes) straight to ROS wire bytes, with no genpy message in between.

`packer(cls)` gives a function (json_value, now) -> the bytes genpy would serialize for
`json_values.from_json(cls, json_value, now)`, generated from the message's fields once and cached. It takes the
common road itself: every field present or with a constant default, numbers of the field's own kind in range,
base64 for uint8[], times as {"secs", "nsecs"}. Anything else (a float 2.0 for an int, null for NaN, a list of
ints for uint8[], a missing header stamp, any error) goes the long way through json_values.from_json, so the result
and every error message stay exactly convert's; the tests compare the two on random and junk input."""

import base64
import io
import struct
from collections.abc import Callable

from rosbridge.codec.fields import DEFAULTS
from rosbridge.codec.fields import STRUCT_CODES as _CODES
from rosbridge.codec.fields import TIME_PART_CODES as _TIME_CODES
from rosbridge.codec.generated import define
from rosbridge.codec.json_values import from_json, parse_slot_type
from rosbridge.message_types import message_class

# The JSON values each kind of field takes on the common road (bool is not an int here, as in convert).
_KINDS = {"bool": "_BOOL", "float32": "_NUMBER", "float64": "_NUMBER"}


class _LongWay(Exception):
    """The value is not on the common road: json_values.from_json decides."""


def _check(ok):
    if not ok:
        raise _LongWay


def _time(value):
    """secs, nsecs of a {"secs", "nsecs"} object already canonical (0 <= nsecs < 1e9)."""
    _check(type(value) is dict and value.keys() <= _SECS_NSECS)
    secs, nsecs = value.get("secs", 0), value.get("nsecs", 0)
    _check(type(secs) is int and type(nsecs) is int and 0 <= nsecs < 1_000_000_000)
    return secs, nsecs


def _times(values, code):
    pairs = [part for value in values for part in _time(value)]
    return struct.pack(f"<{len(pairs)}{code}", *pairs)


def _numbers(values, kinds, code):
    _check(all(type(value) in kinds for value in values))
    return struct.pack(f"<{len(values)}{code}", *values)


def _string(value):
    _check(type(value) is str)
    return value.encode()  # (a lone surrogate raises UnicodeEncodeError: the long way then refuses it)


def _strings(values):
    return b"".join(_U32(len(data)) + data for data in map(_string, values))


def _bytes(value):
    _check(type(value) is str)
    return base64.b64decode(value, validate=True)


_SECS_NSECS = frozenset(("secs", "nsecs"))
_U32 = struct.Struct("<I").pack
_GLOBALS = {
    "_check": _check,
    "_time": _time,
    "_times": _times,
    "_numbers": _numbers,
    "_string": _string,
    "_strings": _strings,
    "_bytes": _bytes,
    "_U32": _U32,
    "_INT": frozenset((int,)),
    "_BOOL": frozenset((bool,)),
    "_NUMBER": frozenset((int, float)),
    "_MISSING": object(),
    "_join": b"".join,
}


class _Generator:
    def __init__(self):
        self.namespace = dict(_GLOBALS)
        self._packers = {}

    def constant(self, value):
        name = f"_c{len(self.namespace)}"
        self.namespace[name] = value
        return name

    def packer(self, cls):
        """The name of a generated function json_value -> bytes for cls (raising _LongWay off the common road)."""
        name = self._packers.get(cls)
        if name is None:
            name = self._packers[cls] = f"pack_{len(self._packers)}"
            define(self._source(name, cls), self.namespace, f"{name}: {cls._type} from JSON")
        return name

    def _source(self, name, cls):
        fields = list(zip(cls.__slots__, cls._slot_types))
        lines = [f"_check(type(v) is dict and v.keys() <= {self.constant(frozenset(cls.__slots__))})", "out = []"]
        codes, values = [], []  # a run of fixed-size values, packed together

        def flush():
            if codes:
                lines.append(
                    f"out.append({self.constant(struct.Struct('<' + ''.join(codes)).pack)}({', '.join(values)}))"
                )
                codes.clear()
                values.clear()

        for index, (field, slot_type) in enumerate(fields):
            base, is_array, size = parse_slot_type(slot_type)
            var = f"f{index}"
            stamp = cls._type == "std_msgs/Header" and field == "stamp"  # missing: now(), the long way
            default = "_MISSING" if stamp else self.constant(_json_default(base, is_array, size))
            lines.append(f"{var} = v.get({field!r}, {default})")
            if not is_array and base in _CODES:
                kinds = _KINDS.get(base, "_INT")
                lines.append(f"_check(type({var}) in {kinds})")
                codes.append(_CODES[base])
                values.append(var)
            elif not is_array and base in _TIME_CODES:
                codes.append(_TIME_CODES[base] * 2)
                values.append(f"*_time({var})")
            else:
                flush()
                lines.extend(self._variable(var, base, is_array, size))
        flush()
        body = "\n    ".join(lines + ["return _join(out)"])
        return f"def {name}(v):\n    {body}\n"

    def _variable(self, var, base, is_array, size):
        """Lines appending the bytes of one field that is not a single fixed-size value."""
        if not is_array:
            if base == "string":
                return [f"{var} = _string({var})", f"out.append(_U32(len({var})))", f"out.append({var})"]
            return [f"out.append({self.packer(message_class(base))}({var}))"]
        if base == "uint8":
            lines, data = [f"{var} = _bytes({var})"], var
        else:
            lines = [f"_check(type({var}) is list)"]
            if base in _CODES:
                data = f"_numbers({var}, {_KINDS.get(base, '_INT')}, {_CODES[base]!r})"
            elif base in _TIME_CODES:
                data = f"_times({var}, {_TIME_CODES[base]!r})"
            elif base == "string":
                data = f"_strings({var})"
            else:
                data = f"_join([{self.packer(message_class(base))}(x) for x in {var}])"
        if size is None:  # a variable-size array starts with its length
            lines.append(f"out.append(_U32(len({var})))")
        else:
            lines.append(f"_check(len({var}) == {size})")
        lines.append(f"out.append({data})")
        return lines


def _json_default(base, is_array, size):
    """The JSON value json_values.from_json takes for a missing field (the same value, as the client could send it)."""
    if is_array:
        if size is None:
            return "" if base == "uint8" else []
        if base == "uint8":
            return base64.b64encode(bytes(size)).decode()
        return [_json_default(base, False, None)] * size
    return DEFAULTS.get(base, {})


_cache: dict[type, Callable] = {}  # message class -> its converter


def packer(cls):
    """A function (json_value, now=None) -> the ROS wire bytes of json_values.from_json(cls, json_value, now)."""
    pack = _cache.get(cls)
    if pack is None:
        generator = _Generator()
        common_road = generator.namespace[generator.packer(cls)]

        def pack(value, now=None):
            try:
                return common_road(value)
            except (_LongWay, struct.error, OverflowError, ValueError):
                # (ValueError: bad base64, a lone surrogate; struct: a number out of the field's range)
                buffer = io.BytesIO()
                from_json(cls, value, now).serialize(buffer)
                return buffer.getvalue()

        _cache[cls] = pack
    return pack
