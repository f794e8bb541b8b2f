"""ROS messages -> CBOR (`compression: cbor`), with RFC 8746 typed arrays as rosbridge sends them, and a
frame's CBOR as parts (the big byte strings left out, written by reference). Topics' messages come from their bytes
(ros_to_cbor.py) to the same values; to_cbor_value here is the road from message objects (service responses).

As the reference (rosbridge_library's cbor_conversion) and roslibjs (cborTypedArrayTags) have it: uint8[] and char[]
are byte strings (Uint8Array in roslibjs), the other numeric arrays typed arrays with the little-endian tags below
(int8 72, uint16 69, int16 77, uint32 70, int32 78, uint64 71, int64 79, float32 85, float64 86: JavaScript typed
arrays, the 64-bit ones read into plain arrays of numbers), bool[] and string[] plain arrays. The reference tags
only variable-size arrays; here fixed-size ones are tagged too (roslibjs reads both the same)."""

import functools
import os
import struct

import cbor2

from rosbridge.codec import BIG_BYTES
from rosbridge.codec.json_values import encoder_factory, json_leaf_encoder

# RFC 8746 tags of the little-endian typed arrays, with the matching struct codes. uint8 arrays go as plain
# CBOR byte strings instead, as the reference sends them.
TYPED_ARRAY_TAGS = {
    "int8": (72, "b"),
    "uint16": (69, "H"),
    "int16": (77, "h"),
    "uint32": (70, "I"),
    "int32": (78, "i"),
    "uint64": (71, "Q"),
    "int64": (79, "q"),
    "float32": (85, "f"),
    "float64": (86, "d"),
}
_UINT, _BYTES = 0x00, 0x40  # CBOR's major types 0 (an unsigned integer) and 2 (a byte string), in a head's top bits


def _typed_array(tag, code):
    return lambda items: cbor2.CBORTag(tag, byte_string(struct.pack(f"<{len(items)}{code}", *items)))


class _Spliced:
    """A big byte string (an image's data), which cbor_parts leaves out of cbor2's output."""

    __slots__ = ("data",)

    def __init__(self, data):
        self.data = data


def byte_string(value):
    """A uint8[] (bytes, or a memoryview of a message's bytes) for cbor_parts: a big one left out of cbor2's output."""
    if len(value) >= BIG_BYTES:
        return _Spliced(value)
    return value if isinstance(value, bytes) else bytes(value)


def _cbor_leaf_encoder(base, is_array):
    if not is_array:
        # CBOR carries NaN and +-Inf, so floats go as they are; time/duration as in JSON
        return None if base in ("float32", "float64") else json_leaf_encoder(base, is_array)
    if base == "uint8":
        return byte_string
    if base in TYPED_ARRAY_TAGS:
        return _typed_array(*TYPED_ARRAY_TAGS[base])
    return json_leaf_encoder(base, is_array)


_cbor_encoder_for = encoder_factory(_cbor_leaf_encoder)


def to_cbor_value(msg):
    """The message as Python values for cbor2: like json_values.to_json, but uint8[]/char[] as bytes, other
    numeric arrays (fixed or variable) as RFC 8746 little-endian typed arrays, and NaN/Inf kept."""
    return _cbor_encoder_for(type(msg))(msg)


def cbor_parts(obj):
    """`obj` (e.g. a publish op whose msg is to_cbor_value(...)) in CBOR, as parts to send one after another. cbor2
    encodes each big byte string as a 16-byte stand-in, whose place then holds the head of the real string and
    the bytes themselves, not copied: cbor2 alone takes over ten times longer."""
    try:
        return [cbor2.dumps(obj, default=_refuse_spliced)]
    except _HasSpliced:
        pass
    spliced = []

    def stand_in(encoder, value):
        _refuse_other(value)
        token = os.urandom(16)
        spliced.append((token, value.data))
        encoder.encode(token)

    encoded, parts, start = cbor2.dumps(obj, default=stand_in), [], 0
    for token, data in spliced:  # (in the order cbor2 wrote them)
        place = encoded.index(_head(_BYTES, 16) + token, start)
        parts += (encoded[start:place] + _head(_BYTES, len(data)), data)
        start = place + 17
    parts.append(encoded[start:])
    return parts


def raw_publish_parts(topic, data, stamp):
    """The publish op of a `compression: cbor-raw` subscriber, {"op": "publish", "topic": topic, "msg": {"bytes":
    data, "secs": s, "nsecs": ns}} (data: the message's ROS bytes; stamp: its receipt time in seconds), as
    cbor2 writes it, in parts as cbor_parts has them. Made here, not by cbor2: the op's head is made once per
    topic (a message at 1 kHz costs a join), and big bytes (a camera image, a cloud) are never copied: they go
    by reference, as the CBOR road sends a big uint8[]."""
    secs = int(stamp)
    head = _raw_head(topic) + _head(_BYTES, len(data))
    tail = b"dsecs" + _head(_UINT, secs) + b"ensecs" + _head(_UINT, int((stamp - secs) * 1e9))
    if len(data) >= BIG_BYTES:
        return [head, data, tail]
    return [b"".join((head, data, tail))]


@functools.lru_cache(maxsize=1024)  # (the topics a bridge serves: a few dozen)
def _raw_head(topic):
    """A map of three pairs, "op": "publish", "topic": topic, "msg": then a map of three pairs and "bytes"."""
    return b"\xa3bopgpublishetopic" + cbor2.dumps(topic) + b"cmsg\xa3ebytes"


class _HasSpliced(Exception):
    pass


def _refuse_spliced(encoder, value):
    _refuse_other(value)
    raise _HasSpliced


def _refuse_other(value):
    if not isinstance(value, _Spliced):
        raise cbor2.CBOREncodeTypeError(f"cannot serialize type {type(value).__name__}")


def _head(major, value):
    """The head of a CBOR data item of major type `major` whose argument is `value` (an unsigned integer's value,
    a byte string's length), in its shortest form (RFC 8949 section 3), as cbor2 writes it."""
    if value < 24:
        return bytes((major | value,))
    for info, size in ((24, 1), (25, 2), (26, 4), (27, 8)):
        if value < 1 << (8 * size):
            return bytes((major | info,)) + value.to_bytes(size, "big")
    raise ValueError(f"{value}: too big for CBOR")
