"""Wire encodings (rosbridge.codec.cbor and .wrapping): CBOR with RFC 8746 typed arrays, JSON packed into PNG,
fragments."""

import base64
import io
import json
import math
import os
import struct
import tracemalloc

import cbor2
import genpy
import geometry_msgs.msg
import pytest
import sensor_msgs.msg
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image
from test_json_values import AllTypes, deserialized, serialized
from test_json_values_properties import EACH_TYPE, messages
from test_ros_to_json import BIG_COUNTS, CLASSES, GRID, BigArrays, big_arrays_message, map_bytes

from rosbridge.codec import BIG_BYTES
from rosbridge.codec.cbor import cbor_parts, raw_publish_parts, to_cbor_value
from rosbridge.codec.fields import parse_slot_type
from rosbridge.codec.json_values import dumps, from_json
from rosbridge.codec.ros_to_cbor import cbor_value
from rosbridge.codec.wrapping import fragments, png_frame, png_unframe
from rosbridge.protocol.encoded import SplicedFrame, cbor_frame

# element type -> (size in bytes, signed, float, struct code)
NUMERIC = {
    "int8": (1, True, False, "b"),
    "uint16": (2, False, False, "H"),
    "int16": (2, True, False, "h"),
    "uint32": (4, False, False, "I"),
    "int32": (4, True, False, "i"),
    "uint64": (8, False, False, "Q"),
    "int64": (8, True, False, "q"),
    "float32": (4, True, True, "f"),
    "float64": (8, True, True, "d"),
}


def rfc8746_tag(size, signed, is_float):
    """The tag of a little-endian typed array, from the bit layout of RFC 8746 section 2.1: 0b010_f_s_e_ll."""
    if is_float:
        return 0b010_1_0_1_00 | {2: 0, 4: 1, 8: 2, 16: 3}[size]
    little_endian = size > 1  # one-byte arrays have no byte order (e = 0)
    return 0b010_0_0_0_00 | signed << 3 | little_endian << 2 | {1: 0, 2: 1, 4: 2, 8: 3}[size]


def tag_codes():
    return {rfc8746_tag(*NUMERIC[base][:3]): NUMERIC[base][3] for base in NUMERIC}


def typed_arrays_as_lists(value):
    """Decoded CBOR with each typed array replaced by the list of its numbers (walked here rather than with a
    tag_hook, whose signature differs between cbor2 versions)."""
    if isinstance(value, cbor2.CBORTag):
        code = tag_codes()[value.tag]
        return list(struct.unpack(f"<{len(value.value) // struct.calcsize(code)}{code}", value.value))
    if isinstance(value, dict):
        return {key: typed_arrays_as_lists(item) for key, item in value.items()}
    if isinstance(value, list):
        return [typed_arrays_as_lists(item) for item in value]
    return value


def cbor_decoded(msg):
    return typed_arrays_as_lists(cbor2.loads(bytes(cbor_frame(to_cbor_value(msg)))))


def sample():
    return deserialized(
        AllTypes(
            b=True,
            i8=-5,
            u64=2**64 - 1,
            f32=0.5,
            f64=-2.5,
            s="ü",
            t=genpy.Time(5, 6),
            d=genpy.Duration(-7, 8),
            bools=[True, False],
            i8s=[-128, 127],
            u16s=[1, 2, 65535],
            i16s=[-32768],
            u32s=[2**32 - 1],
            i32s=[-(2**31), 5],
            u64s=[2**64 - 1],
            i64s=[-(2**63)],
            f32s=[0.25, -1e30],
            f64s=[1e-300, 2.0],
            strings=["x", ""],
            times=[genpy.Time(1, 1)],
            durations=[genpy.Duration(1), genpy.Duration(-2)],
            bytes=bytes(range(256)),
            chars=b"wxyz",
            fixed_bytes=b"\x00\x01",
            signed_bytes=[-1, 1],
            points=[geometry_msgs.msg.Point(1, 2, 3)],
        )
    )


def test_numeric_arrays_are_little_endian_typed_arrays_with_rfc8746_tags():
    msg = sample()
    raw = cbor2.loads(bytes(cbor_frame(to_cbor_value(msg))))
    for name, slot_type in zip(AllTypes.__slots__, AllTypes._slot_types):
        base, is_array, _ = parse_slot_type(slot_type)
        if is_array and base in NUMERIC:
            size, signed, is_float, code = NUMERIC[base]
            tag = raw[name]
            assert isinstance(tag, cbor2.CBORTag) and tag.tag == rfc8746_tag(size, signed, is_float), name
            values = list(struct.unpack(f"<{len(getattr(msg, name))}{code}", tag.value))
            expected = (
                [struct.unpack("<f", struct.pack("<f", v))[0] for v in getattr(msg, name)]
                if base == "float32"
                else list(getattr(msg, name))
            )
            assert values == expected, name


