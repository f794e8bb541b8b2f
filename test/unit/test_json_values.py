"""ROS <-> JSON conversion (rosbridge.codec.json_values), field type by field type, on real message classes and on a
message generated at run time that holds every field type ROS 1 has."""

import io
import json
import math

import genpy
import genpy.dynamic
import geometry_msgs.msg
import pytest
import rosgraph_msgs.msg
import sensor_msgs.msg
import std_msgs.msg
import std_srvs.srv

import turtlesim.msg
import turtlesim.srv
from rosbridge.codec.json_values import ConversionError, dumps, from_json, request_from_args, to_json

ALL_TYPES_FIELDS = """\
bool b
int8 i8
uint8 u8
int16 i16
uint16 u16
int32 i32
uint32 u32
int64 i64
uint64 u64
byte by
char ch
float32 f32
float64 f64
string s
time t
duration d
bool[] bools
int8[] i8s
uint16[3] u16s
int16[] i16s
uint32[] u32s
int32[] i32s
uint64[] u64s
int64[] i64s
float32[] f32s
float64[2] f64s
string[] strings
time[] times
duration[2] durations
uint8[] bytes
char[4] chars
uint8[2] fixed_bytes
byte[] signed_bytes
std_msgs/Header header
geometry_msgs/Point[] points
geometry_msgs/Point[2] point_pair
"""


def _generate_all_types():
    separator = "=" * 80 + "\n"
    definition = ALL_TYPES_FIELDS + "".join(
        f"{separator}MSG: {cls._type}\n{cls._full_text}\n" for cls in (std_msgs.msg.Header, geometry_msgs.msg.Point)
    )
    return genpy.dynamic.generate_dynamic("test_convert/AllTypes", definition)["test_convert/AllTypes"]


AllTypes = _generate_all_types()


def serialized(msg):
    buffer = io.BytesIO()
    msg.serialize(buffer)
    return buffer.getvalue()


def deserialized(msg):
    """The message as it arrives from ROS (genpy gives tuples, bytes etc. there)."""
    copy = type(msg)()
    copy.deserialize(serialized(msg))
    return copy


def round_trip(msg, now=None):
    return from_json(type(msg), json.loads(dumps(to_json(msg))), now)


# --- ROS -> JSON ------------------------------------------------------------------------------------------


def test_default_all_types_message_to_json():
    assert to_json(deserialized(AllTypes())) == {
        "b": False,
        "i8": 0,
        "u8": 0,
        "i16": 0,
        "u16": 0,
        "i32": 0,
        "u32": 0,
        "i64": 0,
        "u64": 0,
        "by": 0,
        "ch": 0,
        "f32": 0.0,
        "f64": 0.0,
        "s": "",
        "t": {"secs": 0, "nsecs": 0},
        "d": {"secs": 0, "nsecs": 0},
        "bools": [],
        "i8s": [],
        "u16s": [0, 0, 0],
        "i16s": [],
        "u32s": [],
        "i32s": [],
        "u64s": [],
        "i64s": [],
        "f32s": [],
        "f64s": [0.0, 0.0],
        "strings": [],
        "times": [],
        "durations": [{"secs": 0, "nsecs": 0}, {"secs": 0, "nsecs": 0}],
        "bytes": "",
        "chars": "AAAAAA==",
        "fixed_bytes": "AAA=",
        "signed_bytes": [],
        "header": {"seq": 0, "stamp": {"secs": 0, "nsecs": 0}, "frame_id": ""},
        "points": [],
        "point_pair": [{"x": 0.0, "y": 0.0, "z": 0.0}, {"x": 0.0, "y": 0.0, "z": 0.0}],
    }


