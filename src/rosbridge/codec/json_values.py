"""ROS messages <-> JSON-ready Python values, as the rosbridge v2 protocol carries them.

Both directions run for every message the bridge forwards, so each message class gets its converters built
once (from its _slot_types) and cached; a call then only walks prepared tuples.

ROS -> JSON (`to_json`): bool, ints, strings as they are; float32/float64 as floats, NaN and +-Inf as None
(JSON has no such numbers); time/duration as {"secs", "nsecs"}; uint8[] and char[] (fixed or variable) as a
base64 string; other arrays as lists; nested messages as dicts. Constants are not fields and are not sent.

JSON -> ROS (`from_json`), strict wherever a silent guess could move a robot the wrong way:
- a missing field takes its default; an unknown field is an error;
- integer fields take JSON integers within the field's range; an integral float such as 2.0 is accepted
  (some clients write every number as a float), 2.5 and true/false are refused;
- float fields take any number; null means NaN (what `to_json` sends for NaN/Inf); float32 must fit;
- bool fields take true/false only; string fields take strings only;
- uint8[]/char[] take a base64 string or a list of ints 0..255;
- time/duration take {"secs", "nsecs"} (either may be missing) or a number of seconds;
- fixed-size arrays need exactly their length;
- with `now` given, a std_msgs/Header whose stamp is missing (also a header missing altogether) gets now().
Every refusal is a ConversionError whose message starts with the path of the field, e.g. `linear.x: ...`.
"""

import base64
import binascii
import json
import keyword
import math
import reprlib
import struct
from collections.abc import Callable

import genpy

from rosbridge.codec.fields import BUILTIN_TYPES, DEFAULTS, FLOAT_TYPES, INT_RANGES, TIME_TYPES, parse_slot_type
from rosbridge.codec.generated import define
from rosbridge.errors import ClientError
from rosbridge.message_types import message_class

_FLOAT32 = struct.Struct("<f")
_FLOAT32_MAX = 3.4028234663852886e38


class ConversionError(ClientError):
    """A JSON value that does not fit the message field it is meant for. str() names the field path."""

    def __init__(self, problem, path=()):
        self.problem = problem
        self.path = path
        super().__init__(f"{format_path(path)}: {problem}" if path else problem)

    def within(self, step):
        """The same error seen from the enclosing value: `step` is a field name or an array index."""
        return ConversionError(self.problem, (step,) + self.path)


def format_path(path):
    text = ""
    for step in path:
        text += f"[{step}]" if isinstance(step, int) else f".{step}" if text else step
    return text


_SHORT = reprlib.Repr()
_SHORT.maxstring, _SHORT.maxother, _SHORT.maxlist, _SHORT.maxdict, _SHORT.maxlevel = 60, 60, 5, 3, 2


def _describe(value):
    """A short description of a JSON value for an error message (bounded cost, even for huge values)."""
    return "null" if value is None else f"{type(value).__name__} {_SHORT.repr(value)}"


def dumps(obj):
    """Compact JSON text, the one way every part of the bridge writes JSON."""
    # CPython escapes long strings ~20x faster for ASCII output (a 640x480 image: 1 ms instead of 26 ms). Without
    # any \u escape in it, the ASCII text is exactly what the Unicode encoder writes; otherwise write that, unless
    # it holds half a surrogate pair (a client's JSON may escape one alone), which has no UTF-8: then the escaped
    # text (valid JSON that every client reads the same).
    text = _ASCII_JSON_ENCODER(obj)
    if "\\u" not in text:
        return text
    unicode_text = _JSON_ENCODER(obj)
    try:
        unicode_text.encode()
    except UnicodeEncodeError:
        return text
    return unicode_text


_JSON_ENCODER = json.JSONEncoder(separators=(",", ":"), allow_nan=False, ensure_ascii=False).encode
_ASCII_JSON_ENCODER = json.JSONEncoder(separators=(",", ":"), allow_nan=False).encode


# ---------------------------------------------------------------------------------------------------------
# ROS -> Python values


def _record_encoder(fields):
    """A function msg -> dict for the (name, converter) fields; converter None means the value as it is.

    It is generated from source once per class (as dataclasses does): a plain dict display runs about four
    times faster than a generic loop over the fields, and it runs for every message the bridge sends."""
    namespace = {}
    items = []
    for index, (name, converter) in enumerate(fields):
        if not name.isidentifier() or keyword.iskeyword(name):
            raise ValueError(f"unsupported field name {name!r}")
        value = f"msg.{name}"
        if converter is not None:
            namespace[f"convert{index}"] = converter
            value = f"convert{index}({value})"
        items.append(f"{name!r}: {value}")
    define(f"def encode(msg):\n    return {{{', '.join(items)}}}\n", namespace, "a message's JSON encoder")
    return namespace["encode"]