def test_rfc8746_tag_numbers():
    assert tag_codes() == {72: "b", 69: "H", 77: "h", 70: "I", 78: "i", 71: "Q", 79: "q", 85: "f", 86: "d"}


def test_cbor_byte_arrays_times_and_the_rest():
    value = cbor_decoded(sample())
    assert value["bytes"] == bytes(range(256)) and value["chars"] == b"wxyz" and value["fixed_bytes"] == b"\x00\x01"
    assert value["t"] == {"secs": 5, "nsecs": 6} and value["d"] == {"secs": -7, "nsecs": 8}
    assert value["durations"] == [{"secs": 1, "nsecs": 0}, {"secs": -2, "nsecs": 0}]
    assert value["bools"] == [True, False] and value["strings"] == ["x", ""] and value["s"] == "ü"
    assert value["u64"] == 2**64 - 1 and value["b"] is True
    assert value["points"] == [{"x": 1.0, "y": 2.0, "z": 3.0}]
    assert value["header"] == {"seq": 0, "stamp": {"secs": 0, "nsecs": 0}, "frame_id": ""}


def test_cbor_keeps_nan_and_infinity():
    value = cbor_decoded(AllTypes(f32=math.nan, f64=-math.inf, f64s=[math.inf, math.nan]))
    assert math.isnan(value["f32"]) and value["f64"] == -math.inf
    assert value["f64s"][0] == math.inf and math.isnan(value["f64s"][1])


def test_cbor_value_decodes_back_to_the_same_message():
    msg = sample()
    value = cbor_decoded(msg)
    for name in ("bytes", "chars", "fixed_bytes"):  # from_json takes byte arrays as lists of ints
        value[name] = list(value[name])
    assert serialized(from_json(AllTypes, value)) == serialized(msg)


def test_cbor_image_data_is_one_byte_string():
    image = sensor_msgs.msg.Image(height=480, width=640, encoding="rgb8", step=1920, data=bytes(640 * 480 * 3))
    frame = cbor_frame({"op": "publish", "topic": "/camera", "msg": to_cbor_value(image)})
    assert isinstance(frame, SplicedFrame) and not frame.text and len(frame) < 640 * 480 * 3 + 200
    assert any(part is image.data for part in frame.parts)  # sent as it is, not copied
    decoded = cbor2.loads(bytes(frame))
    assert decoded["op"] == "publish" and decoded["msg"]["data"] == image.data and decoded["msg"]["width"] == 640


@pytest.mark.parametrize("size", [0, 4, 23, 24, 255, 256, BIG_BYTES - 1, BIG_BYTES, 640 * 480 * 3])
@pytest.mark.parametrize("stamp", [0.0, 12.25, 1764150000.000000023, 1764150000.999999])
@pytest.mark.parametrize("topic", ["/t", "/rover/" + "x" * 300, "/ünïcode"], ids=["short", "long", "unicode"])
def test_the_cbor_raw_op_is_what_cbor2_writes_and_big_bytes_go_by_reference(size, stamp, topic):
    data = bytearray(os.urandom(size))
    parts = raw_publish_parts(topic, data, stamp)
    secs = int(stamp)
    assert b"".join(parts) == cbor2.dumps(
        {
            "op": "publish",
            "topic": topic,
            "msg": {"bytes": bytes(data), "secs": secs, "nsecs": int((stamp - secs) * 1e9)},
        }
    )
    assert len(parts) == (3 if size >= BIG_BYTES else 1)
    if size >= BIG_BYTES:
        assert parts[1] is data  # not copied


TEXTS = [
    "",
    "1",
    "{}",
    "[1]",
    '"ab"',
    dumps({"op": "publish", "topic": "/t", "msg": {"data": "x" * 1000}}),
    dumps({"s": "héllo ☃ 😀", "n": [1, 2.5, None]}),
]


@pytest.mark.parametrize("text", TEXTS, ids=lambda text: f"{len(text)}-chars")
def test_png_round_trip(text):
    assert json.loads(png_unframe(png_frame(text)) or "null") == json.loads(text or "null")


