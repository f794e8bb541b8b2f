"""cloud.py: a sensor_msgs/PointCloud2 read from its serialized bytes and decimated to a bounded number of
little-endian float32 triples (x, y, z / intensity / 0), whatever its fields' types, byte order and row padding;
the strides few distinct max_points come to, and the answers kept within a bound in bytes."""

import io
import math
import struct
import time
from array import array

import pytest
from sensor_msgs.msg import PointCloud2, PointField

from rosbridge.http.cloud import Answers, CloudError, decimate, point_count, read_cloud, stride_for

F32, F64, U16 = PointField.FLOAT32, PointField.FLOAT64, PointField.UINT16


def serialized(msg):
    out = io.BytesIO()
    msg.serialize(out)
    return out.getvalue()


def cloud_message(points, fields, formats, point_step, height=1, row_padding=0, big_endian=False, frame="lidar"):
    """points: tuples of values, packed by formats (struct letters per field) at the fields' offsets."""
    order = ">" if big_endian else "<"
    width = len(points) // height
    rows = []
    for r in range(height):
        row = bytearray()
        for values in points[r * width : (r + 1) * width]:
            point = bytearray(point_step)
            for (_name, offset, _), letter, value in zip(fields, formats, values):
                struct.pack_into(order + letter, point, offset, value)
            row += point
        rows.append(bytes(row) + bytes(row_padding))
    msg = PointCloud2(
        height=height,
        width=width,
        is_bigendian=big_endian,
        point_step=point_step,
        row_step=width * point_step + row_padding,
        data=b"".join(rows),
        is_dense=False,
        fields=[PointField(name=n, offset=o, datatype=t, count=1) for n, o, t in fields],
    )
    msg.header.frame_id = frame
    msg.header.stamp.secs, msg.header.stamp.nsecs = 12, 250_000_000
    return serialized(msg)


def triples(body):
    values = array("f")
    values.frombytes(body)
    return [tuple(values[i : i + 3]) for i in range(0, len(values), 3)]


XYZI = [("x", 0, F32), ("y", 4, F32), ("z", 8, F32), ("intensity", 16, F32)]


def test_xyz_float32_read_and_kept_whole_when_small():
    points = [(i, -i, 0.5 * i, 9.0) for i in range(10)]
    cloud = read_cloud(cloud_message(points, XYZI, "ffff", 32))
    assert (cloud.width, cloud.height, cloud.point_step, cloud.frame_id) == (10, 1, 32, "lidar")
    assert cloud.stamp == pytest.approx(12.25)
    body, kept, total, third = decimate(cloud, 100)
    assert (kept, total, third) == (10, 10, "z")
    assert triples(body) == [(i, -i, 0.5 * i) for i in range(10)]


def test_every_kth_point_at_most_max_points():
    points = [(i, 2 * i, 3 * i) for i in range(1000)]
    raw = cloud_message(points, XYZI[:3], "fff", 12)
    cloud = read_cloud(raw)
    assert point_count(raw) == 1000
    for max_points, stride in ((1, 1024), (7, 144), (100, 10), (333, 4), (999, 2), (1000, 1), (5000, 1)):
        body, kept, total, _ = decimate(cloud, max_points)
        assert stride_for(1000, max_points) == stride
        assert kept <= max_points and total == 1000 and len(body) == 12 * kept
        assert triples(body) == [(i, 2 * i, 3 * i) for i in range(0, 1000, stride)]


def test_strides_are_exact_to_15_then_8_per_doubling_keeping_at_least_8_9_of_the_points():
    assert [stride_for(n, 1) for n in range(1, 16)] == list(range(1, 16))
    assert [stride_for(n, 1) for n in range(16, 34)] == [
        16,
        18,
        18,
        20,
        20,
        22,
        22,
        24,
        24,
        26,
        26,
        28,
        28,
        30,
        30,
        32,
        32,
        36,
    ]
    total = 300_000
    strides = {stride_for(total, m) for m in range(1, 200_001)}
    assert len(strides) == 111
    for max_points in range(1, 200_001, 7):
        exact, stride = math.ceil(total / max_points), stride_for(total, max_points)
        kept = len(range(0, total, stride))
        assert kept <= max_points and stride < exact * 9 / 8 + 1e-9
        assert kept >= len(range(0, total, exact)) * 8 / 9


def test_intensity_third_when_there_is_no_z_and_zero_when_neither():
    fields = [("intensity", 0, F32), ("x", 4, F32), ("y", 8, F32)]
    cloud = read_cloud(cloud_message([(7.0, 1.0, 2.0), (8.0, 3.0, 4.0)], fields, "fff", 12))
    body, _, _, third = decimate(cloud, 10)
    assert third == "intensity" and triples(body) == [(1, 2, 7), (3, 4, 8)]
    cloud = read_cloud(cloud_message([(1.0, 2.0)], [("x", 0, F32), ("y", 4, F32)], "ff", 8))
    body, _, _, third = decimate(cloud, 10)
    assert third == "none" and triples(body) == [(1, 2, 0)]


