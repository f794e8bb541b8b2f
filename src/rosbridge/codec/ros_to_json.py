"""ROS serialized messages (the bytes rospy receives) straight to the JSON text the bridge sends: no genpy message
and no Python dict in between.

The bytes come from the bridge's own TCPROS links (rosbridge.ros_side.links).
`json_text(cls)` gives a function bytes -> text for one message type, generated from its fields once and cached
(as genpy generates its deserializers). The text is exactly `json_values.dumps(json_values.to_json(msg))` for the
message genpy would deserialize from those bytes; the tests compare the two for every message type on the machine.
`json_parts(cls)` gives the same text with each big base64 string (an image's data) left out, so that the frame
can carry those bytes as they are instead of copying them into one text.
Consecutive fixed-size fields, nested messages' included, are read with one struct call and written with one
%-format; variable-size fields (strings, arrays) are written to their own text first.

Big numeric arrays (a map's int8[] cells, 16 million of them) are written without a Python object per element:
int8[] and bool[] by bytes.translate over chunks of the bytes (_ByteTable), the wider numbers from a
memoryview cast to their type, a chunk at a time; no tuple of all the values is ever made. An array whose text is
BIG_BYTES or longer is left out of the text as ASCII bytes, one SPLICE_MARK per chunk, as the big base64 strings
are, so that the frame carries those bytes by reference instead of copying them into one text."""

import base64
import itertools
import json
import struct
import sys
from collections.abc import Callable

from genpy.rostime import _canon

from rosbridge.codec import BIG_BYTES
from rosbridge.codec.fields import BUILTIN_TYPES, parse_slot_type
from rosbridge.codec.fields import STRUCT_CODES as _CODES
from rosbridge.codec.fields import TIME_PART_CODES as _TIME_CODES
from rosbridge.codec.generated import define
from rosbridge.message_types import message_class

_FLOATS = ("float32", "float64")
_NS = 1_000_000_000
# Where json_parts left a big base64 string out. JSON text never holds a raw NUL: strings escape it as \u0000.
SPLICE_MARK = "\x00"


def _finite(x):
    """A float as JSON writes it: NaN and +-Inf are null (as json_values.to_json sends them)."""
    return x if x - x == 0 else "null"


def _floats(values):
    total = sum(values, 0.0)  # finite unless some value is not (or the sum overflows: then look at each)
    return ",".join(map(str, values if total - total == 0 else map(_finite, values)))


def _ints(values):
    return ",".join(map(str, values))


def _bools(values):
    return ",".join(["false", "true"][value] for value in values)


def _base64_text(data, spliced):
    """uint8[] as the text of a JSON string; a big one (its base64 bytes) goes to `spliced`, a mark in its place."""
    encoded = base64.b64encode(data)
    if len(encoded) < BIG_BYTES:
        return encoded.decode()
    spliced.append(encoded)
    return SPLICE_MARK


# Arrays of this many elements or fewer are written from a tuple (_ints, _floats, _bools): cheaper for a few values.
_SMALL = 64
_BYTES_CHUNK = 1 << 16  # elements of a one-byte array written at once (_ByteTable)
_NUMBERS_CHUNK = 1 << 13  # elements of a wider numeric array written at once (_Numbers)
# memoryview.cast reads numbers in the machine's byte order; ROS sends them little-endian
_LITTLE_ENDIAN = sys.byteorder == "little"


def check_length(b, end):
    """A truncated message: the error struct raises for one (a slice of a memoryview would be short, silently)."""
    if end > len(b):
        raise struct.error(f"an array runs past the end of the message ({end} > {len(b)} bytes)")


def _array_text(pieces, s):
    """The text of one array from `pieces` (ASCII bytes, in order, commas included): in line if short, else
    left out: the pieces go to `s` as they are, a SPLICE_MARK for each in the text."""
    if sum(map(len, pieces)) < BIG_BYTES:
        return b"".join(pieces).decode("ascii")
    s.extend(pieces)
    return SPLICE_MARK * len(pieces)