@pytest.mark.parametrize("text", TEXTS[1:], ids=lambda text: f"{len(text)}-chars")
def test_png_as_roslibjs_reads_it(text):
    """roslibjs draws the image on a canvas and builds the text from the R, G, B bytes of each pixel, one
    String.fromCharCode per byte, then JSON.parses it (trailing newlines are whitespace to JSON)."""
    with Image.open(io.BytesIO(base64.b64decode(png_frame(text)))) as image:
        assert image.format == "PNG" and image.mode == "RGB"
        width, height = image.size
        rgba = image.convert("RGBA").tobytes()
    text_from_canvas = "".join(chr(rgba[i]) + chr(rgba[i + 1]) + chr(rgba[i + 2]) for i in range(0, len(rgba), 4))
    assert json.loads(text_from_canvas) == json.loads(text)
    assert set(text_from_canvas[len(text_from_canvas.rstrip("\n")) :]) <= {"\n"}
    assert abs(width - height) <= max(2, width // 10)  # about square, as the reference makes them


def test_png_escapes_non_ascii_so_byte_wise_decoding_works():
    text = dumps({"s": "ü😀"})
    assert png_unframe(png_frame(text)).isascii()


def test_fragments():
    text = dumps({"op": "publish", "topic": "/t", "msg": {"data": "abcdefghij" * 10}})
    parts = fragments(text, 7, "publish:/t:1")
    assert [part["num"] for part in parts] == list(range(len(parts))) and len(parts) == math.ceil(len(text) / 7)
    assert all(
        part["op"] == "fragment" and part["id"] == "publish:/t:1" and part["total"] == len(parts) for part in parts
    )
    assert all(len(part["data"]) == 7 for part in parts[:-1]) and 1 <= len(parts[-1]["data"]) <= 7
    assert "".join(part["data"] for part in parts) == text


def test_fragments_of_short_text_and_bad_size():
    assert fragments("abc", 10, 5) == [{"op": "fragment", "id": 5, "data": "abc", "num": 0, "total": 1}]
    assert fragments("", 10, "x") == [{"op": "fragment", "id": "x", "data": "", "num": 0, "total": 1}]
    with pytest.raises(ValueError):
        fragments("abc", 0, "x")


def test_png_unframe_refuses_images_that_unpack_too_big():
    big = Image.new("RGB", (2000, 2000))
    buffer = io.BytesIO()
    big.save(buffer, format="PNG")  # compresses to a few kB
    with pytest.raises(ValueError, match="would unpack to 12000000 bytes"):
        png_unframe(base64.b64encode(buffer.getvalue()).decode(), max_bytes=10**6)


GOOD_PNG = base64.b64decode(png_frame('{"a":1}' * 50))


def spoiled_png(cut, noise):
    return base64.b64encode(GOOD_PNG[:cut] + noise + GOOD_PNG[cut + len(noise) :]).decode()


@settings(deadline=None, max_examples=300)
@given(
    junk=st.binary(max_size=200).map(lambda raw: base64.b64encode(raw).decode())
    | st.text(max_size=50)
    | st.integers(0, len(GOOD_PNG)).map(lambda cut: base64.b64encode(GOOD_PNG[:cut]).decode())
    | st.builds(spoiled_png, st.integers(0, len(GOOD_PNG)), st.binary(min_size=1, max_size=40))
)
def test_png_unframe_of_junk_raises_only_value_error(junk):
    """(PIL itself raises OSError, SyntaxError and more for broken images.)"""
    try:
        png_unframe(junk)
    except ValueError:
        pass


@pytest.mark.parametrize("sizes", [[BIG_BYTES], [BIG_BYTES - 1, 70_000], [70_000, 100, 1 << 17]])
def test_big_byte_strings_are_put_in_place_exactly_as_cbor2_would_write_them(sizes):
    blobs = [os.urandom(size) for size in sizes]
    messages = [
        sensor_msgs.msg.Image(height=1, width=len(blob), encoding="mono8", step=len(blob), data=blob) for blob in blobs
    ]
    obj = {"op": "publish", "topic": "/camera", "msg": [to_cbor_value(m) for m in messages]}
    expected = cbor2.dumps(
        {"op": "publish", "topic": "/camera", "msg": [{**to_cbor_value(m), "data": m.data} for m in messages]}
    )
    assert b"".join(cbor_parts(obj)) == expected


# ---------------------------------------------------------------------------------------------------------
# ROS bytes straight to CBOR (rosbridge.codec.ros_to_cbor): what to_cbor_value gives for genpy's message, with no
# genpy message and every array of numbers taken from the bytes as they are


def publish_cbor(value):
    return b"".join(cbor_parts({"op": "publish", "topic": "/t", "msg": value}))


def genpy_cbor(cls, data):
    msg = cls()
    msg.deserialize(data)
    return publish_cbor(to_cbor_value(msg))


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls._type)
@EACH_TYPE
@given(data=st.data())
def test_random_messages_give_the_cbor_of_genpy_and_to_cbor_value(cls, data):
    wire_bytes = serialized(data.draw(messages(cls, any_wire_value=True)))
    assert publish_cbor(cbor_value(cls)(wire_bytes)) == genpy_cbor(cls, wire_bytes)


