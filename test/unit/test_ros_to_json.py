"""rosbridge.codec.ros_to_json against genpy: for every message type on this machine, random messages serialized by
genpy give exactly the JSON text the bridge wrote before (genpy deserialization, json_values.to_json,
json_values.dumps)."""

import base64
import gc
import math
import random
import struct
import tracemalloc

import genpy
import genpy.dynamic
import pytest
import rosmsg
import rospkg
from hypothesis import given
from hypothesis import strategies as st
from sensor_msgs.msg import ChannelFloat32, CompressedImage
from std_msgs.msg import Header
from test_json_values import AllTypes, serialized
from test_json_values_properties import EACH_TYPE, messages

from rosbridge.codec import BIG_BYTES
from rosbridge.codec.fields import parse_slot_type
from rosbridge.codec.json_values import dumps, to_json
from rosbridge.codec.ros_to_json import SPLICE_MARK, check_whole, fixed_size, joined, json_parts, json_text
from rosbridge.message_types import UnknownType, message_class

from sensor_messages import occupancy_grid_cells


def installed_message_classes():
    """Every message type whose definition and Python class are installed (ros-*-msgs and python3-*-msgs)."""
    packages = rospkg.RosPack()
    classes = []
    for package in sorted(packages.list()):
        for type_name in rosmsg.list_types(package, ".msg", packages):
            try:
                classes.append(message_class(type_name))
            except UnknownType:  # a definition without its Python class
                pass
    return classes


CLASSES = [AllTypes] + installed_message_classes()


def genpy_json_text(cls, data):
    msg = cls()
    msg.deserialize(data)
    return dumps(to_json(msg))


def test_every_installed_message_package_is_covered():
    names = {cls._type.split("/")[0] for cls in CLASSES}
    assert {"std_msgs", "geometry_msgs", "sensor_msgs", "rosgraph_msgs", "turtlesim"} <= names
    assert len(CLASSES) > 90


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls._type)
@EACH_TYPE
@given(data=st.data())
def test_random_messages_give_the_text_of_genpy_and_convert(cls, data):
    wire_bytes = serialized(data.draw(messages(cls, any_wire_value=True)))
    assert json_text(cls)(wire_bytes) == genpy_json_text(cls, wire_bytes)


def test_special_values():
    msg = AllTypes(
        f32=math.inf,
        f64=math.nan,
        f64s=[-math.inf, 1.5],
        s='quote " back \\ and \x01 ☃',
        strings=["", "😀"],
        bools=[True, False, True],
        signed_bytes=[-1, 5],
        chars=b"\xff\x00ab",
    )
    msg.t.secs, msg.t.nsecs = 7, 2_500_000_000  # on the wire as sent; genpy carries it into secs
    msg.d.secs, msg.d.nsecs = 1, -1
    data = serialized(msg)
    text = json_text(AllTypes)(data)
    assert text == genpy_json_text(AllTypes, data)
    assert '"f32":null,"f64":null' in text and '"f64s":[null,1.5]' in text
    assert '"t":{"secs":9,"nsecs":500000000}' in text and '"d":{"secs":0,"nsecs":999999999}' in text


def test_invalid_utf8_is_replaced_as_genpy_does():
    data = serialized(message_class("std_msgs/String")(data="ok")).replace(b"ok", b"o\xff")
    assert json_text(message_class("std_msgs/String"))(data) == genpy_json_text(message_class("std_msgs/String"), data)
    assert json_text(message_class("std_msgs/String"))(data) == '{"data":"o\ufffd"}'


def test_a_large_image_as_base64():
    image = message_class("sensor_msgs/Image")(
        height=480, width=640, encoding="rgb8", step=1920, data=bytes(range(256)) * 3600
    )
    data = serialized(image)
    assert json_text(type(image))(data) == genpy_json_text(type(image), data)


