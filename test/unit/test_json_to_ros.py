"""rosbridge.codec.json_to_ros against json_values.from_json + genpy: for every message type on this machine, random
messages as a client would send them, and spoiled ones, give the same bytes or the same ConversionError."""

import json

import genpy
import pytest
from hypothesis import given
from hypothesis import strategies as st
from test_json_values import AllTypes, serialized
from test_json_values_properties import EACH_TYPE, SETTINGS, json_junk, messages
from test_ros_to_json import CLASSES

from rosbridge.codec.json_to_ros import packer
from rosbridge.codec.json_values import ConversionError, from_json, to_json


def now():
    return genpy.Time(7, 8)


def long_way(cls, value):
    """convert's answer: the serialized message, or the ConversionError's text."""
    try:
        return serialized(from_json(cls, value, now))
    except ConversionError as error:
        return f"error: {error}"


def packed(cls, value):
    try:
        return packer(cls)(value, now)
    except ConversionError as error:
        return f"error: {error}"


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls._type)
@EACH_TYPE
@given(data=st.data())
def test_random_messages_as_json_pack_like_convert(cls, data):
    value = json.loads(json.dumps(to_json(data.draw(messages(cls)))))  # ints stay ints, as a client sends them
    for name in data.draw(st.lists(st.sampled_from(cls.__slots__), max_size=2)) if cls.__slots__ else ():
        value.pop(name, None)  # missing fields take their defaults
    assert packed(cls, value) == long_way(cls, value)


@pytest.mark.parametrize(
    "cls",
    [AllTypes]
    + [
        c
        for c in CLASSES
        if c._type
        in ("geometry_msgs/Twist", "sensor_msgs/Image", "sensor_msgs/JointState", "visualization_msgs/MarkerArray")
    ],
    ids=lambda cls: cls._type,
)
@SETTINGS
@given(data=st.data())
def test_junk_packs_or_fails_like_convert(cls, data):
    value = data.draw(json_junk | messages(cls).map(to_json))
    if isinstance(value, dict):
        for name in data.draw(st.lists(st.sampled_from(cls.__slots__ + ["extra"]), max_size=3)):
            value[name] = data.draw(json_junk)
    assert packed(cls, value) == long_way(cls, value)


@pytest.mark.parametrize(
    "value",
    [
        {"linear": {"x": 1, "y": 2.5}, "angular": {"z": -1}},  # ints for floats, fields missing: the common road
        {"linear": {"x": 2**1100}},
        {"linear": {"x": None}},
        {"linear": {"x": True}},
        {"linear": "x"},
        [],
    ],
)
def test_twist_edges(value):
    twist = CLASSES[[c._type for c in CLASSES].index("geometry_msgs/Twist")]
    assert packed(twist, value) == long_way(twist, value)


def test_special_cases_of_all_types():
    for value in [
        {"u8": 256},
        {"i64": -(2**63)},
        {"u64": 2**64},
        {"f32": 3.5e38},
        {"f32": 3.4028235e38},
        {"i8": 2.0},
        {"s": "\ud800"},
        {"bytes": "!!"},
        {"bytes": [1, 2]},
        {"fixed_bytes": "AAAA"},
        {"t": 5.5},
        {"t": {"secs": 1, "nsecs": 2_000_000_000}},
        {"d": {"secs": -1, "nsecs": -5}},
        {"header": {}},
        {"header": {"stamp": {"secs": 3}}},
        {"u16s": [1, 2]},
        {"bools": [1]},
        {"points": [{"x": 1}, 7]},
        {"times": [{"secs": 1}, {"nsecs": 3}]},
        {"strings": ["a", 1]},
        {"f64s": [1, 2]},
    ]:
        assert packed(AllTypes, value) == long_way(AllTypes, value), value


def test_the_common_road_builds_no_genpy_message(monkeypatch):
    import rosbridge.codec.json_to_ros

    monkeypatch.setattr(rosbridge.codec.json_to_ros, "from_json", lambda *args: pytest.fail("took the long way"))
    by_name = {c._type: c for c in CLASSES}
    twist = {"linear": {"x": 2, "y": 0.5, "z": 0}, "angular": {"x": 0, "y": 0, "z": 1.8}}
    assert packer(by_name["geometry_msgs/Twist"])(twist) == long_way(by_name["geometry_msgs/Twist"], twist)
    image = {
        "header": {"seq": 3, "stamp": {"secs": 1, "nsecs": 2}, "frame_id": "cam"},
        "height": 2,
        "width": 3,
        "encoding": "rgb8",
        "is_bigendian": 0,
        "step": 9,
        "data": "AAECAwQFBgcICQoLDA0ODxAR",
    }
    assert packer(by_name["sensor_msgs/Image"])(image) == long_way(by_name["sensor_msgs/Image"], image)