class _ByteTable:
    """The JSON text of an array of a one-byte type (int8, bool) from its bytes, with no Python object per element.

    Each element's text (at most `width` characters, then a comma) gets a fixed-size slot, padded with NUL
    bytes: plane k (bytes.translate with the k-th characters of the 256 texts) fills the k-th byte of every
    slot (an extended slice assignment), then one more translate deletes the padding. Planes that hold only
    padding in a chunk are left out (a map's 0 and -1 take 2-3 bytes a slot, not 5), and so is the delete when
    no plane holds any. About 10 ns per element, against 100 for a tuple of ints and a str each."""

    def __init__(self, texts):
        width = max(map(len, texts))
        padded = [text.encode("ascii").ljust(width, b"\0") for text in texts]
        self.planes = [bytes(text[k] for text in padded) for k in range(width)]
        self.commas = b"," * _BYTES_CHUNK

    def __call__(self, b, p, n, s):
        """The text of the n elements at b[p:] (n > 0): in line, or SPLICE_MARKs with the text in s (_array_text)."""
        end = p + n
        check_length(b, end)
        view = memoryview(b)
        pieces = [
            self._chunk(view[start : min(start + _BYTES_CHUNK, end)].tobytes()) for start in range(p, end, _BYTES_CHUNK)
        ]
        pieces[-1] = pieces[-1][:-1]  # (its last comma)
        return _array_text(pieces, s)

    def _chunk(self, chunk):
        """The text of the elements in `chunk` (bytes), each followed by a comma."""
        count = len(chunk)
        planes = [chunk.translate(plane) for plane in self.planes]
        padding = [plane.count(0) for plane in planes[1:]]  # (every text has a first character)
        while padding and padding[-1] == count:
            del planes[-1], padding[-1]
        slot = len(planes) + 1
        text = bytearray(slot * count)
        for k, plane in enumerate(planes):
            text[k::slot] = plane
        text[slot - 1 :: slot] = self.commas if count == _BYTES_CHUNK else self.commas[:count]
        return bytes(text.translate(None, b"\0") if any(padding) else text)


class _Numbers:
    """The JSON text of an array of wider numbers (int16 to uint64, float32, float64) from a memoryview cast to
    their type, a chunk at a time, with no tuple of them all (each value is an object only while its text is made):
    the text of _ints and _floats."""

    def __init__(self, code):
        self.code, self.size, self.floats = code, struct.calcsize(code), code in "fd"

    def __call__(self, b, p, n, s):
        """As _ByteTable's."""
        if not _LITTLE_ENDIAN:
            values = struct.unpack_from(f"<{n}{self.code}", b, p)
            return _floats(values) if self.floats else _ints(values)
        end = p + n * self.size
        check_length(b, end)
        view = memoryview(b)[p:end].cast(self.code)
        texts = [self._chunk(view[start : start + _NUMBERS_CHUNK]) for start in range(0, n, _NUMBERS_CHUNK)]
        if sum(map(len, texts)) + len(texts) < BIG_BYTES:
            return ",".join(texts)
        last = texts.pop()
        return _array_text([(text + ",").encode("ascii") for text in texts] + [last.encode("ascii")], s)

    def _chunk(self, values):
        text = ",".join(map(repr, values))  # (repr: the text json.dumps writes for an int or a float)
        if self.floats and "n" in text:  # nan, inf, -inf; a finite float's text has no n
            text = text.replace("-inf", "null").replace("inf", "null").replace("nan", "null")
        return text


# the arrays written by _ByteTable and _Numbers (uint8[] is base64; time[] and duration[], rare, from a tuple)
_ARRAYS = {
    "int8": _ByteTable([str(value - 256 if value > 127 else value) for value in range(256)]),
    "bool": _ByteTable(["false"] + ["true"] * 255),  # any byte but 0 is true, as struct's '?' and genpy's bool()
    **{base: _Numbers(code) for base, code in _CODES.items() if base not in ("bool", "int8", "uint8")},
}


def _times(values):
    """secs, nsecs, secs, nsecs, ... as JSON objects (as they are: genpy makes only single times canonical)."""
    return ",".join(['{"secs":%d,"nsecs":%d}' % pair for pair in zip(values[::2], values[1::2])])


_GLOBALS = {
    "_U32": struct.Struct("<I").unpack_from,
    "_b64text": _base64_text,
    "_str": json.encoder.encode_basestring,
    "_unpack_from": struct.unpack_from,
    "_finite": _finite,
    "_floats": _floats,
    "_ints": _ints,
    "_bools": _bools,
    "_times": _times,
    "_canon": _canon,
    "_BOOL": ("false", "true"),
    "_NS": _NS,
    **{f"_{base}_array": array for base, array in _ARRAYS.items()},
}


