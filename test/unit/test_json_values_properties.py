"""Property tests of rosbridge.codec.json_values: random messages of every field type survive msg -> JSON text -> msg,
and random JSON junk is either turned into a message ROS can send or refused with a ConversionError."""

import json

import genpy
import geometry_msgs.msg
import pytest
import rosgraph_msgs.msg
import sensor_msgs.msg
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_json_values import AllTypes, serialized

import turtlesim.msg
from rosbridge.codec.fields import INT_RANGES, parse_slot_type
from rosbridge.codec.json_values import ConversionError, dumps, from_json, to_json
from rosbridge.message_types import message_class

SETTINGS = settings(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
# For the tests run once for every installed message type (163 on Debian 12): the field kinds recur from type to type,
# so a quarter of Hypothesis' default examples each still tries every kind thousands of times, in a quarter the time.
EACH_TYPE = settings(SETTINGS, max_examples=25)

CLASSES = [
    AllTypes,
    geometry_msgs.msg.Twist,
    turtlesim.msg.Pose,
    sensor_msgs.msg.Image,
    sensor_msgs.msg.CameraInfo,
    rosgraph_msgs.msg.Log,
    geometry_msgs.msg.PoseArray,
]


def _raw_time(cls, low, high):
    """A time or duration as any wire bytes can hold it: nsecs over a second too (genpy carries it into secs)."""

    def make(secs, nsecs):
        value = cls()
        value.secs, value.nsecs = secs, nsecs
        return value

    return st.builds(make, st.integers(low, high), st.integers(low, high))


def scalar_values(base, any_wire_value=False):
    """any_wire_value: also NaN and +-Inf, and times whose nsecs are over a second, as ROS peers may send;
    otherwise only values that come back bit for bit through JSON (NaN/Inf go out as null on purpose)."""
    if base in INT_RANGES:
        return st.integers(*INT_RANGES[base])
    if base in ("float32", "float64"):
        return st.floats(width=32 if base == "float32" else 64, allow_nan=any_wire_value, allow_infinity=any_wire_value)
    if base == "bool":
        return st.booleans()
    if base == "string":
        return st.text(max_size=8)
    if base == "time":
        return (
            _raw_time(genpy.Time, 0, 2**32 - 1)
            if any_wire_value
            else st.builds(genpy.Time, st.integers(0, 2**32 - 1), st.integers(0, 10**9 - 1))
        )
    if base == "duration":
        return (
            _raw_time(genpy.Duration, -(2**31), 2**31 - 1)
            if any_wire_value
            else st.builds(genpy.Duration, st.integers(-(2**31), 2**31 - 1), st.integers(0, 10**9 - 1))
        )
    return messages(message_class(base), any_wire_value)


def field_values(slot_type, any_wire_value=False):
    base, is_array, size = parse_slot_type(slot_type)
    if base == "uint8" and is_array:
        return st.binary(min_size=size or 0, max_size=size or 8)
    if is_array:
        return st.lists(scalar_values(base, any_wire_value), min_size=size or 0, max_size=size or 3)
    return scalar_values(base, any_wire_value)


def messages(cls, any_wire_value=False):
    return st.builds(
        cls,
        **{name: field_values(slot_type, any_wire_value) for name, slot_type in zip(cls.__slots__, cls._slot_types)},
    )


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls._type)
@SETTINGS
@given(data=st.data())
def test_random_messages_round_trip_through_json_text(cls, data):
    msg = data.draw(messages(cls))
    back = from_json(cls, json.loads(dumps(to_json(msg))))
    assert serialized(back) == serialized(msg)
    assert to_json(back) == to_json(msg)


FIELD_NAMES = sorted({name for cls in CLASSES for name in cls.__slots__} | {"secs", "nsecs"})
json_junk = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=6),
    lambda children: (
        st.lists(children, max_size=4)
        | st.dictionaries(st.sampled_from(FIELD_NAMES) | st.text(max_size=3), children, max_size=4)
    ),
    max_leaves=12,
)


@pytest.mark.parametrize("cls", CLASSES, ids=lambda cls: cls._type)
@SETTINGS
@given(data=st.data())
def test_json_junk_is_refused_with_conversion_error_or_accepted_as_sendable(cls, data):
    value = data.draw(json_junk | messages(cls).map(to_json))
    if isinstance(value, dict):  # spoil some fields of a valid message
        for name in data.draw(st.lists(st.sampled_from(cls.__slots__ + ["extra"]), max_size=3)):
            value[name] = data.draw(json_junk)
    try:
        msg = from_json(cls, value, now=lambda: genpy.Time(1, 2))
    except ConversionError:
        return
    serialized(msg)  # whatever is accepted, ROS can send
