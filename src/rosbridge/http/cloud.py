"""sensor_msgs/PointCloud2 made small for a top-down view (pure: no rospy, no tornado): read from its serialized
bytes (read_cloud), then decimate() keeps every k-th point, at most max_points, as little-endian float32 triples
(x, y, third), the third being z, else intensity, else 0. Only the bytes of the kept points are touched, by
strided slices (C speed: a 300k-point cloud to 20k points is a few ms); NaN points are passed on (the page skips
them). k is rounded up to one of 8 values per doubling (stride_for), so that the many max_points a client may ask
come to few distinct answers, which Answers keeps within a bound in bytes. The /cloud endpoint (cloud_routes.py)
serves the result."""

import collections
import struct
import sys
from array import array

# sensor_msgs/PointField datatypes: (struct letter, size)
DATATYPES = {1: ("b", 1), 2: ("B", 1), 3: ("h", 2), 4: ("H", 2), 5: ("i", 4), 6: ("I", 4), 7: ("f", 4), 8: ("d", 8)}
FLOAT32, FLOAT64 = 7, 8


class CloudError(ValueError):
    """A cloud that cannot be read or has no x and y."""


class Field:
    __slots__ = ("name", "offset", "datatype", "count")

    def __init__(self, name, offset, datatype, count=1):
        self.name, self.offset, self.datatype, self.count = name, offset, datatype, count


class Cloud:
    """What decimate needs of a PointCloud2; data: its point bytes (a bytes-like object, not copied)."""

    __slots__ = ("stamp", "frame_id", "height", "width", "fields", "is_bigendian", "point_step", "row_step", "data")

    def __init__(self, height, width, fields, is_bigendian, point_step, row_step, data, stamp=0.0, frame_id=""):
        self.height, self.width, self.fields = height, width, fields
        self.is_bigendian, self.point_step, self.row_step, self.data = is_bigendian, point_step, row_step, data
        self.stamp, self.frame_id = stamp, frame_id


class _Reader:
    """ROS serialization (little-endian) read from the start of a message's bytes."""

    def __init__(self, data):
        self.view, self.at = memoryview(data).cast("B"), 0

    def take(self, fmt):
        size = struct.calcsize(fmt)
        if self.at + size > len(self.view):
            raise CloudError("the message is truncated")
        values = struct.unpack_from(fmt, self.view, self.at)
        self.at += size
        return values

    def block(self):
        (length,) = self.take("<I")
        if self.at + length > len(self.view):
            raise CloudError("the message is truncated")
        self.at += length
        return self.view[self.at - length : self.at]

    def header_and_size(self):
        """(stamp, frame_id, height, width): what comes before the fields."""
        _, secs, nsecs = self.take("<III")
        frame_id = bytes(self.block()).decode("utf-8", "replace")
        height, width = self.take("<II")
        return secs + nsecs * 1e-9, frame_id, height, width


def point_count(data):
    """The number of points (height x width) of a serialized sensor_msgs/PointCloud2, read without its fields."""
    _, _, height, width = _Reader(data).header_and_size()
    return height * width


def read_cloud(data):
    """A Cloud from a serialized sensor_msgs/PointCloud2 (ROS serialization, little-endian)."""
    reader = _Reader(data)
    stamp, frame_id, height, width = reader.header_and_size()
    (count,) = reader.take("<I")
    fields = []
    for _ in range(count):
        name = bytes(reader.block()).decode("utf-8", "replace")
        offset, datatype, field_count = reader.take("<IBI")
        fields.append(Field(name, offset, datatype, field_count))
    is_bigendian, point_step, row_step = reader.take("<BII")
    points = reader.block()
    return Cloud(height, width, fields, bool(is_bigendian), point_step, row_step, points, stamp, frame_id)


