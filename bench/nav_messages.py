"""What a navigation rover publishes (the rover bench, bench/nav_bench.py), each stream's topic, type, rate and
message, with the odd cases such messages have: NaN and inf ranges, empty arrays, non-ASCII text, a 4000x4000 map,
a 300k-point cloud. Each message is built once; a publisher only sets its stamps (stamp()). Shared by the generator
node (nav_robot.py), the ceiling (nav_ceiling.py), the clients that check what arrives (nav_clients.py) and
convert_bench.py. Needs the ROS message packages (no node); the TF frames and the map's cells come from
testkit/sensor_messages.py (shared with the tests)."""

import io
import math
import random
import struct
import sys
from collections import namedtuple
from pathlib import Path

import genpy
import std_msgs.msg

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "testkit"))
from sensor_messages import moving_frames, occupancy_grid_cells, quaternion, tf_message  # noqa: E402

Stream = namedtuple("Stream", "name topic type hz build")  # hz 0: latched, published once


def serialized(msg):
    buffer = io.BytesIO()
    msg.serialize(buffer)
    return buffer.getvalue()


def deserialized(cls, data):
    msg = cls()
    msg.deserialize(data)
    return msg


# ---- the messages ------------------------------------------------------------------------------------------


def laser_scan():
    """A 1081-ray scan, as a rover's lidar at 40 Hz: ranges with NaN (no return) and inf (out of range)."""
    import sensor_msgs.msg

    rng = random.Random(2)
    scan = sensor_msgs.msg.LaserScan(
        angle_min=-2.35619, angle_max=2.35619, angle_increment=0.004363323, range_min=0.05, range_max=30.0
    )
    scan.header.frame_id = "laser"
    scan.ranges = [
        rng.choice([math.nan, math.inf]) if rng.random() < 0.05 else rng.uniform(0.1, 30) for _ in range(1081)
    ]
    scan.intensities = [float(rng.randrange(256)) for _ in range(1081)]
    return scan


def tf_frames():
    """/tf of a busy robot: 50 frames moving under odom (testkit/sensor_messages.py's)."""
    return moving_frames(0, genpy.Time())


def tf_static():
    """/tf_static: the sensors' mounts on base_link."""
    mounts = [
        ("base_link", "laser", (0.2, 0.0, 0.3), quaternion()),
        ("base_link", "imu_link", (0.0, 0.0, 0.1), quaternion()),
        ("base_link", "gps", (-0.1, 0.0, 0.5), quaternion()),
        ("base_link", "lidar", (0.1, 0.0, 0.6), quaternion(yaw=math.pi / 2)),
        ("base_link", "camera", (0.25, 0.0, 0.4), quaternion(pitch=0.2)),
    ]
    return tf_message(mounts, genpy.Time())


def odometry():
    import nav_msgs.msg

    odom = nav_msgs.msg.Odometry(child_frame_id="base_link")
    odom.header.frame_id = "odom"
    odom.pose.pose.position.x, odom.pose.pose.position.y = 12.5, -3.25
    odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = math.sin(0.3), math.cos(0.3)
    odom.pose.covariance = [0.01 * (i % 7 == 0) for i in range(36)]
    odom.twist.twist.linear.x, odom.twist.twist.angular.z = 0.8, -0.1
    odom.twist.covariance = [0.002 * (i % 7 == 0) for i in range(36)]
    return odom


def imu():
    import sensor_msgs.msg

    msg = sensor_msgs.msg.Imu()
    msg.header.frame_id = "imu_link"
    msg.orientation.x, msg.orientation.w = 0.0998, 0.995
    msg.orientation_covariance = [0.0025, 0, 0, 0, 0.0025, 0, 0, 0, 0.0025]
    msg.angular_velocity.z = 0.02
    msg.angular_velocity_covariance = [-1.0] + [0.0] * 8  # (-1: not known, as drivers say it)
    msg.linear_acceleration.x, msg.linear_acceleration.z = 0.12, 9.81
    msg.linear_acceleration_covariance = [0.04, 0, 0, 0, 0.04, 0, 0, 0, 0.04]
    return msg


def nav_sat_fix():
    import sensor_msgs.msg

    fix = sensor_msgs.msg.NavSatFix(
        latitude=48.858370,
        longitude=2.294481,
        altitude=35.2,
        position_covariance=[1.2, 0, 0, 0, 1.2, 0, 0, 0, 4.0],
        position_covariance_type=sensor_msgs.msg.NavSatFix.COVARIANCE_TYPE_APPROXIMATED,
    )
    fix.header.frame_id = "gps"
    fix.status.status, fix.status.service = sensor_msgs.msg.NavSatStatus.STATUS_FIX, 1
    return fix


