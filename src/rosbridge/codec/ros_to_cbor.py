"""ROS serialized messages (the bytes read from TCPROS) straight to the values cbor2 writes for `compression: cbor`:
no genpy message in between.

`cbor_value(cls)` gives a function bytes -> value, generated from the type's fields once and cached (as
ros_to_json does for JSON text). The value is what cbor.to_cbor_value gives for the message genpy would deserialize
from those bytes, and cbor2 writes the same bytes for both (the tests compare them for every message type on the
machine), with one difference on purpose: a float32[] holds the float32 bits as ROS sent them, where the road
through genpy turns a signalling NaN into a quiet one.

Arrays of numbers are never unpacked: each is an RFC 8746 little-endian typed array (the tags of
cbor.TYPED_ARRAY_TAGS, which roslibjs reads into JavaScript typed arrays) whose payload is the array's bytes as
they are in the message, and uint8[]/char[] a byte string of them. A big one (BIG_BYTES or more) is a view of the
message's bytes, which cbor.cbor_parts writes by reference: a 16 MB map or a 5 MB point cloud is not copied at all
on its way to the socket."""

import struct
from collections.abc import Callable

from cbor2 import CBORTag
from genpy.rostime import _canon

from rosbridge.codec.cbor import TYPED_ARRAY_TAGS, byte_string
from rosbridge.codec.fields import BUILTIN_TYPES, STRUCT_CODES, TIME_PART_CODES, parse_slot_type
from rosbridge.codec.ros_to_json import Generator, Reader, check_length
from rosbridge.message_types import message_class

_NS = 1_000_000_000


def _bytes_of(b, p, size):
    """The `size` bytes at b[p:]: a copy if small, a view if big (see cbor.byte_string)."""
    end = p + size
    check_length(b, end)
    return byte_string(memoryview(b)[p:end])


def _typed_array(tag, b, p, size):
    return CBORTag(tag, _bytes_of(b, p, size))


def _times(values):
    """secs, nsecs, secs, nsecs, ... as {"secs", "nsecs"} (as they are: genpy makes only single times canonical)."""
    return [{"secs": secs, "nsecs": nsecs} for secs, nsecs in zip(values[::2], values[1::2])]


def _decode(b, p, n):
    return b[p : p + n].decode("utf-8", "rosmsg")


_GLOBALS = {
    "_U32": struct.Struct("<I").unpack_from,
    "_unpack_from": struct.unpack_from,
    "_decode": _decode,
    "_bytes_of": _bytes_of,
    "_typed_array": _typed_array,
    "_times": _times,
    "_canon": _canon,
    "_NS": _NS,
}


class _ValueReader(Reader):
    """The source of one generated function read_<n>(b, p) -> (value, position after the message)."""

    def source(self, name, expression):
        self.flush()
        body = "\n    ".join(self.lines + [f"return {expression}, p"])
        return f"def {name}(b, p):\n    {body}\n"


class _Generator(Generator):
    """CBOR value readers."""

    def __init__(self):
        super().__init__(_GLOBALS)

    def _source(self, name, cls, top):
        reader = _ValueReader(self)
        return reader.source(name, self._message(reader, cls, top))

    def _message(self, reader, cls, top):
        """Reads the fields of a cls (in line); -> the expression of its value, a dict display."""
        items = []
        for field, slot_type in zip(cls.__slots__, cls._slot_types):
            base, is_array, size = parse_slot_type(slot_type)
            if is_array:
                value = self._array(reader, base, size)
            elif base in BUILTIN_TYPES:
                value = self._builtin(reader, base, top)
            else:
                value = self._message(reader, message_class(base), False)
            items.append(f"{field!r}: {value}")
        return "{" + ", ".join(items) + "}"

    @staticmethod
    def _builtin(reader, base, top):
        if base == "string":
            text = reader.var()
            reader.statement(f"(n,) = _U32(b, p); p += 4; {text} = _decode(b, p, n); p += n")
            return text
        if base in TIME_PART_CODES:
            secs, nsecs = reader.fixed(TIME_PART_CODES[base] * 2)
            if top:
                reader.after_read(f"if not 0 <= {nsecs} < _NS: {secs}, {nsecs} = _canon({secs}, {nsecs})")
            return f"{{'secs': {secs}, 'nsecs': {nsecs}}}"
        (value,) = reader.fixed(STRUCT_CODES[base])  # (bool: '?', True or False as genpy's bool())
        return value

    def _array(self, reader, base, size):
        count = str(size) if size is not None else "n"
        if size is None:
            reader.statement("(n,) = _U32(b, p); p += 4")
        value = reader.var()
        if base == "uint8":
            reader.statement(f"{value} = _bytes_of(b, p, {count}); p += {count}")
        elif base in TYPED_ARRAY_TAGS:
            tag, code = TYPED_ARRAY_TAGS[base]
            width = struct.calcsize("<" + code)
            reader.statement(f"{value} = _typed_array({tag}, b, p, {width} * {count}); p += {width} * {count}")
        elif base == "bool":
            reader.statement(f"{value} = list(_unpack_from('<%d?' % {count}, b, p)); p += {count}")
        elif base in TIME_PART_CODES:
            reader.statement(
                f"{value} = _times(_unpack_from('<%d{TIME_PART_CODES[base]}' % (2 * {count}), b, p)); p += 8 * {count}"
            )
        elif base == "string":
            reader.statement(f"{value} = []")
            reader.statement(
                f"for _ in range({count}):\n        (m,) = _U32(b, p); p += 4; {value}.append(_decode(b, p, m)); p += m"
            )
        else:
            item = self.reader(message_class(base))
            reader.statement(f"{value} = []")
            reader.statement(f"for _ in range({count}):\n        t, p = {item}(b, p); {value}.append(t)")
        return value


_cache: dict[type, Callable] = {}  # message class -> its converter


def cbor_value(cls):
    """A function bytes -> the value of the message of class cls serialized in them, for cbor.cbor_parts."""
    convert = _cache.get(cls)
    if convert is None:
        generator = _Generator()
        read = generator.namespace[generator.reader(cls, top=True)]

        def convert(data):
            return read(data, 0)[0]

        _cache[cls] = convert
    return convert