def encoder_factory(leaf_encoder):
    """encoder_for(cls) -> cached function msg -> dict, for one flavour of output (JSON here, CBOR in cbor.py).

    leaf_encoder(base, is_array) gives the converter of a non-message field (base is a key of BUILTIN_TYPES,
    aliases resolved), or None where the value is used as it is. Messages and arrays of them are handled here."""
    cache = {}

    def encoder_for(cls):
        encoder = cache.get(cls)
        if encoder is None:
            fields = []
            for name, slot_type in zip(cls.__slots__, cls._slot_types):
                base, is_array, _ = parse_slot_type(slot_type)
                if base in BUILTIN_TYPES:
                    converter = leaf_encoder(base, is_array)
                else:
                    nested = encoder_for(message_class(base))
                    converter = (lambda items, nested=nested: [nested(item) for item in items]) if is_array else nested
                fields.append((name, converter))
            encoder = cache[cls] = _record_encoder(fields)
        return encoder

    return encoder_for


def _finite_or_none(value):
    return value if math.isfinite(value) else None


def time_to_json(value):
    return {"secs": value.secs, "nsecs": value.nsecs}


def _base64(value):
    return base64.b64encode(value if isinstance(value, bytes) else bytes(value)).decode("ascii")


def json_leaf_encoder(base, is_array):
    if base in FLOAT_TYPES:
        return (lambda items: [_finite_or_none(x) for x in items]) if is_array else _finite_or_none
    if base in TIME_TYPES:
        return (lambda items: [time_to_json(x) for x in items]) if is_array else time_to_json
    if not is_array:
        return None
    if base == "uint8":
        return _base64
    return list  # genpy gives fixed arrays (and some deserialized ones) as tuples


_json_encoder_for = encoder_factory(json_leaf_encoder)


def to_json(msg):
    """The message as plain JSON-ready Python values (dict/list/str/int/float/bool/None)."""
    return _json_encoder_for(type(msg))(msg)


# ---------------------------------------------------------------------------------------------------------
# Python values (parsed JSON) -> ROS


def _int_decoder(base):
    low, high = INT_RANGES[base]

    def decode(value, now=None):
        if type(value) is not int:
            if type(value) is float and value.is_integer():
                value = int(value)
            else:
                raise ConversionError(f"expected an integer ({base}), got {_describe(value)}")
        if low <= value <= high:
            return value
        raise ConversionError(f"{value} is out of range for {base} ({low}..{high})")

    return decode


def _float_decoder(base):
    check_float32 = base == "float32"

    def decode(value, now=None):
        kind = type(value)
        if kind is int:
            try:
                value = float(value)
            except OverflowError:
                raise ConversionError(f"{value} is out of range for {base}") from None
        elif value is None:
            return math.nan  # to_json's rendering of NaN and +-Inf
        elif kind is not float:
            raise ConversionError(f"expected a number, got {_describe(value)}")
        if check_float32 and not -_FLOAT32_MAX <= value <= _FLOAT32_MAX and math.isfinite(value):
            try:  # values just above the maximum still round to it
                _FLOAT32.pack(value)
            except OverflowError:
                raise ConversionError(f"{value} is out of range for float32") from None
        return value

    return decode


def _decode_bool(value, now=None):
    if type(value) is bool:
        return value
    raise ConversionError(f"expected true or false, got {_describe(value)}")


def _decode_string(value, now=None):
    if type(value) is not str:
        raise ConversionError(f"expected a string, got {_describe(value)}")
    if not value.isascii():
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            raise ConversionError("string is not valid Unicode (it holds a lone surrogate)") from None
    return value


def _time_decoder(base):
    tval = TIME_TYPES[base]
    secs_type, nsecs_type = ("uint32", "uint32") if base == "time" else ("int32", "int32")
    decode_secs, decode_nsecs = _int_decoder(secs_type), _int_decoder(nsecs_type)
    low, high = INT_RANGES[secs_type]

    def decode(value, now=None):
        kind = type(value)
        if kind is dict:
            unknown = value.keys() - {"secs", "nsecs"}
            if unknown:
                raise ConversionError(f"unknown field {min(map(str, unknown))!r} in {base}")
            parts = []
            for key, decode_part in (("secs", decode_secs), ("nsecs", decode_nsecs)):
                try:
                    parts.append(decode_part(value.get(key, 0)))
                except ConversionError as error:
                    raise error.within(key) from None
            result = tval(*parts)
        elif (kind is int or kind is float) and math.isfinite(value) and low <= value <= high:
            result = tval.from_sec(value)
        else:
            raise ConversionError(
                f'expected {{"secs": ..., "nsecs": ...}} or a number of seconds in {base} range, got {_describe(value)}'
            )
        if not low <= result.secs <= high:  # genpy carries whole seconds out of nsecs
            raise ConversionError(f"{base} {result.secs}.{result.nsecs:09d} s is out of range")
        return result

    return decode