def diagnostics():
    """Statuses whose names, messages and values are not ASCII (a French and a Japanese driver), one with no
    values."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    array = DiagnosticArray()
    array.status = [
        DiagnosticStatus(
            level=DiagnosticStatus.OK,
            name="batterie: état",
            message="Chargée à 87 % ✓",
            hardware_id="bms-01",
            values=[KeyValue("tension", "25,2 V"), KeyValue("température", "31 °C")],
        ),
        DiagnosticStatus(
            level=DiagnosticStatus.WARN,
            name="モーター 左",
            message="温度が高い (72 °C)",
            hardware_id="motor-left",
            values=[KeyValue("電流", "3.4 A")],
        ),
        DiagnosticStatus(
            level=DiagnosticStatus.ERROR, name="lidar", message="no data for 2 s — is it 🔌?", hardware_id="", values=[]
        ),
    ]
    return array


def joint_states():
    """Four wheels' positions; velocity and effort empty, as a driver that does not measure them sends them."""
    import sensor_msgs.msg

    return sensor_msgs.msg.JointState(
        name=["wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"], position=[0.5, -1.25, 3.0, 12.75], velocity=[], effort=[]
    )


def point_cloud(points=300_000):
    """An unorganised cloud of x, y, z, intensity (float32 each: 16 bytes a point), as a lidar driver sends it."""
    import sensor_msgs.msg

    cloud = sensor_msgs.msg.PointCloud2(
        height=1, width=points, is_bigendian=False, point_step=16, row_step=16 * points, is_dense=True
    )
    cloud.header.frame_id = "lidar"
    cloud.fields = [
        sensor_msgs.msg.PointField(name=name, offset=4 * i, datatype=7, count=1)
        for i, name in enumerate(("x", "y", "z", "intensity"))
    ]
    cloud.data = random.Random(1).randbytes(16 * points)
    return cloud


def occupancy_grid_class():
    """nav_msgs/OccupancyGrid whose data (int8[]) is held as bytes and written as they are (genpy would pack a
    Python int per cell: seconds and a gigabyte for this map)."""
    import nav_msgs.msg

    class BigOccupancyGrid(nav_msgs.msg.OccupancyGrid):
        def serialize(self, buff):
            cells, self.data = self.data, []
            try:
                head = serialized(super())  # (data empty: its length, 0, is the last 4 bytes)
            finally:
                self.data = cells
            buff.write(head[:-4] + struct.pack("<I", len(cells)))
            buff.write(cells)

    return BigOccupancyGrid


def occupancy_grid(side=4000):
    grid = occupancy_grid_class()()
    grid.header.frame_id = "map"
    grid.info.resolution, grid.info.width, grid.info.height = 0.05, side, side
    grid.info.origin.position.x = grid.info.origin.position.y = -side * 0.05 / 2
    grid.info.origin.orientation.w = 1.0
    grid.data = occupancy_grid_cells(side)
    return grid


STREAMS = (
    Stream("scan", "/scan", "sensor_msgs/LaserScan", 40, laser_scan),
    Stream("tf", "/tf", "tf2_msgs/TFMessage", 100, tf_frames),
    Stream("tf_static", "/tf_static", "tf2_msgs/TFMessage", 0, tf_static),
    Stream("odom", "/odom", "nav_msgs/Odometry", 50, odometry),
    Stream("imu", "/imu/data", "sensor_msgs/Imu", 100, imu),
    Stream("fix", "/fix", "sensor_msgs/NavSatFix", 10, nav_sat_fix),
    Stream("diagnostics", "/diagnostics", "diagnostic_msgs/DiagnosticArray", 1, diagnostics),
    Stream("joint_states", "/joint_states", "sensor_msgs/JointState", 50, joint_states),
    Stream("points", "/points", "sensor_msgs/PointCloud2", 5, point_cloud),
    Stream("map", "/map", "nav_msgs/OccupancyGrid", 0, occupancy_grid),
)
BY_NAME = {stream.name: stream for stream in STREAMS}
BY_TOPIC = {stream.topic: stream for stream in STREAMS}


# ---- stamps ------------------------------------------------------------------------------------------------


def headers(msg):
    """The std_msgs/Header objects in msg (its own, those of an array of messages such as TF's transforms), found
    once: stamp() then sets them."""
    found = []
    if isinstance(msg, std_msgs.msg.Header):
        return [msg]
    for name, kind in zip(msg.__slots__, msg._slot_types):
        if "/" not in kind:
            continue
        value = getattr(msg, name)
        for item in value if kind.endswith("]") else [value]:
            found += headers(item)
    return found


def stamp(header_list, seconds):
    t = genpy.Time.from_sec(seconds)
    for header in header_list:
        header.stamp = t


# A stamp no real message has: a message stamped with it shows where its stamps are, in its ROS bytes and in any
# encoding of them (nav_ceiling.py's templates, nav_clients.py's checks).
SENTINEL = (2147483001, 999999001)
SENTINEL_RAW = struct.pack("<II", *SENTINEL)


def sentinel_bytes(msg):
    """msg's ROS bytes with every stamp the SENTINEL (and the header seq 0), and where each stamp starts."""
    for header in headers(msg):
        header.stamp, header.seq = genpy.Time(*SENTINEL), 0
    data = serialized(msg)
    places, at = [], data.find(SENTINEL_RAW)
    while at >= 0:
        places.append(at)
        at = data.find(SENTINEL_RAW, at + 1)
    if len(places) != len(headers(msg)):
        raise ValueError(f"{msg._type}: {len(places)} sentinel stamps in its bytes, {len(headers(msg))} headers")
    return data, places
