"""A robot's sensor messages, made alike for the tests (test/browser/test_viewers.py) and the benchmarks
(bench/page_bench.py, bench/payloads.py), and a thread that publishes them at a steady rate. Needs the ROS message
packages; only Publishing needs a node."""

import math
import random
import threading
import time
from array import array

CAMERA = "/turtle_camera/image_raw"  # the demo camera's topic (rosrun turtlesim turtle_camera)


def quaternion(roll=0.0, pitch=0.0, yaw=0.0):
    """(x, y, z, w) of the rotation roll, pitch, yaw (radians), as tf writes it."""
    cr, sr, cp, sp, cy, sy = (f(a / 2) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def tf_message(transforms, stamp):
    """tf2_msgs/TFMessage of [(parent, child, (tx, ty, tz), (qx, qy, qz, qw))]."""
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    message = TFMessage()
    for parent, child, t, q in transforms:
        stamped = TransformStamped()
        stamped.header.stamp, stamped.header.frame_id, stamped.child_frame_id = stamp, parent, child
        (stamped.transform.translation.x, stamped.transform.translation.y, stamped.transform.translation.z) = t
        r = stamped.transform.rotation
        r.x, r.y, r.z, r.w = q
        message.transforms.append(stamped)
    return message


def moving_frames(n, stamp, parent="odom", prefix="moving_", count=50):
    """The n-th message of `count` frames (prefix0 ...) circling under parent, each turning: at 100 Hz, a busy
    robot's /tf."""
    return tf_message(
        [
            (parent, f"{prefix}{i}", (math.cos(n / 100 + i), math.sin(n / 100 + i), 0.0), quaternion(yaw=n / 100))
            for i in range(count)
        ],
        stamp,
    )


def wide_scan(n, stamp, frame="fast_laser"):
    """The n-th scan of a 1081-ray, 270° lidar (40 Hz on a rover): walls 2-4 m away that sway from scan to scan."""
    from sensor_msgs.msg import LaserScan

    message = LaserScan(
        angle_min=-2.35,
        angle_max=2.35,
        angle_increment=4.7 / 1081,
        range_min=0.1,
        range_max=30.0,
        ranges=[3 + math.sin(i / 30 + n / 10) for i in range(1081)],
    )
    message.header.stamp, message.header.frame_id = stamp, frame
    return message


def big_cloud(n=300_000):
    """A sensor_msgs/PointCloud2 of n points (x, y, z, intensity as float32: 16 bytes each) in frame `lidar`:
    a disc of radius 10 m, z rising with the angle."""
    from sensor_msgs.msg import PointCloud2, PointField

    values = array("f")
    for i in range(n):
        angle, radius = i * 2.399963, 10 * math.sqrt(i / n)
        values.extend((radius * math.cos(angle), radius * math.sin(angle), (i % 100) / 50, 1.0))
    message = PointCloud2(
        height=1,
        width=n,
        point_step=16,
        row_step=16 * n,
        is_dense=True,
        data=values.tobytes(),
        fields=[
            PointField(name=k, offset=o, datatype=PointField.FLOAT32, count=1)
            for k, o in (("x", 0), ("y", 4), ("z", 8), ("intensity", 12))
        ],
    )
    message.header.frame_id = "lidar"
    return message


class Publishing:
    """Publishes make(n) for n = 0, 1, ... on topic at rate_hz from a thread, on a fixed schedule (no drift);
    `published` counts the messages sent, stop() ends it and unregisters the publisher."""

    def __init__(self, rospy, topic, msg_class, make, rate_hz, latch=False):
        self.publisher = rospy.Publisher(topic, msg_class, queue_size=10, latch=latch)
        self.make, self.period = make, 1.0 / rate_hz
        self.published = 0
        self.stopped = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        due = time.monotonic()
        while not self.stopped.is_set():
            self.publisher.publish(self.make(self.published))
            self.published += 1
            due += self.period
            self.stopped.wait(max(0.0, due - time.monotonic()))

    def stop(self):
        self.stopped.set()
        self._thread.join(10)  # (rospy fails a publish to a topic unregistered meanwhile)
        self.publisher.unregister()


def occupancy_grid_cells(side=4000):
    """The cells of a side x side map as SLAM makes one: unknown (-1) around the explored part, free (0) inside
    it, walls and obstacles (100) and some cells in between."""
    rng = random.Random(0)
    cells = bytearray(b"\xff") * (side * side)
    for y in range(side // 8, side - side // 8):
        cells[y * side + side // 8 : y * side + side - side // 8] = bytes(side - side // 4)
    for _ in range(side * 5):
        at = rng.randrange(side * side - 8)
        cells[at : at + 8] = bytes([rng.choice([100, 100, 100, 50, 99, 1])]) * 8
    return bytes(cells)
