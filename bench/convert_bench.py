"""Micro-benchmark of the ROS <-> JSON conversion, in microseconds per call: the bridge's direct roads
(rosbridge.codec.ros_to_json: ROS bytes -> JSON text; codec.json_to_ros: parsed JSON -> ROS bytes) beside the genpy roads
(deserialize + convert.to_json + dumps; convert.from_json + serialize), and the other wire encodings (best of several repeats, so a busy machine disturbs it less). No roscore needed:

    export PATH=/usr/bin:$PATH; source .build/setup.bash; python3 bench/convert_bench.py
"""
import io
import json
import timeit

import geometry_msgs.msg
import sensor_msgs.msg

from rosbridge.codec.json_values import dumps, from_json, to_json
from rosbridge.codec.cbor import to_cbor_value
from rosbridge.codec.wrapping import png_frame
from rosbridge.frames import cbor_frame
from rosbridge.codec.json_to_ros import packer
from rosbridge.codec.ros_to_json import json_text


def best_microseconds(function, repeats=5):
    timer = timeit.Timer(function)
    number, _ = timer.autorange()  # enough calls for about 0.2 s
    return min(timer.repeat(repeats, number)) / number * 1e6


def samples():
    twist = geometry_msgs.msg.Twist()
    twist.linear.x, twist.angular.z = 1.5, -0.25
    image = sensor_msgs.msg.Image(height=480, width=640, encoding="rgb8", step=640 * 3,
                                  data=bytes(range(256)) * (640 * 480 * 3 // 256))
    image.header.frame_id = "camera"
    return {"geometry_msgs/Twist": twist, "sensor_msgs/Image 640x480 rgb8": image}


def serialized(msg):
    buffer = io.BytesIO()
    msg.serialize(buffer)
    return buffer.getvalue()


def deserialized(cls, data):
    msg = cls()
    msg.deserialize(data)
    return msg


def main():
    print(f"{'message':34} {'operation':36} {'us/call':>10}")
    for name, msg in samples().items():
        value = to_json(msg)
        parsed = json.loads(dumps(value))
        cls, data = type(msg), serialized(msg)
        cases = {
            "bytes -> text: genpy, to_json, dumps": lambda: dumps(to_json(deserialized(cls, data))),
            "bytes -> text: wire.json_text": lambda: json_text(cls)(data),
            "parsed -> bytes: from_json, genpy": lambda: serialized(from_json(cls, parsed)),
            "parsed -> bytes: packing.packer": lambda: packer(cls)(parsed),
            "to_json": lambda: to_json(msg),
            "from_json": lambda: from_json(type(msg), parsed),
            "dumps(to_json)": lambda: dumps(to_json(msg)),
            "from_json(json.loads(text))": lambda text=dumps(value): from_json(type(msg), json.loads(text)),
            "cbor_frame(to_cbor_value)": lambda: cbor_frame(to_cbor_value(msg)),
            "png_frame(dumps(to_json))": lambda: png_frame(dumps(to_json(msg))),
        }
        for operation, function in cases.items():
            print(f"{name:34} {operation:36} {best_microseconds(function):10.2f}")


if __name__ == "__main__":
    main()
