"""The messages the benchmarks send, in both forms: the JSON a rosbridge client sends and the rospy message
object a plain ROS node publishes. Both forms describe the same message, so the bridge and its plain-rospy
baseline move exactly the same data. Each payload carries a sequence number so receivers can check loss."""

import base64
import json
import random
import struct

IMAGE_W, IMAGE_H = 640, 480
STRING_BYTES = 1_000_000


def _image_bytes():
    """A camera-like rgb8 frame: smooth gradients plus a little noise (so PNG compresses it as it would a real
    picture, neither trivially nor not at all). Deterministic."""
    rng = random.Random(0)
    noise = bytes(rng.randrange(8) for _ in range(4096))
    row = bytearray()
    out = bytearray()
    for y in range(IMAGE_H):
        row.clear()
        for x in range(IMAGE_W):
            n = noise[(x * 7 + y * 13) % 4096]
            row += bytes(((x * 255 // IMAGE_W) + n & 255, (y * 255 // IMAGE_H) + n & 255, (x + y) // 5 + n & 255))
        out += row
    return bytes(out)


def _text():
    rng = random.Random(1)
    words = ["turtle", "pose", "twist", "bridge", "rover", "wheel", "sensor", "map", "x", "y", "theta"]
    parts, size = [], 0
    while size < STRING_BYTES:
        w = rng.choice(words)
        parts.append(w)
        size += len(w) + 1
    return " ".join(parts)[:STRING_BYTES]


TYPES = {
    "twist": "geometry_msgs/Twist",
    "float": "std_msgs/Float64",
    "string": "std_msgs/String",
    "image": "sensor_msgs/Image",
    "cloud": "sensor_msgs/PointCloud2",  # (ROS side only: the bridge sends clouds decimated, by HTTP)
}


def json_msg(kind, seq=0):
    """The message as a rosbridge client writes it (a dict ready for json.dumps)."""
    if kind == "twist":
        return {"linear": {"x": float(seq), "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 1.5}}
    if kind == "float":
        return {"data": float(seq)}
    if kind == "string":
        return {"data": _cached("text", _text)}
    if kind == "image":  # (the data encoded for every message, as a server sending an image it has as bytes must)
        return {**_image_fields(seq), "data": base64.b64encode(_cached("image", _image_bytes)).decode()}
    raise ValueError(f"unknown payload kind {kind!r}")


def _image_fields(seq):
    """An image's fields but its data."""
    return {
        "header": {"seq": seq, "stamp": {"secs": 0, "nsecs": 0}, "frame_id": "camera"},
        "height": IMAGE_H,
        "width": IMAGE_W,
        "encoding": "rgb8",
        "is_bigendian": 0,
        "step": IMAGE_W * 3,
    }


def publish_frame(kind, topic, seq=0):
    """A complete rosbridge `publish` op as text."""
    return json.dumps({"op": "publish", "topic": topic, "msg": json_msg(kind, seq)}, separators=(",", ":"))


def cbor_frame(kind, topic, seq=0):
    """The same `publish` op as CBOR, binary fields as byte strings (what a CBOR subscriber gets)."""
    import cbor2

    msg = {**_image_fields(seq), "data": _cached("image", _image_bytes)} if kind == "image" else json_msg(kind, seq)
    return cbor2.dumps({"op": "publish", "topic": topic, "msg": msg})


def ros_bytes(kind, seq=0):
    """The message's ROS 1 bytes, as TCPROS carries it and a Foxglove client publishes it (`ros1`); made here
    without ROS imports, so for a Twist only (six float64s)."""
    if kind != "twist":
        raise ValueError(f"no ROS bytes made here for {kind!r}")
    return struct.pack("<6d", float(seq), 0.0, 0.0, 0.0, 0.0, 1.5)


def ros_msg(kind, seq=0):
    """The same message as a rospy message object (imports ROS message packages, so only in ROS processes)."""
    if kind == "twist":
        from geometry_msgs.msg import Twist, Vector3

        return Twist(linear=Vector3(x=float(seq)), angular=Vector3(z=1.5))
    if kind == "float":
        from std_msgs.msg import Float64

        return Float64(data=float(seq))
    if kind == "string":
        from std_msgs.msg import String

        return String(data=_cached("text", _text))
    if kind == "image":
        from sensor_msgs.msg import Image
        from std_msgs.msg import Header

        return Image(
            header=Header(seq=seq, frame_id="camera"),
            height=IMAGE_H,
            width=IMAGE_W,
            encoding="rgb8",
            is_bigendian=0,
            step=IMAGE_W * 3,
            data=_cached("image", _image_bytes),
        )
    if kind == "cloud":  # (testkit/sensor_messages.py: the cloud the viewer's tests draw; on PYTHONPATH in the suite)
        from sensor_messages import big_cloud

        return _cached("cloud", big_cloud)
    raise ValueError(f"unknown payload kind {kind!r}")


def seq_of(kind, msg):
    """The sequence number in a received message, given as a rospy object, a JSON dict, or its ROS bytes (as
    cbor-raw's {"bytes": ...} or foxglove_bridge's payload)."""
    msg = _ros_bytes(msg)
    if isinstance(msg, (bytes, memoryview)):  # (twist: linear.x first; float: data; image, cloud: header.seq)
        return (
            int(struct.unpack_from("<d", msg)[0])
            if kind in ("twist", "float")
            else struct.unpack_from("<I", msg)[0]
            if kind in ("image", "cloud")
            else 0
        )
    if isinstance(msg, dict):
        if kind == "twist":
            return int(msg["linear"]["x"])
        if kind == "float":
            return int(msg["data"])
        if kind == "image":
            return int(msg["header"]["seq"])
        return 0
    if kind == "twist":
        return int(msg.linear.x)
    if kind == "float":
        return int(msg.data)
    if kind in ("image", "cloud"):
        return int(msg.header.seq)
    return 0


_cache = {}


def _cached(key, make):
    if key not in _cache:
        _cache[key] = make()
    return _cache[key]


def stamp_of(kind, msg):
    """The header stamp (seconds) of a received image or cloud, or the send time a Twist carries in angular.y
    (ros_roles.py pub --stamp: its ROS bytes keep their 48), as seq_of takes it; None for the others."""
    if kind == "twist":
        msg = _ros_bytes(msg)
        if isinstance(msg, (bytes, memoryview)):
            stamp = struct.unpack_from("<d", msg, 32)[0]  # (linear x, y, z, angular x, then y)
        else:
            stamp = msg["angular"]["y"] if isinstance(msg, dict) else msg.angular.y
        return stamp or None
    if kind not in ("image", "cloud"):
        return None
    msg = _ros_bytes(msg)
    if isinstance(msg, (bytes, memoryview)):
        secs, nsecs = struct.unpack_from("<II", msg, 4)
    elif isinstance(msg, dict):
        secs, nsecs = msg["header"]["stamp"]["secs"], msg["header"]["stamp"]["nsecs"]
    else:
        secs, nsecs = msg.header.stamp.secs, msg.header.stamp.nsecs
    return secs + nsecs / 1e9 if secs else None


def _ros_bytes(msg):
    """cbor-raw's message ({"bytes": the ROS bytes, "secs", "nsecs": when the bridge got it}) as its bytes."""
    return msg["bytes"] if isinstance(msg, dict) and "bytes" in msg else msg