def test_float64_uint16_and_big_endian_fields():
    fields = [("x", 0, F64), ("y", 8, F64), ("intensity", 16, U16)]
    for big in (False, True):
        cloud = read_cloud(cloud_message([(1.5, -2.25, 300), (1e3, 0.125, 65535)], fields, "ddH", 20, big_endian=big))
        assert cloud.is_bigendian is big
        assert triples(decimate(cloud, 10)[0]) == [(1.5, -2.25, 300), (1000, 0.125, 65535)]


def test_rows_with_padding_and_nan_points_passed_on():
    points = [(float(i), float(i), math.nan if i == 4 else 1.0) for i in range(12)]
    cloud = read_cloud(cloud_message(points, XYZI[:3], "fff", 16, height=3, row_padding=5))
    assert cloud.row_step == 4 * 16 + 5
    got = triples(decimate(cloud, 100)[0])
    assert [p[:2] for p in got] == [(i, i) for i in range(12)] and math.isnan(got[4][2])


@pytest.mark.parametrize("width", [1, 2, 3])
def test_many_short_padded_rows(width):
    """More rows than bytes in a row: unpadded a byte of every row at a time, not a row at a time."""
    points = [(float(i), -float(i), 0.5 * i) for i in range(120 * width)]
    cloud = read_cloud(cloud_message(points, XYZI[:3], "fff", 12, height=120, row_padding=3))
    for max_points in (1000, 50, 7):
        stride = stride_for(len(points), max_points)
        assert triples(decimate(cloud, max_points)[0]) == [points[i] for i in range(0, len(points), stride)]


def test_empty_clouds_and_bad_ones():
    empty = read_cloud(cloud_message([], XYZI[:3], "fff", 12))
    assert decimate(empty, 10) == (b"", 0, 0, "z")
    with pytest.raises(CloudError, match="no x and y"):
        decimate(read_cloud(cloud_message([(1.0,)], [("x", 0, F32)], "f", 4)), 10)
    with pytest.raises(CloudError, match="shorter"):
        cloud = read_cloud(cloud_message([(1.0, 2.0, 3.0)] * 4, XYZI[:3], "fff", 12))
        cloud.data = cloud.data[:-1]
        decimate(cloud, 10)
    with pytest.raises(CloudError, match="outside its point"):
        cloud = read_cloud(cloud_message([(1.0, 2.0)], [("x", 0, F32), ("y", 4, F32)], "ff", 8))
        cloud.fields[1].offset = 6
        decimate(cloud, 10)
    with pytest.raises(CloudError, match="truncated"):
        read_cloud(cloud_message([(1.0, 2.0, 3.0)], XYZI[:3], "fff", 12)[:-8])
    with pytest.raises(CloudError, match="truncated"):
        point_count(cloud_message([(1.0, 2.0, 3.0)], XYZI[:3], "fff", 12)[:20])


def test_a_300k_point_cloud_decimated_quickly_without_copying_it_whole():
    n = 300_000
    data = array("f", [v for i in range(n) for v in (i, -i, 0.001 * i, 0.0)]).tobytes()
    msg = PointCloud2(
        height=1,
        width=n,
        point_step=16,
        row_step=16 * n,
        data=data,
        fields=[
            PointField(name=k, offset=o, datatype=F32, count=1)
            for k, o in (("x", 0), ("y", 4), ("z", 8), ("intensity", 12))
        ],
    )
    raw = serialized(msg)
    started = time.perf_counter()
    cloud = read_cloud(raw)
    body, kept, total, _ = decimate(cloud, 20000)
    elapsed = time.perf_counter() - started
    assert (kept, total) == (20000, n) and len(body) == 240_000
    assert triples(body)[-1] == pytest.approx((299_985, -299_985, 299.985), rel=1e-6)
    assert elapsed < 0.05, elapsed


def test_answers_are_kept_within_their_bytes_the_least_recently_asked_dropped_first():
    answers = Answers(100)
    answers.put("/a", 1, "a1", 40)
    answers.put("/a", 2, "a2", 40)
    assert answers.get("/a", 1) == "a1"  # (now the most recently asked)
    answers.put("/b", 1, "b1", 40)
    assert (answers.get("/a", 2), answers.get("/a", 1), answers.get("/b", 1), answers.bytes) == (None, "a1", "b1", 80)
    answers.put("/b", 1, "b1'", 50)  # (in place of the one before)
    assert (answers.get("/b", 1), answers.bytes) == ("b1'", 90)
    answers.put("/c", 1, "too big", 101)
    assert (answers.get("/c", 1), answers.bytes) == (None, 90)
    answers.forget("/a")  # (its next cloud came)
    assert (answers.get("/a", 1), answers.get("/b", 1), answers.bytes) == (None, "b1'", 50)
    answers.forget("/b")
    answers.forget("/never")
    assert answers.bytes == 0