def stride_for(total, max_points):
    """k for decimate: the smallest stride that keeps at most max_points of total points, rounded up to one of
    8 values per doubling above 15 (16, 18, ... 30, 32, 36, ...): at most 1/8 more than the exact stride, so at
    least 8/9 as many points, and a 300k-point cloud has 111 distinct answers in all."""
    exact = max(1, -(-total // max_points))
    unit = 1 << max(0, exact.bit_length() - 4)
    return -(-exact // unit) * unit


def third_field(cloud):
    """The name of the value sent third: "z", else "intensity", else "none"."""
    names = {field.name for field in cloud.fields}
    return "z" if "z" in names else "intensity" if "intensity" in names else "none"


def decimate(cloud, max_points):
    """(bytes of little-endian float32 triples, points kept, points in the cloud, third field's name): every k-th
    point (k = stride_for(points, max_points)), in the cloud's order. Raises CloudError."""
    if max_points < 1:
        raise CloudError("max_points must be at least 1")
    by_name = {field.name: field for field in cloud.fields}
    if "x" not in by_name or "y" not in by_name:
        raise CloudError("the cloud has no x and y fields")
    width, height, step = cloud.width, cloud.height, cloud.point_step
    total = width * height
    if total == 0:
        return b"", 0, 0, third_field(cloud)
    if step <= 0:
        raise CloudError("point_step must be positive")
    row_bytes = width * step
    row_step = cloud.row_step or row_bytes
    if row_step < row_bytes or len(cloud.data) < row_step * (height - 1) + row_bytes:
        raise CloudError(
            f"the cloud's data ({len(cloud.data)} bytes) is shorter than its {height}x{width} points "
            f"of {step} bytes (row_step {row_step})"
        )
    data = cloud.data
    if height > 1 and row_step != row_bytes:  # rows with padding: their points put end to end first
        data = _unpadded(data, height, row_bytes, row_step)
    stride = stride_for(total, max_points)
    kept = len(range(0, total, stride))
    third = third_field(cloud)
    columns = [
        _column(data, by_name["x"], step, stride, kept, cloud.is_bigendian),
        _column(data, by_name["y"], step, stride, kept, cloud.is_bigendian),
        _column(data, by_name[third], step, stride, kept, cloud.is_bigendian) if third != "none" else bytes(4 * kept),
    ]
    out = bytearray(12 * kept)
    for i, column in enumerate(columns):
        for b in range(4):
            out[4 * i + b :: 12] = column[b::4]
    return bytes(out), kept, total, third


def _unpadded(data, height, row_bytes, row_step):
    """The rows' bytes without their padding, by as few slices as can be (at most the square root of the bytes):
    a row at a time, or, for many short rows, a byte of every row at a time (300k rows: 25 ms, where joining them
    one by one took 140 ms, 40 ms of it in one call that holds the GIL)."""
    view = memoryview(data).cast("B")
    if height <= row_bytes:
        return b"".join(view[r * row_step : r * row_step + row_bytes] for r in range(height))
    out = bytearray(height * row_bytes)
    for b in range(row_bytes):
        out[b::row_bytes] = view[b::row_step][:height]
    return out


def _column(data, field, step, stride, kept, big_endian):
    """One field's values of every stride-th point, as little-endian float32 bytes (4 * kept)."""
    if field.datatype not in DATATYPES:
        raise CloudError(f"field {field.name} has an unknown datatype {field.datatype}")
    letter, size = DATATYPES[field.datatype]
    if field.offset + size > step:
        raise CloudError(f"field {field.name} lies outside its point ({field.offset} + {size} > {step})")
    view = memoryview(data).cast("B")
    every = step * stride
    raw = bytearray(size * kept)
    for b in range(size):  # byte b of each kept value
        raw[b::size] = view[field.offset + b :: every][:kept]
    values = array(letter)
    values.frombytes(bytes(raw))
    if big_endian != (sys.byteorder == "big"):
        values.byteswap()
    if letter != "f":
        values = array("f", values)
    if sys.byteorder == "big":
        values.byteswap()
    return values.tobytes()


class Answers:
    """What was made of each topic's newest cloud: (topic, key) -> answer, at most max_bytes in all (each
    answer's size as put), the least recently asked dropped first; forget(topic) when its next cloud comes."""

    def __init__(self, max_bytes):
        self.max_bytes, self.bytes = max_bytes, 0
        self._kept = collections.OrderedDict()  # (topic, key) -> (answer, size), the least recently asked first
        self._keys = {}  # topic -> its keys in _kept

    def get(self, topic, key):
        found = self._kept.get((topic, key))
        if found is None:
            return None
        self._kept.move_to_end((topic, key))
        return found[0]

    def put(self, topic, key, answer, size):
        if (topic, key) in self._kept:
            self._drop((topic, key))
        if size > self.max_bytes:
            return
        self._kept[topic, key] = (answer, size)
        self._keys.setdefault(topic, set()).add(key)
        self.bytes += size
        while self.bytes > self.max_bytes:
            self._drop(next(iter(self._kept)))

    def forget(self, topic):
        for key in list(self._keys.get(topic, ())):
            self._drop((topic, key))

    def _drop(self, topic_key):
        _, size = self._kept.pop(topic_key)
        self.bytes -= size
        topic, key = topic_key
        keys = self._keys[topic]
        keys.discard(key)
        if not keys:
            del self._keys[topic]