class Reader:
    """The source of one generated function read_<n>(b, p, s) -> (json text, position after the message); s: the
    list that receives the big base64 strings left out of the text (see json_parts). (ros_to_cbor's readers are
    made the same way.)"""

    def __init__(self, generator):
        self._generator = generator
        self.lines = []
        self._codes, self._fixed_vars, self._after = [], [], []  # the pending run of fixed-size fields
        self._template, self._args = [], []
        self._names = 0

    def var(self):
        self._names += 1
        return f"v{self._names}"

    def text(self, literal):
        self._template.append(literal.replace("%", "%%"))

    def value(self, expression):
        self._template.append("%s")
        self._args.append(expression)

    def fixed(self, codes):
        """Variables that will hold the next fixed-size values (read with the rest of the run)."""
        names = [self.var() for _ in codes]
        self._codes.append(codes)
        self._fixed_vars.extend(names)
        return names

    def after_read(self, line):
        self._after.append(line)

    def flush(self):
        """Reads the pending run of fixed-size fields."""
        if not self._codes:
            return
        layout = struct.Struct("<" + "".join(self._codes))
        name = self._generator.constant(layout.unpack_from)
        self.lines.append(f"{', '.join(self._fixed_vars)}, = {name}(b, p)")
        self.lines.append(f"p += {layout.size}")
        self.lines.extend(self._after)
        self._codes, self._fixed_vars, self._after = [], [], []

    def statement(self, line):
        """Code that reads a variable-size part (after the pending fixed-size run)."""
        self.flush()
        self.lines.append(line)

    def source(self, name):
        self.flush()
        template = "".join(self._template)
        result = f"{template!r} % ({', '.join(self._args)},)" if self._args else repr(template)
        body = "\n    ".join(self.lines + [f"return {result}, p"])
        return f"def {name}(b, p, s):\n    {body}\n"


class Generator:
    """Generates and compiles the readers of one message type and of every type nested in it, into `namespace`
    (the names the generated code uses). A subclass says what a reader is: _source(name, cls, top)."""

    def __init__(self, namespace):
        self.namespace = dict(namespace)
        self._readers = {}  # (message class, top) -> name of its reader function
        self._constants = 0

    def constant(self, value):
        self._constants += 1
        name = f"_c{self._constants}"
        self.namespace[name] = value
        return name

    def reader(self, cls, top=False):
        """The name of cls's reader, generating it (and those it calls) if needed. top: the message itself, not
        one nested in it (genpy makes the times among its own fields canonical, and no others)."""
        name = self._readers.get((cls, top))
        if name is None:
            name = self._readers[cls, top] = f"read_{len(self._readers)}"
            define(self._source(name, cls, top), self.namespace, f"{name}: {cls._type} read")
        return name


class _Generator(Generator):
    """JSON text readers."""

    def __init__(self):
        super().__init__(_GLOBALS)

    def _source(self, name, cls, top):
        reader = Reader(self)
        self._message(reader, cls, top)
        return reader.source(name)

    def _message(self, reader, cls, top):
        reader.text("{")
        for index, (field, slot_type) in enumerate(zip(cls.__slots__, cls._slot_types)):
            reader.text(("," if index else "") + json.dumps(field) + ":")
            base, is_array, size = parse_slot_type(slot_type)
            if is_array:
                self._array(reader, base, size)
            elif base in BUILTIN_TYPES:
                self._builtin(reader, base, top)
            else:
                self._message(reader, message_class(base), False)  # nested: read in line with the enclosing fields
        reader.text("}")

    @staticmethod
    def _builtin(reader, base, top):
        if base == "string":
            text = reader.var()
            reader.statement(f"(n,) = _U32(b, p); p += 4; {text} = _str(b[p:p + n].decode('utf-8', 'rosmsg')); p += n")
            reader.value(text)
        elif base in _TIME_CODES:
            secs, nsecs = reader.fixed(_TIME_CODES[base] * 2)
            if top:
                reader.after_read(f"if not 0 <= {nsecs} < _NS: {secs}, {nsecs} = _canon({secs}, {nsecs})")
            reader.text('{"secs":')
            reader.value(secs)
            reader.text(',"nsecs":')
            reader.value(nsecs)
            reader.text("}")
        else:
            (value,) = reader.fixed(_CODES[base])
            if base == "bool":
                reader.value(f"_BOOL[{value}]")
            elif base in _FLOATS:
                reader.after_read(f"if {value} - {value}: {value} = _finite({value})")
                reader.value(value)
            else:
                reader.value(value)

    def _array(self, reader, base, size):
        count = str(size) if size is not None else "n"
        if size is None:
            reader.statement("(n,) = _U32(b, p); p += 4")
        text = reader.var()
        if base == "uint8":  # uint8[] and char[]: base64 of the bytes as they are
            reader.statement(f"{text} = _b64text(memoryview(b)[p:p + {count}], s); p += {count}")  # (no copy)
            reader.text('"')
            reader.value(text)
            reader.text('"')
            return
        if base in _CODES or base in _TIME_CODES:
            code, per_item = (_TIME_CODES[base], 2) if base in _TIME_CODES else (_CODES[base], 1)
            width = struct.calcsize("<" + code) * per_item
            if size is None:
                unpack = f"_unpack_from('<%d{code}' % ({per_item} * n), b, p)"
            else:
                unpack = f"{self.constant(struct.Struct('<' + code * per_item * size).unpack_from)}(b, p)"
            join = (
                "_floats"
                if base in _FLOATS
                else "_times"
                if base in _TIME_CODES
                else "_bools"
                if base == "bool"
                else "_ints"
            )
            small = f"{join}({unpack})"  # (a few values: from a tuple)
            if base not in _ARRAYS or size is not None and size <= _SMALL:
                reader.statement(f"{text} = {small}; p += {width} * {count}")
            elif size is None:
                reader.statement(f"{text} = {small} if n <= {_SMALL} else _{base}_array(b, p, n, s); p += {width} * n")
            else:
                reader.statement(f"{text} = _{base}_array(b, p, {size}, s); p += {width * size}")
        elif base == "string":
            reader.statement(f"{text} = []")
            reader.statement(
                f"for _ in range({count}):\n"
                f"        (m,) = _U32(b, p); p += 4; {text}.append(_str(b[p:p + m].decode('utf-8', "
                f"'rosmsg'))); p += m"
            )
            reader.statement(f"{text} = ','.join({text})")
        else:
            item = self.reader(message_class(base))
            reader.statement(f"{text} = []")
            reader.statement(f"for _ in range({count}):\n        t, p = {item}(b, p, s); {text}.append(t)")
            reader.statement(f"{text} = ','.join({text})")
        reader.text("[")
        reader.value(text)
        reader.text("]")