def test_values_to_json():
    msg = deserialized(
        AllTypes(
            b=True,
            i8=-128,
            u8=255,
            i16=-32768,
            u16=65535,
            i32=-(2**31),
            u32=2**32 - 1,
            i64=-(2**63),
            u64=2**64 - 1,
            by=-1,
            ch=200,
            f32=0.5,
            f64=-1e300,
            s="héllo ☃ 😀",
            t=genpy.Time(1700000000, 5),
            d=genpy.Duration(-3, 500),
            bools=[True, False],
            i8s=[-1, 2],
            u16s=[1, 2, 65535],
            u64s=[2**64 - 1],
            i64s=[-(2**63)],
            f32s=[1.5, -2.25],
            f64s=[1e-300, 3.0],
            strings=["a", "ü"],
            times=[genpy.Time(1, 2)],
            bytes=b"\x00\xffhi",
            chars=b"abcd",
            fixed_bytes=b"\x01\x02",
            signed_bytes=[-128, 127],
            points=[geometry_msgs.msg.Point(1, 2, 3)],
        )
    )
    value = to_json(msg)
    assert value["b"] is True
    assert (value["i8"], value["u8"], value["i16"], value["u16"]) == (-128, 255, -32768, 65535)
    assert (value["i32"], value["u32"], value["i64"], value["u64"]) == (-(2**31), 2**32 - 1, -(2**63), 2**64 - 1)
    assert (value["by"], value["ch"], value["f32"], value["f64"]) == (-1, 200, 0.5, -1e300)
    assert value["s"] == "héllo ☃ 😀"
    assert value["t"] == {"secs": 1700000000, "nsecs": 5}
    assert value["d"] == {"secs": -3, "nsecs": 500}
    assert value["bools"] == [True, False] and value["i8s"] == [-1, 2] and value["u16s"] == [1, 2, 65535]
    assert value["u64s"] == [2**64 - 1] and value["i64s"] == [-(2**63)]
    assert value["f32s"] == [1.5, -2.25] and value["f64s"] == [1e-300, 3.0] and value["strings"] == ["a", "ü"]
    assert value["times"] == [{"secs": 1, "nsecs": 2}]
    assert value["bytes"] == "AP9oaQ==" and value["chars"] == "YWJjZA==" and value["fixed_bytes"] == "AQI="
    assert value["signed_bytes"] == [-128, 127]
    assert value["points"] == [{"x": 1.0, "y": 2.0, "z": 3.0}]
    assert json.loads(dumps(value)) == value


def test_arrays_are_lists_even_where_genpy_gives_tuples():
    value = to_json(deserialized(sensor_msgs.msg.CameraInfo(D=[0.1, 0.2], K=[1.0] * 9)))
    assert type(value["D"]) is list and type(value["K"]) is list and value["K"] == [1.0] * 9


def test_nan_and_infinity_become_null():
    msg = AllTypes(f32=math.nan, f64=math.inf, f32s=[1.0, -math.inf, math.nan], f64s=[math.nan, 2.0])
    value = to_json(msg)
    assert (value["f32"], value["f64"], value["f32s"], value["f64s"]) == (None, None, [1.0, None, None], [None, 2.0])
    dumps(value)  # no NaN left for the strict encoder to refuse


def test_uint8_array_given_as_list_still_goes_as_base64():
    assert to_json(std_msgs.msg.UInt8MultiArray(data=[1, 2, 3]))["data"] == "AQID"


def test_constants_are_not_fields():
    value = to_json(rosgraph_msgs.msg.Log(level=rosgraph_msgs.msg.Log.WARN, msg="careful"))
    assert set(value) == {"header", "level", "name", "msg", "file", "function", "line", "topics"}
    assert value["level"] == 4 and value["msg"] == "careful"