def _bytes_decoder(size):
    def decode(value, now=None):
        if type(value) is str:
            try:
                value = base64.b64decode(value, validate=True)
            except (binascii.Error, ValueError):
                raise ConversionError(
                    "expected base64 text or a list of ints 0..255, got a string that is not valid base64"
                ) from None
        elif type(value) is list:
            for index, item in enumerate(value):
                if type(item) is not int or not 0 <= item <= 255:
                    raise ConversionError(f"expected an integer 0..255, got {_describe(item)}", (index,))
            value = bytes(value)
        else:
            raise ConversionError(f"expected base64 text or a list of ints 0..255, got {_describe(value)}")
        if size is not None and len(value) != size:
            raise ConversionError(f"expected exactly {size} bytes, got {len(value)}")
        return value

    return decode


def _array_decoder(decode_item, size):
    def decode(value, now=None):
        if type(value) is not list:
            raise ConversionError(f"expected an array, got {_describe(value)}")
        if size is not None and len(value) != size:
            raise ConversionError(f"expected exactly {size} elements, got {len(value)}")
        result = []
        index = 0
        try:
            for index, item in enumerate(value):  # noqa: B007  (the failing index is told below)
                result.append(decode_item(item, now))
        except ConversionError as error:
            raise error.within(index) from None
        return result

    return decode


def _leaf_decoder(base):
    if base in INT_RANGES:
        return _int_decoder(base)
    if base in FLOAT_TYPES:
        return _float_decoder(base)
    if base in TIME_TYPES:
        return _time_decoder(base)
    return _decode_bool if base == "bool" else _decode_string


def _constant(value):
    return lambda now=None: value


# The value of a field missing from the JSON (times and messages: an empty object).


def _field_default(base, is_array, size, decode):
    """A function now -> a fresh default value for a field missing from the JSON."""
    if not is_array and base in DEFAULTS:
        return _constant(DEFAULTS[base])
    if base == "uint8" and is_array:
        return _constant(bytes(size or 0))
    # Mutable values (lists, times, messages) must be new for every message: decode a JSON default.
    json_default = {} if not is_array else [] if size is None else [DEFAULTS.get(base, {})] * size
    return lambda now=None: decode(json_default, now)


_decoders: dict[type, Callable] = {}  # message class -> its converter


def _stamp_default(now=None):
    return now() if now is not None else genpy.Time()


def _decoder_for(cls):
    """A cached function (json_value, now) -> new instance of cls."""
    decoder = _decoders.get(cls)
    if decoder is not None:
        return decoder
    fields = []
    for name, slot_type in zip(cls.__slots__, cls._slot_types):
        base, is_array, size = parse_slot_type(slot_type)
        if base == "uint8" and is_array:
            decode = _bytes_decoder(size)
        else:
            decode = _leaf_decoder(base) if base in BUILTIN_TYPES else _decoder_for(message_class(base))
            if is_array:
                decode = _array_decoder(decode, size)
        default = _field_default(base, is_array, size, decode)
        if cls._type == "std_msgs/Header" and name == "stamp":
            default = _stamp_default
        fields.append((name, decode, default))
    names = frozenset(name for name, _, _ in fields)
    type_name = cls._type

    def decode_message(value, now=None):
        if type(value) is not dict:
            raise ConversionError(f"expected an object ({type_name}), got {_describe(value)}")
        if not value.keys() <= names:
            unknown = min(map(str, value.keys() - names))
            raise ConversionError(f"unknown field {unknown!r} in {type_name}")
        msg = cls.__new__(cls)
        for name, decode, default in fields:
            if name in value:
                try:
                    setattr(msg, name, decode(value[name], now))
                except ConversionError as error:
                    raise error.within(name) from None
            else:
                setattr(msg, name, default(now))
        return msg

    _decoders[cls] = decode_message
    return decode_message


def from_json(msg_class, obj, now=None):
    """A new msg_class instance from JSON-parsed `obj` (a dict). `now`: zero-arg callable -> genpy.Time, used
    for header stamps missing from `obj`. Raises ConversionError naming the offending field."""
    return _decoder_for(msg_class)(obj, now)


def request_from_args(request_class, args, now=None):
    """A service request from call_service `args`: an object of fields, a list of values in field order,
    or None/missing for an all-default request."""
    if args is None:
        args = {}
    elif type(args) is list:
        names = request_class.__slots__
        if len(args) != len(names):
            raise ConversionError(
                f"expected {len(names)} positional args ({', '.join(names) or 'none'}), got {len(args)}"
            )
        args = dict(zip(names, args))
    elif type(args) is not dict:
        raise ConversionError(f"expected an object or a list, got {_describe(args)}", ("args",))
    return from_json(request_class, args, now)
