"""rosbridge.codec.ros_to_json against genpy: for every message type on this machine, random messages serialized by genpy give
exactly the JSON text the bridge wrote before (genpy deserialization, convert.to_json, convert.dumps)."""
import base64
import math

import genpy
import genpy.dynamic
import pytest
import rosmsg
import rospkg
from hypothesis import given, strategies as st
from sensor_msgs.msg import CompressedImage
from std_msgs.msg import Header

from test_json_values import AllTypes, serialized
from test_json_values_properties import SETTINGS, messages
from rosbridge.codec.json_values import dumps, to_json
from rosbridge.codec import BIG_BYTES
from rosbridge.types import UnknownType, message_class
from rosbridge.codec.ros_to_json import SPLICE_MARK, joined, json_parts, json_text


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
@SETTINGS
@given(data=st.data())
def test_random_messages_give_the_text_of_genpy_and_convert(cls, data):
    wire_bytes = serialized(data.draw(messages(cls, any_wire_value=True)))
    assert json_text(cls)(wire_bytes) == genpy_json_text(cls, wire_bytes)


def test_special_values():
    msg = AllTypes(f32=math.inf, f64=math.nan, f64s=[-math.inf, 1.5], s='quote " back \\ and \x01 ☃',
                   strings=["", "😀"], bools=[True, False, True], signed_bytes=[-1, 5], chars=b"\xff\x00ab")
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
    image = message_class("sensor_msgs/Image")(height=480, width=640, encoding="rgb8", step=1920,
                                               data=bytes(range(256)) * 3600)
    data = serialized(image)
    assert json_text(type(image))(data) == genpy_json_text(type(image), data)


def _spliced_type():
    """Big byte arrays before, inside and after an array of nested messages."""
    separator = "=" * 80 + "\n"
    definition = "uint8[] first\nsensor_msgs/CompressedImage[] images\nstring between\nuint8[] last\n" + "".join(
        f"{separator}MSG: {cls._type}\n{cls._full_text}\n" for cls in (CompressedImage, Header))
    return genpy.dynamic.generate_dynamic("test_wire/Spliced", definition)["test_wire/Spliced"]


def test_big_byte_arrays_are_left_out_of_the_text_in_order():
    cls = _spliced_type()
    blobs = [bytes([i]) * (60_000 + i) for i in range(4)]  # each over 64 KB in base64
    msg = cls(first=blobs[0], images=[CompressedImage(format="jpeg", data=blobs[1]), CompressedImage(data=b"ab"),
                                      CompressedImage(data=blobs[2])], between="x", last=blobs[3])
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