def _spliced_type():
    """Big byte arrays before, inside and after an array of nested messages."""
    separator = "=" * 80 + "\n"
    definition = "uint8[] first\nsensor_msgs/CompressedImage[] images\nstring between\nuint8[] last\n" + "".join(
        f"{separator}MSG: {cls._type}\n{cls._full_text}\n" for cls in (CompressedImage, Header)
    )
    return genpy.dynamic.generate_dynamic("test_wire/Spliced", definition)["test_wire/Spliced"]


def test_big_byte_arrays_are_left_out_of_the_text_in_order():
    cls = _spliced_type()
    blobs = [bytes([i]) * (60_000 + i) for i in range(4)]  # each over 64 KB in base64
    msg = cls(
        first=blobs[0],
        images=[
            CompressedImage(format="jpeg", data=blobs[1]),
            CompressedImage(data=b"ab"),
            CompressedImage(data=blobs[2]),
        ],
        between="x",
        last=blobs[3],
    )
    data = serialized(msg)
    text, spliced = json_parts(cls)(data)
    assert text.count(SPLICE_MARK) == 4 and len(text) < 2000
    assert spliced == [base64.b64encode(blob) for blob in blobs]
    assert joined(text, spliced) == json_text(cls)(data) == genpy_json_text(cls, data)