_readers: dict[type, Callable] = {}  # message class -> its reader: (bytes, offset, spliced) -> (text, end)
_cache: dict[type, Callable] = {}  # message class -> its converter


def _reader(cls):
    read = _readers.get(cls)
    if read is None:
        generator = _Generator()
        read = _readers[cls] = generator.namespace[generator.reader(cls, top=True)]
    return read


def json_parts(cls):
    """A function bytes -> (text, spliced) for the message of class cls serialized in them: its JSON text with a
    SPLICE_MARK where each big base64 string goes, and those strings (bytes, ASCII) in order."""
    convert = _cache.get(cls)
    if convert is None:
        read = _reader(cls)

        def convert(data):
            spliced = []
            return read(data, 0, spliced)[0], spliced

        _cache[cls] = convert
    return convert


_fixed_sizes: dict = {}  # class -> fixed_size(class)


def fixed_size(cls):
    """The bytes that every serialized message of class cls takes, or None when that depends on its values (a
    string or an array of no set length among its fields, nested ones' included)."""
    if cls in _fixed_sizes:
        return _fixed_sizes[cls]
    total = 0
    for slot_type in cls._slot_types:
        base, is_array, count = parse_slot_type(slot_type)
        if base in _CODES:
            size = struct.calcsize("<" + _CODES[base])
        elif base in _TIME_CODES:
            size = struct.calcsize("<" + _TIME_CODES[base] * 2)
        elif base in BUILTIN_TYPES:  # (string)
            size = None
        else:
            size = fixed_size(message_class(base))
        if size is None or (is_array and count is None):
            total = None
            break
        total += size * (count if is_array else 1)
    _fixed_sizes[cls] = total
    return total


def check_whole(cls, data):
    """Raises ValueError unless `data` is exactly one serialized message of class cls (a client's bytes). A type of
    fixed size (a Twist: 48 bytes) is checked by its length alone: any bytes of that length read as one."""
    size = fixed_size(cls)
    if size is not None:
        if len(data) != size:
            raise ValueError(f"{len(data)} bytes, but a {cls._type} takes {size}")
        return
    try:
        end = _reader(cls)(data, 0, [])[1]
    except (struct.error, IndexError, UnicodeDecodeError) as error:
        raise ValueError(f"not a whole {cls._type} ({len(data)} bytes): {error}") from None
    if end != len(data):
        raise ValueError(f"{len(data)} bytes, but a {cls._type} of these fields takes {end}")


def joined(text, spliced):
    """The whole text of what json_parts gave."""
    if not spliced:
        return text
    pieces = text.split(SPLICE_MARK)
    return "".join(itertools.chain.from_iterable(zip(pieces, [part.decode() for part in spliced] + [""])))


def json_text(cls):
    """A function bytes -> the JSON text of the message of class cls serialized in them (see the module)."""
    parts = json_parts(cls)
    return lambda data: joined(*parts(data))