def comparable(value):
    """Decoded CBOR with typed arrays as lists of their items, floats as their bits but every NaN the same (the road
    through genpy turns a signalling NaN in a float32[] into a quiet one)."""
    if isinstance(value, cbor2.CBORTag):
        code = tag_codes()[value.tag]
        items = struct.unpack(f"<{len(value.value) // struct.calcsize(code)}{code}", value.value)
        return value.tag, [comparable(item) for item in items]
    if isinstance(value, float):
        return "nan" if math.isnan(value) else struct.pack("<d", value)
    if isinstance(value, dict):
        return {key: comparable(item) for key, item in value.items()}
    if isinstance(value, list):
        return [comparable(item) for item in value]
    return value


@pytest.mark.parametrize("count", BIG_COUNTS)
def test_big_numeric_arrays_give_the_cbor_of_genpy_and_to_cbor_value(count):
    data = serialized(big_arrays_message(count, seed=count))
    value = cbor_value(BigArrays)(data)
    assert comparable(cbor2.loads(publish_cbor(value))) == comparable(cbor2.loads(genpy_cbor(BigArrays, data)))
    assert isinstance(value["i8s"], cbor2.CBORTag) and value["i8s"].tag == 72
    # the big ones are views of the message's bytes, written by reference
    frame = cbor_frame({"op": "publish", "topic": "/t", "msg": value})
    views = [part for part in getattr(frame, "parts", ()) if isinstance(part, memoryview)]
    assert all(view.obj is data and len(view) >= BIG_BYTES for view in views)
    # 8192 elements of 8 bytes: the three 64-bit arrays; from 65536: every numeric array but bool[] (a list), the
    # byte string, the two big channels and the grid
    assert len(views) == (0 if count < 8192 else 3 if count < 16384 else 13)


def test_float32_arrays_keep_their_bits():
    bits = [0x7F800001, 0x7FC00000, 0xFFC00001, 0x7F800000, 0x80000000, 0x00000001]  # NaN (signalling), -0.0 ...
    cls = genpy.dynamic.generate_dynamic("test_wire/F32s", "float32[] values\n")["test_wire/F32s"]
    raw = struct.pack(f"<{len(bits)}I", *bits)
    value = cbor_value(cls)(struct.pack("<I", len(bits)) + raw)
    assert value["values"].tag == 85 and value["values"].value == raw


def test_a_map_and_a_cloud_as_cbor_are_not_copied():
    grid = serialized(GRID())[:-4] + map_bytes(2000)
    cloud = sensor_msgs.msg.PointCloud2(
        height=1, width=300_000, point_step=16, row_step=4_800_000, data=os.urandom(4_800_000), is_dense=True
    )
    cloud.fields = [
        sensor_msgs.msg.PointField(name=name, offset=4 * i, datatype=7, count=1) for i, name in enumerate("xyz")
    ]
    cases = ((GRID, grid, grid[-2000 * 2000 :]), (sensor_msgs.msg.PointCloud2, serialized(cloud), cloud.data))
    for cls, data, cells in cases:
        convert = cbor_value(cls)
        cbor_frame({"op": "publish", "topic": "/t", "msg": convert(data)})  # (what is made once: not counted)
        tracemalloc.start()
        try:
            frame = cbor_frame({"op": "publish", "topic": "/t", "msg": convert(data)})
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert peak < 100_000, (cls, peak)
        (view,) = [part for part in frame.parts if isinstance(part, memoryview)]
        assert view.obj is data and view == cells
        decoded = cbor2.loads(bytes(frame))["msg"]
        if cls is GRID:
            assert decoded["data"].tag == 72 and decoded["data"].value == cells
        else:
            assert decoded["data"] == cloud.data and decoded["width"] == 300_000
            assert [field["name"] for field in decoded["fields"]] == ["x", "y", "z"]