def test_a_byte_array_just_under_the_limit_stays_in_the_text():
    msg = AllTypes(bytes=b"x" * (BIG_BYTES // 4 * 3 - 3))  # base64: BIG_BYTES - 4 characters
    text, spliced = json_parts(AllTypes)(serialized(msg))
    assert spliced == [] and SPLICE_MARK not in text


def test_readers_are_made_once_per_type():
    assert json_parts(message_class("geometry_msgs/Twist")) is json_parts(message_class("geometry_msgs/Twist"))
    assert genpy.Message  # (genpy's 'rosmsg' decoding error handler is registered by importing it)


# ---------------------------------------------------------------------------------------------------------
# Big numeric arrays: written from the bytes without a Python object per element (the same text as genpy's road)

BIG_ARRAYS_FIELDS = """\
int8[] i8s
bool[] bools
int16[] i16s
uint16[] u16s
int32[] i32s
uint32[] u32s
int64[] i64s
uint64[] u64s
float32[] f32s
float64[] f64s
uint8[] u8s
int8[100] fixed_i8s
bool[70] fixed_bools
uint16[200] fixed_u16s
float64[65] fixed_f64s
float32[3] small_f32s
sensor_msgs/ChannelFloat32[] channels
std_msgs/Int8MultiArray grid
"""
_CODES = {
    "int8": "b",
    "bool": "?",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
    "uint8": "B",
}
# floats whose text is special: NaN and +-Inf (null), -0.0, the extremes, a subnormal
SPECIAL_FLOATS = [
    math.nan,
    math.inf,
    -math.inf,
    -0.0,
    0.0,
    5e-324,
    -1.7976931348623157e308,
    1e16,
    1e-5,
    0.1,
    123456789.0,
    -2.5,
]
SPECIAL_FLOAT32S = [
    math.nan,
    math.inf,
    -math.inf,
    -0.0,
    1e-45,
    3.4028234663852886e38,
    -1.1754943508222875e-38,
    16777216.0,
    0.1,
    1e-5,
]


def _big_arrays_type():
    separator = "=" * 80 + "\n"
    nested = [ChannelFloat32] + [
        message_class(f"std_msgs/{name}") for name in ("Int8MultiArray", "MultiArrayLayout", "MultiArrayDimension")
    ]
    definition = BIG_ARRAYS_FIELDS + "".join(f"{separator}MSG: {cls._type}\n{cls._full_text}\n" for cls in nested)
    return genpy.dynamic.generate_dynamic("test_wire/BigArrays", definition)["test_wire/BigArrays"]


BigArrays = _big_arrays_type()


def random_values(base, count, rng):
    """`count` values of a numeric type, as any bytes on the wire hold them (floats: NaN and Inf too, and the
    special ones above among them)."""
    code = _CODES[base]
    raw = rng.randbytes(count * struct.calcsize(code))
    values = list(struct.unpack(f"<{count}{code}", raw))
    if base in ("float32", "float64"):
        specials = SPECIAL_FLOAT32S if base == "float32" else SPECIAL_FLOATS
        for value in specials[:count]:
            values[rng.randrange(count)] = value
    if base == "int8" and count:  # a map's cells: long runs of -1, 0 and 100
        start = rng.randrange(count)
        values[start : start + 5000] = [rng.choice([-1, 0, 100])] * len(values[start : start + 5000])
    return values


def big_arrays_message(count, seed=0):
    rng = random.Random(seed)
    fields = {}
    for name, slot_type in zip(BigArrays.__slots__, BigArrays._slot_types):
        base, is_array, size = parse_slot_type(slot_type)
        if base in _CODES:
            values = random_values(base, size or count, rng)
            fields[name] = bytes(values) if base == "uint8" else values
    channels = [
        ChannelFloat32(name=f"c{i}", values=random_values("float32", n, rng))
        for i, n in enumerate([count, 0, 3, count // 2])
    ]
    grid = message_class("std_msgs/Int8MultiArray")(data=random_values("int8", count * 3, rng))
    grid.layout.dim = [message_class("std_msgs/MultiArrayDimension")(label="rows", size=count, stride=3)]
    return BigArrays(channels=channels, grid=grid, **fields)


BIG_COUNTS = [0, 1, 64, 65, 3000, (1 << 13) + 1, (1 << 16) + 1, 150_000]


@pytest.mark.parametrize("count", BIG_COUNTS)
def test_big_numeric_arrays_give_the_text_of_genpy_and_convert(count):
    data = serialized(big_arrays_message(count, seed=count))
    text, spliced = json_parts(BigArrays)(data)
    assert joined(text, spliced) == genpy_json_text(BigArrays, data)
    if count >= 1 << 16:  # the arrays' texts are left out of the text (each over BIG_BYTES)
        assert len(text) < 20_000 and text.count(SPLICE_MARK) == len(spliced)
        assert all(isinstance(part, bytes) and part.isascii() for part in spliced)
    if count <= 65:
        assert spliced == []


def test_special_floats_in_big_arrays_are_null_or_written_as_python_does():
    floats = [math.nan, -math.inf, math.inf, -0.0, 0.1, 1e16, 5e-324] * 3000
    msg = BigArrays(f64s=floats, f32s=[x for x in floats if x != 5e-324])
    data = serialized(msg)
    text = json_text(BigArrays)(data)
    assert text == genpy_json_text(BigArrays, data)
    assert '"f64s":[null,null,null,-0.0,0.1,1e+16,5e-324,null,' in text
    assert '"f32s":[null,null,null,-0.0,0.10000000149011612,1.0000000272564224e+16,null,' in text


def test_any_byte_but_0_is_true_in_a_bool_array():
    cls = genpy.dynamic.generate_dynamic("test_wire/Bools", "bool[] bools\nint8[] cells\n")["test_wire/Bools"]
    raw = bytes(range(256)) * 300
    data = struct.pack("<I", len(raw)) + raw + struct.pack("<I", len(raw)) + raw
    text = json_text(cls)(data)
    assert text == genpy_json_text(cls, data)
    assert text.startswith('{"bools":[false,true,true,') and '"cells":[0,1,2,' in text and ",-128,-127," in text


@pytest.mark.parametrize("slot_type", ["int8[]", "bool[]", "float64[]", "uint64[]", "int16[100]"])
def test_a_truncated_big_array_is_an_error_as_before(slot_type):
    cls = genpy.dynamic.generate_dynamic("test_wire/One", f"{slot_type} values\n")["test_wire/One"]
    data = serialized(cls(values=[0] * 100))
    with pytest.raises(struct.error):
        json_text(cls)(data[:-1])


def map_bytes(side):
    """A nav_msgs/OccupancyGrid-like int8[] of side x side cells (sensor_messages.occupancy_grid_cells), as its
    serialized field."""
    cells = occupancy_grid_cells(side)
    return struct.pack("<I", len(cells)) + cells


_GRID_DEFINITION = "std_msgs/Header header\nint8[] data\n" + "=" * 80 + f"\nMSG: std_msgs/Header\n{Header._full_text}\n"
GRID = genpy.dynamic.generate_dynamic("test_wire/Grid", _GRID_DEFINITION)["test_wire/Grid"]  # (a map's header, cells)


def test_a_map_gives_the_text_of_genpy_and_convert():
    data = serialized(GRID())[:-4] + map_bytes(1000)
    assert json_text(GRID)(data) == genpy_json_text(GRID, data)


def _converted_peak(convert, data):
    """tracemalloc's peak while convert(data) runs, above what was traced before, and what stays traced after."""
    gc.collect()
    tracemalloc.reset_peak()
    before = tracemalloc.get_traced_memory()[0]
    result = convert(data)
    size = sum(map(len, result[1])) + len(result[0])
    peak = tracemalloc.get_traced_memory()[1] - before
    del result
    gc.collect()
    return peak, tracemalloc.get_traced_memory()[0] - before, size


def test_a_map_costs_about_its_text_in_memory_and_the_tenth_as_much_as_the_first():
    """No tuple of the cells, no str per cell: the peak is the text itself and a chunk's work (the road through
    genpy peaks at about 100 bytes a cell); all of it is given back, and the tenth map, after clouds and scans
    in between, costs what the first did."""
    data = serialized(GRID())[:-4] + map_bytes(2000)
    cloud = serialized(message_class("sensor_msgs/PointCloud2")(data=bytes(range(256)) * 8000, width=64000))
    scan = serialized(message_class("sensor_msgs/LaserScan")(ranges=[1.5, math.inf, math.nan] * 360))
    convert = json_parts(GRID)
    convert(data)  # (the reader is generated once: not counted)
    tracemalloc.start()
    try:
        peaks, kept = [], []
        for _ in range(10):
            peak, left, size = _converted_peak(convert, data)
            peaks.append(peak)
            kept.append(left)
            for other, cls in ((cloud, "sensor_msgs/PointCloud2"), (scan, "sensor_msgs/LaserScan")):
                json_parts(message_class(cls))(other)
    finally:
        tracemalloc.stop()
    assert size > 2000 * 2000 * 2
    assert peaks[0] < size * 1.1 + 2_000_000, (peaks[0], size)
    assert max(peaks) < peaks[0] * 1.1 and max(kept) < 100_000, (peaks, kept)


def test_a_traceback_through_a_generated_reader_shows_its_source_lines():
    import traceback

    from geometry_msgs.msg import Twist

    from rosbridge.codec.ros_to_json import json_parts

    with pytest.raises(struct.error) as raised:
        json_parts(Twist)(bytes(10))  # 48 bytes of doubles expected
    generated = [
        frame
        for frame in traceback.extract_tb(raised.value.__traceback__)
        if frame.filename.startswith("<rosbridge generated")
    ]
    assert generated and all(frame.line for frame in generated)
    assert "geometry_msgs/Twist" in generated[0].filename


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls._type)
@EACH_TYPE
@given(data=st.data())
def test_a_fixed_size_is_every_message_s_length_and_whole_bytes_are_told_from_a_byte_more_or_less(cls, data):
    """check_whole takes a type of fixed size by its length alone, without reading it: that length must be what
    genpy writes for any message of the type. Whole bytes pass; a byte more or less is refused, read or not."""
    wire_bytes = serialized(data.draw(messages(cls, any_wire_value=True)))
    size = fixed_size(cls)
    assert size is None or len(wire_bytes) == size
    check_whole(cls, wire_bytes)
    for wrong in ([wire_bytes[:-1]] if wire_bytes else []) + [wire_bytes + b"\x00"]:
        with pytest.raises(ValueError, match=cls._type):
            check_whole(cls, wrong)


def test_a_type_with_a_string_or_an_open_array_has_no_fixed_size():
    from geometry_msgs.msg import Twist
    from sensor_msgs.msg import LaserScan

    assert fixed_size(Twist) == 48
    assert fixed_size(Header) is None and fixed_size(LaserScan) is None