def test_twist_pose_and_image():
    twist = geometry_msgs.msg.Twist(geometry_msgs.msg.Vector3(1.0, 0, 0), geometry_msgs.msg.Vector3(0, 0, -0.5))
    assert to_json(twist) == {"linear": {"x": 1.0, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": -0.5}}
    pose = deserialized(turtlesim.msg.Pose(x=5.544444561004639, y=1.0, theta=-1.5, linear_velocity=2.0))
    assert to_json(pose) == {
        "x": 5.544444561004639,
        "y": 1.0,
        "theta": -1.5,
        "linear_velocity": 2.0,
        "angular_velocity": 0.0,
    }
    image = sensor_msgs.msg.Image(height=1, width=2, encoding="rgb8", step=6, data=bytes(range(6)))
    image.header.stamp = genpy.Time(10, 20)
    image.header.frame_id = "cam"
    assert to_json(deserialized(image)) == {
        "header": {"seq": 0, "stamp": {"secs": 10, "nsecs": 20}, "frame_id": "cam"},
        "height": 1,
        "width": 2,
        "encoding": "rgb8",
        "is_bigendian": 0,
        "step": 6,
        "data": "AAECAwQF",
    }


def test_visualization_markers():
    visualization_msgs = pytest.importorskip("visualization_msgs.msg")
    marker = visualization_msgs.Marker(
        ns="n",
        id=3,
        type=visualization_msgs.Marker.SPHERE,
        points=[geometry_msgs.msg.Point(1, 2, 3)],
        lifetime=genpy.Duration(2),
    )
    array = visualization_msgs.MarkerArray(markers=[marker, marker])
    value = to_json(deserialized(array))
    assert len(value["markers"]) == 2 and value["markers"][1]["points"] == [{"x": 1.0, "y": 2.0, "z": 3.0}]
    assert value["markers"][0]["lifetime"] == {"secs": 2, "nsecs": 0} and "SPHERE" not in value["markers"][0]
    assert round_trip(array) == deserialized(array)


# --- JSON -> ROS ------------------------------------------------------------------------------------------


def test_missing_fields_take_defaults():
    msg = from_json(AllTypes, {})
    assert serialized(msg) == serialized(AllTypes())
    assert msg.header.stamp == genpy.Time(0, 0)  # no `now`: nothing to fill in


def test_defaults_are_fresh_objects():
    first, second = from_json(AllTypes, {}), from_json(AllTypes, {})
    first.points.append(geometry_msgs.msg.Point())
    first.f64s[0] = 1.0
    first.t.secs = 5
    first.point_pair[0].x = 1.0
    assert second.points == [] and second.f64s == [0.0, 0.0] and second.t.secs == 0 and second.point_pair[0].x == 0


def test_values_from_json():
    msg = from_json(
        AllTypes,
        {
            "b": True,
            "i8": -128,
            "u64": 2**64 - 1,
            "f32": 1,
            "f64": 2.0,
            "s": "ü😀",
            "t": {"secs": 3},
            "d": {"secs": -1, "nsecs": 5},
            "u16s": [1, 2, 3],
            "f64s": [1, None],
            "bools": [False, True],
            "bytes": "AP9oaQ==",
            "chars": [97, 98, 99, 100],
            "fixed_bytes": "AQI=",
            "times": [{"nsecs": 7}, 1.5],
            "points": [{"x": 1}, {}],
            "header": {"frame_id": "map"},
        },
    )
    assert msg.b is True and msg.i8 == -128 and msg.u64 == 2**64 - 1
    assert msg.f32 == 1.0 and type(msg.f32) is float and msg.f64 == 2.0 and msg.s == "ü😀"
    assert msg.t == genpy.Time(3, 0) and msg.d == genpy.Duration(-1, 5)
    assert msg.u16s == [1, 2, 3] and msg.f64s[0] == 1.0 and math.isnan(msg.f64s[1]) and msg.bools == [False, True]
    assert msg.bytes == b"\x00\xffhi" and msg.chars == b"abcd" and msg.fixed_bytes == b"\x01\x02"
    assert msg.times == [genpy.Time(0, 7), genpy.Time(1, 500000000)]
    assert msg.points == [geometry_msgs.msg.Point(1.0, 0, 0), geometry_msgs.msg.Point()]
    assert msg.header.frame_id == "map"
    deserialized(msg)  # and ROS can send it


def test_integral_floats_are_accepted_for_integers():
    msg = from_json(AllTypes, {"i32": 2.0, "u8": 255.0, "i64s": [-3.0]})
    assert (msg.i32, msg.u8, msg.i64s) == (2, 255, [-3]) and type(msg.i32) is int


def test_time_as_seconds():
    msg = from_json(AllTypes, {"t": 12.25, "d": -0.5})
    assert msg.t == genpy.Time(12, 250000000) and msg.d == genpy.Duration.from_sec(-0.5)


def test_nanoseconds_carry_into_seconds():
    assert from_json(AllTypes, {"t": {"secs": 1, "nsecs": 2500000000}}).t == genpy.Time(3, 500000000)


@pytest.mark.parametrize(
    "field,bounds",
    [
        ("i8", (-(2**7), 2**7 - 1)),
        ("u8", (0, 2**8 - 1)),
        ("i16", (-(2**15), 2**15 - 1)),
        ("u16", (0, 2**16 - 1)),
        ("i32", (-(2**31), 2**31 - 1)),
        ("u32", (0, 2**32 - 1)),
        ("i64", (-(2**63), 2**63 - 1)),
        ("u64", (0, 2**64 - 1)),
        ("by", (-(2**7), 2**7 - 1)),
        ("ch", (0, 2**8 - 1)),
    ],
)
def test_integer_bounds(field, bounds):
    low, high = bounds
    for value in (low, high):
        assert getattr(deserialized(from_json(AllTypes, {field: value})), field) == value
    for value in (low - 1, high + 1):
        with pytest.raises(ConversionError, match=rf"^{field}: {value} is out of range"):
            from_json(AllTypes, {field: value})


def test_float32_range():
    biggest = 3.4028234663852886e38
    assert from_json(AllTypes, {"f32": -biggest}).f32 == -biggest
    with pytest.raises(ConversionError, match="^f32: .* out of range for float32"):
        from_json(AllTypes, {"f32": 1e39})
    with pytest.raises(ConversionError, match=r"^f32s\[1\]: .* out of range for float32"):
        from_json(AllTypes, {"f32s": [0, -1e39]})
    with pytest.raises(ConversionError, match="^f64: .* out of range for float64"):
        from_json(AllTypes, {"f64": 10**400})


def test_header_stamp_filled_with_now_when_missing():
    now = lambda: genpy.Time(1234, 5678)  # noqa: E731
    assert from_json(std_msgs.msg.Header, {"frame_id": "a"}, now).stamp == genpy.Time(1234, 5678)
    assert from_json(geometry_msgs.msg.PoseStamped, {"pose": {}}, now).header.stamp == genpy.Time(1234, 5678)
    assert from_json(geometry_msgs.msg.PoseStamped, {"header": {}}, now).header.stamp == genpy.Time(1234, 5678)
    given = {"header": {"stamp": {"secs": 7, "nsecs": 8}}}
    assert from_json(geometry_msgs.msg.PoseStamped, given, now).header.stamp == genpy.Time(7, 8)
    # a time field that is not a header's stamp is left alone
    assert from_json(AllTypes, {}, now).t == genpy.Time(0, 0)


@pytest.mark.parametrize(
    "cls,value,error",
    [
        (geometry_msgs.msg.Twist, {"linear": {"x": "abc"}}, "linear.x: expected a number, got str 'abc'"),
        (geometry_msgs.msg.Twist, {"foo": 1}, "unknown field 'foo' in geometry_msgs/Twist"),
        (geometry_msgs.msg.Twist, {"angular": {"w": 1}}, "angular: unknown field 'w' in geometry_msgs/Vector3"),
        (
            geometry_msgs.msg.Twist,
            {"linear": [1, 2, 3]},
            "linear: expected an object (geometry_msgs/Vector3), got list",
        ),
        (geometry_msgs.msg.Twist, [1], "expected an object (geometry_msgs/Twist), got list [1]"),
        (geometry_msgs.msg.Twist, None, "expected an object (geometry_msgs/Twist), got null"),
        (geometry_msgs.msg.Twist, {"linear": {"x": True}}, "linear.x: expected a number, got bool True"),
        (turtlesim.msg.Pose, {"theta": "1.0"}, "theta: expected a number, got str '1.0'"),
        (AllTypes, {"i32": True}, "i32: expected an integer (int32), got bool True"),
        (AllTypes, {"i32": 2.5}, "i32: expected an integer (int32), got float 2.5"),
        (AllTypes, {"i32": "3"}, "i32: expected an integer (int32), got str '3'"),
        (AllTypes, {"u8": None}, "u8: expected an integer (uint8), got null"),
        (AllTypes, {"b": 1}, "b: expected true or false, got int 1"),
        (AllTypes, {"s": 5}, "s: expected a string, got int 5"),
        (AllTypes, {"s": "\ud800"}, "s: string is not valid Unicode"),
        (AllTypes, {"t": "now"}, 't: expected {"secs": ..., "nsecs": ...} or a number of seconds'),
        (AllTypes, {"t": -1}, 't: expected {"secs": ..., "nsecs": ...} or a number of seconds'),
        (AllTypes, {"t": {"sec": 1}}, "t: unknown field 'sec' in time"),
        (AllTypes, {"t": {"secs": 1.5}}, "t.secs: expected an integer (uint32), got float 1.5"),
        (AllTypes, {"d": {"nsecs": 2**31}}, "d.nsecs: 2147483648 is out of range for int32"),
        (AllTypes, {"t": {"secs": 2**32 - 1, "nsecs": 10**9}}, "t: time 4294967296.000000000 s is out of range"),
        (AllTypes, {"u16s": [1, 2]}, "u16s: expected exactly 3 elements, got 2"),
        (AllTypes, {"i32s": [1, 2, "x"]}, "i32s[2]: expected an integer (int32), got str 'x'"),
        (AllTypes, {"i32s": {"0": 1}}, "i32s: expected an array, got dict"),
        (AllTypes, {"bytes": "not base64!"}, "bytes: expected base64 text or a list of ints 0..255, got a string"),
        (AllTypes, {"bytes": "é"}, "bytes: expected base64 text or a list of ints 0..255, got a string"),
        (AllTypes, {"bytes": [0, 1, 2, 256]}, "bytes[3]: expected an integer 0..255, got int 256"),
        (AllTypes, {"bytes": [True]}, "bytes[0]: expected an integer 0..255, got bool True"),
        (AllTypes, {"bytes": 5}, "bytes: expected base64 text or a list of ints 0..255, got int 5"),
        (AllTypes, {"chars": "YWJj"}, "chars: expected exactly 4 bytes, got 3"),
        (AllTypes, {"points": [{}, {"z": "up"}]}, "points[1].z: expected a number, got str 'up'"),
        (AllTypes, {"point_pair": [{}]}, "point_pair: expected exactly 2 elements, got 1"),
        (AllTypes, {"header": {"stamp": {"secs": -1}}}, "header.stamp.secs: -1 is out of range for uint32"),
        (sensor_msgs.msg.Image, {"data": [1, -1]}, "data[1]: expected an integer 0..255, got int -1"),
    ],
)
def test_bad_values_are_refused_naming_the_field(cls, value, error):
    with pytest.raises(ConversionError) as raised:
        from_json(cls, value)
    assert str(raised.value).startswith(error)


def test_request_from_args():
    spawn = turtlesim.srv.SpawnRequest
    assert request_from_args(spawn, {"x": 1, "y": 2.5, "name": "t2"}) == spawn(1.0, 2.5, 0.0, "t2")
    assert request_from_args(spawn, [1, 2.5, 0.5, "t2"]) == spawn(1.0, 2.5, 0.5, "t2")
    assert request_from_args(spawn, None) == spawn() == request_from_args(spawn, {})
    assert request_from_args(std_srvs.srv.EmptyRequest, []) == std_srvs.srv.EmptyRequest()
    with pytest.raises(ConversionError, match=r"expected 4 positional args \(x, y, theta, name\), got 2"):
        request_from_args(spawn, [1, 2])
    with pytest.raises(ConversionError, match="expected 0 positional args"):
        request_from_args(std_srvs.srv.EmptyRequest, [1])
    with pytest.raises(ConversionError, match="^name: expected a string"):
        request_from_args(spawn, [1, 2, 3, 4])
    with pytest.raises(ConversionError, match="^args: expected an object or a list, got str"):
        request_from_args(spawn, "x=1")


def test_dumps_is_compact_strict_and_keeps_unicode():
    assert dumps({"a": [1, 2.5, None], "s": "ü"}) == '{"a":[1,2.5,null],"s":"ü"}'
    with pytest.raises(ValueError):
        dumps({"x": math.nan})


# --- round trips ------------------------------------------------------------------------------------------


def test_all_types_round_trip():
    msg = deserialized(
        AllTypes(
            b=True,
            i8=-5,
            u64=2**64 - 1,
            f32=0.1,
            f64=-2.5,
            s="ü",
            t=genpy.Time(5, 6),
            d=genpy.Duration(-7, 8),
            bools=[True],
            i8s=[-128],
            u16s=[1, 2, 3],
            f32s=[0.25],
            strings=["x", ""],
            times=[genpy.Time(1, 1)],
            bytes=bytes(range(256)),
            chars=b"wxyz",
            signed_bytes=[-1],
            points=[geometry_msgs.msg.Point(1, 2, 3)],
        )
    )
    assert serialized(round_trip(msg)) == serialized(msg)


def test_image_round_trip():
    image = deserialized(sensor_msgs.msg.Image(height=2, width=2, encoding="mono8", step=2, data=b"\x00\x01\xfe\xff"))
    assert round_trip(image) == image


@pytest.mark.parametrize("text", ["\ud800", "a\udfff b", "\\\ud800", "\udc00\ud800", "é 😀 \ud83d"])
def test_dumps_keeps_surrogates_escaped_so_the_text_has_utf8(text):
    encoded = dumps({"s": text})
    encoded.encode()  # (raises for a raw lone surrogate)
    assert json.loads(encoded) == {"s": text}
