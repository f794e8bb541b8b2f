"""ROS serialized messages (the bytes rospy receives) straight to the JSON text the bridge sends: no genpy message
and no Python dict in between.

The bytes come from the bridge's own TCPROS links (rosbridge.ros_side.links).
`json_text(cls)` gives a function bytes -> text for one message type, generated from its fields once and cached
(as genpy generates its deserializers). The text is exactly `convert.dumps(convert.to_json(msg))` for the message
genpy would deserialize from those bytes; the tests compare the two for every message type on the machine.
`json_parts(cls)` gives the same text with each big base64 string (an image's data) left out, so that the frame
can carry those bytes as they are instead of copying them into one text.
Consecutive fixed-size fields, nested messages' included, are read with one struct call and written with one
%-format; variable-size fields (strings, arrays) are written to their own text first."""
import base64
import itertools
import json
import struct

from genpy.rostime import _canon

from rosbridge.codec.fields import BUILTIN_TYPES, STRUCT_CODES as _CODES, TIME_PART_CODES as _TIME_CODES, parse_slot_type
from rosbridge.codec import BIG_BYTES
from rosbridge.types import message_class

_FLOATS = ("float32", "float64")
_NS = 1_000_000_000
# Where json_parts left a big base64 string out. JSON text never holds a raw NUL: strings escape it as \u0000.
SPLICE_MARK = "\x00"


def _finite(x):
    """A float as JSON writes it: NaN and +-Inf are null (as convert.to_json sends them)."""
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


def _times(values):
    """secs, nsecs, secs, nsecs, ... as JSON objects (as they are: genpy makes only single times canonical)."""
    return ",".join(['{"secs":%d,"nsecs":%d}' % pair for pair in zip(values[::2], values[1::2])])


_GLOBALS = {
    "_U32": struct.Struct("<I").unpack_from, "_b64text": _base64_text, "_str": json.encoder.encode_basestring,
    "_unpack_from": struct.unpack_from, "_finite": _finite, "_floats": _floats, "_ints": _ints, "_bools": _bools,
    "_times": _times, "_canon": _canon, "_BOOL": ("false", "true"), "_NS": _NS,
}


class _Reader:
    """The source of one generated function read_<n>(b, p, s) -> (json text, position after the message); s: the
    list that receives the big base64 strings left out of the text (see json_parts)."""

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


class _Generator:
    """Generates and compiles the readers of one message type and of every type nested in it."""

    def __init__(self):
        self.namespace = dict(_GLOBALS)
        self._readers = {}  # message class -> name of its reader function
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
            reader = _Reader(self)
            self._message(reader, cls, top)
            exec(reader.source(name), self.namespace)
        return name

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
            reader.statement(f"(n,) = _U32(b, p); p += 4; {text} = _str(b[p:p + n].decode('utf-8', 'rosmsg')); "
                             "p += n")
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
            join = "_floats" if base in _FLOATS else "_times" if base in _TIME_CODES else \
                "_bools" if base == "bool" else "_ints"
            reader.statement(f"{text} = {join}({unpack}); p += {width} * {count}")
        elif base == "string":
            reader.statement(f"{text} = []")
            reader.statement(f"for _ in range({count}):\n"
                             f"        (m,) = _U32(b, p); p += 4; {text}.append(_str(b[p:p + m].decode('utf-8', "
                             f"'rosmsg'))); p += m")
            reader.statement(f"{text} = ','.join({text})")
        else:
            item = self.reader(message_class(base))
            reader.statement(f"{text} = []")
            reader.statement(f"for _ in range({count}):\n        t, p = {item}(b, p, s); {text}.append(t)")
            reader.statement(f"{text} = ','.join({text})")
        reader.text("[")
        reader.value(text)
        reader.text("]")


_cache = {}


def json_parts(cls):
    """A function bytes -> (text, spliced) for the message of class cls serialized in them: its JSON text with a
    SPLICE_MARK where each big base64 string goes, and those strings (bytes, ASCII) in order."""
    convert = _cache.get(cls)
    if convert is None:
        generator = _Generator()
        read = generator.namespace[generator.reader(cls, top=True)]

        def convert(data):
            spliced = []
            return read(data, 0, spliced)[0], spliced
        _cache[cls] = convert
    return convert


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
