"""The demo's optional nodes beside turtlesim_node, run as a user runs them (rosrun): turtle_tf (world -> each
turtle on /tf, the camera and lasers on /tf_static), turtle_laser (a LaserScan per turtle, its settings served by
dynamic_reconfigure) and turtle_actions (each turtle's rotate_absolute action server)."""

import math
import threading
import time

import pytest

from harness import wait_for

CENTRE = 5.544444561004639  # where turtle1 starts (m)


@pytest.fixture(scope="module")
def demo(ros):
    procs = [
        ros.spawn(["rosrun", "turtlesim", name], name)
        for name in ("turtlesim_node", "turtle_tf", "turtle_laser", "turtle_actions")
    ]
    yield
    for proc in procs:
        proc.stop()


def latest(node, topic, type_, predicate, timeout=20):
    found = []

    def look():
        message = node.wait_for_message(topic, type_, timeout=timeout)
        if predicate(message):
            found.append(message)
        return bool(found)

    wait_for(look, timeout, what=f"a matching message on {topic}")
    return found[0]


def test_tf_places_each_turtle_in_the_world_and_the_sensors_statically(demo, node):
    from tf2_msgs.msg import TFMessage

    tf = latest(node, "/tf", TFMessage, lambda m: any(t.child_frame_id == "turtle1" for t in m.transforms))
    turtle1 = next(t for t in tf.transforms if t.child_frame_id == "turtle1")
    assert turtle1.header.frame_id == "world"
    assert (turtle1.transform.translation.x, turtle1.transform.translation.y) == pytest.approx((CENTRE, CENTRE))
    assert turtle1.transform.rotation.w == pytest.approx(1.0)  # facing east
    static = latest(node, "/tf_static", TFMessage, lambda m: len(m.transforms) >= 2)
    assert {(t.header.frame_id, t.child_frame_id) for t in static.transforms} >= {
        ("world", "turtle_camera"),
        ("turtle1", "turtle1/laser"),
    }


def test_the_laser_sees_the_walls_and_a_turtle_spawned_in_front(demo, node, ros):
    from sensor_msgs.msg import LaserScan

    scan = latest(node, "/turtle1/scan", LaserScan, lambda m: True)
    assert scan.header.frame_id == "turtle1/laser" and len(scan.ranges) == 360
    ahead = scan.ranges[round((0.0 - scan.angle_min) / scan.angle_increment)]
    assert ahead == pytest.approx(11.088889 - CENTRE, abs=1e-3)
    ros.run(["rosservice", "call", "/spawn", "8.0", str(CENTRE), "0.0", "turtle2"])
    index = round((0.0 - scan.angle_min) / scan.angle_increment)
    scan = latest(node, "/turtle1/scan", LaserScan, lambda m: m.ranges[index] < 5)
    assert scan.ranges[index] == pytest.approx(8.0 - CENTRE - 0.45, abs=1e-3)
    assert not math.isinf(latest(node, "/turtle2/scan", LaserScan, lambda m: True).ranges[0])
    ros.run(["rosservice", "call", "/kill", "turtle2"])
    wait_for(
        lambda: "/turtle2/scan" not in dict(ros.master().getPublishedTopics("")),
        15,
        what="turtle2's laser to go with it",
    )


# ---- the laser's settings (dynamic_reconfigure) ------------------------------------------------------------------


def test_the_lasers_settings_change_what_it_publishes_and_out_of_range_values_are_clamped(
    demo, laser_settings, node, ros
):
    from sensor_msgs.msg import LaserScan

    ros.run(["rosrun", "dynamic_reconfigure", "dynparam", "set", "/turtle_laser", "rays", "90"])  # as a user does
    scan = latest(node, "/turtle1/scan", LaserScan, lambda m: len(m.ranges) == 90)
    assert scan.angle_increment == pytest.approx(2 * math.pi / 90)
    assert node.get_param("/turtle_laser/rays") == 90
    # beyond the ranges of cfg/Laser.cfg: the node answers (and runs) the nearest end
    answer = laser_settings.update_configuration({"rays": 100000, "rate": 1000.0, "range_max": 3.0})
    assert (answer["rays"], answer["rate"], answer["range_max"]) == (1440, 40.0, 3.0)
    scan = latest(node, "/turtle1/scan", LaserScan, lambda m: len(m.ranges) == 1440)
    assert scan.range_max == 3.0 and scan.scan_time == pytest.approx(1 / 40)
    assert all(math.isinf(r) or r <= 3.0 for r in scan.ranges)
    assert sum(map(math.isinf, scan.ranges)) > 1000  # the walls are 5.5 m away or more, beyond 3 m
    assert 20 < scans_in_a_second(node) <= 42  # 40 Hz asked (10 before), on a busy machine too
    answer = laser_settings.update_configuration({"rays": -5, "noise": 2.0})
    assert (answer["rays"], answer["noise"]) == (3, 0.5)
    # NaN passes dynamic_reconfigure's clamp: the node keeps the value it had, and says so
    answer = laser_settings.update_configuration({"rate": math.nan, "rays": 180, "noise": 0.0})
    assert (answer["rate"], answer["rays"]) == (40.0, 180)
    assert latest(node, "/turtle1/scan", LaserScan, lambda m: len(m.ranges) == 180).scan_time == pytest.approx(1 / 40)
    # a double for the integer `rays` (a web page's call, which dynamic_reconfigure's Client would have made an int)
    # passes the clamp: refused, and the node scans on; an integral one is taken
    assert reconfigure_raw(node, rays=100.5)["rays"] == 180
    assert reconfigure_raw(node, rays=120.0)["rays"] == 120
    assert len(latest(node, "/turtle1/scan", LaserScan, lambda m: len(m.ranges) == 120).ranges) == 120


def reconfigure_raw(node, **doubles):
    """The laser's set_parameters service called with these values as doubles, as a rosbridge client may: its
    answer as a dict."""
    from dynamic_reconfigure.encoding import decode_config
    from dynamic_reconfigure.msg import Config, DoubleParameter
    from dynamic_reconfigure.srv import Reconfigure

    call = node.ServiceProxy("/turtle_laser/set_parameters", Reconfigure)
    config = Config(doubles=[DoubleParameter(name, value) for name, value in doubles.items()])
    return decode_config(call(config).config)


def test_the_lasers_start_up_parameters_are_read_and_clamped_too(demo, node, ros):
    from dynamic_reconfigure.client import Client

    proc = ros.spawn(
        ["rosrun", "turtlesim", "turtle_laser", "__name:=laser_params", "_rays:=99999", "_rate:=2.5"], "laser_params"
    )
    try:
        settings = Client("/laser_params", timeout=30).get_configuration(timeout=10)
        assert (settings["rays"], settings["rate"], settings["range_max"]) == (1440, 2.5, 12.0)
    finally:
        proc.stop()


def scans_in_a_second(node):
    from sensor_msgs.msg import LaserScan

    stamps = []
    subscriber = node.Subscriber("/turtle1/scan", LaserScan, lambda m: stamps.append(m.header.stamp.to_sec()))
    wait_for(lambda: stamps, 10, what="a scan")
    time.sleep(1.0)
    subscriber.unregister()
    return sum(stamp <= stamps[0] + 1.0 for stamp in stamps) - 1


def test_the_lasers_noise_shows_in_its_ranges(demo, laser_settings, node):
    from sensor_msgs.msg import LaserScan

    laser_settings.update_configuration({"noise": 0.0, "rays": 360})
    clean = latest(node, "/turtle1/scan", LaserScan, lambda m: len(m.ranges) == 360)
    laser_settings.update_configuration({"noise": 0.2})
    noisy = latest(node, "/turtle1/scan", LaserScan, lambda m: m.ranges[0] != clean.ranges[0])
    errors = [n - c for n, c in zip(noisy.ranges, clean.ranges) if not math.isinf(c)]
    assert 0.1 < (sum(e * e for e in errors) / len(errors)) ** 0.5 < 0.3  # the standard deviation asked: 0.2 m


# ---- the rotate_absolute action -----------------------------------------------------------------------------------


@pytest.fixture
def rotate(demo, node):
    """An actionlib client of /turtle1/rotate_absolute (turtlesim/RotateAbsolute), the goal cancelled after."""
    import actionlib

    from turtlesim.msg import RotateAbsoluteAction

    client = actionlib.SimpleActionClient("/turtle1/rotate_absolute", RotateAbsoluteAction)
    assert client.wait_for_server(node.Duration(30)), "no /turtle1/rotate_absolute server"
    yield client
    client.cancel_all_goals()


def heading(node):
    from turtlesim.msg import Pose

    return node.wait_for_message("/turtle1/pose", Pose, timeout=10)


def send(rotate, theta):
    """Sends a goal; returns the feedback it gets, as a list that grows."""
    from turtlesim.msg import RotateAbsoluteGoal

    feedback, lock = [], threading.Lock()

    def received(message):
        with lock:
            feedback.append(message.remaining)

    rotate.send_goal(RotateAbsoluteGoal(theta=theta), feedback_cb=received)
    return feedback


def test_a_rotate_goal_turns_the_turtle_to_its_heading_with_feedback(rotate, node):
    from actionlib_msgs.msg import GoalStatus

    from turtlesim.rotate import TOLERANCE, normalized

    start = heading(node).theta
    goal = normalized(start + 2.0)  # 2 rad counter-clockwise: about 2.5 s
    feedback = send(rotate, goal)
    assert rotate.wait_for_result(node.Duration(15))
    assert rotate.get_state() == GoalStatus.SUCCEEDED, rotate.get_goal_status_text()
    assert len(feedback) > 60  # one per pose (62.5 Hz) while it turned
    assert feedback[0] == pytest.approx(2.0, abs=0.05) and abs(feedback[-1]) < 0.03
    assert all(b <= a + 1e-6 for a, b in zip(feedback, feedback[1:]))  # always nearer
    pose = heading(node)
    assert abs(normalized(goal - pose.theta)) < TOLERANCE + 0.01 and pose.angular_velocity == 0.0
    assert rotate.get_result().delta == pytest.approx(normalized(start - pose.theta), abs=0.01)  # ROS 2's delta
    assert "reached" in rotate.get_goal_status_text()


def test_a_cancel_stops_the_turtle_where_it_is(rotate, node):
    from actionlib_msgs.msg import GoalStatus

    from turtlesim.rotate import normalized

    feedback = send(rotate, normalized(heading(node).theta - 3.0))  # clockwise, 3 s or more
    wait_for(lambda: len(feedback) > 20, 10, what="the goal's feedback")
    rotate.cancel_goal()
    assert rotate.wait_for_result(node.Duration(5))
    assert rotate.get_state() == GoalStatus.PREEMPTED
    assert "cancelled at" in rotate.get_goal_status_text()
    time.sleep(0.1)  # (a pose in flight)
    stopped = heading(node)
    time.sleep(0.5)
    still = heading(node)
    assert still.theta == stopped.theta and still.angular_velocity == 0.0
    assert abs(feedback[-1]) > 1.0  # it was stopped on its way


def test_another_driver_takes_the_turtle_over_and_the_goal_is_aborted(rotate, node, ros):
    from actionlib_msgs.msg import GoalStatus

    from turtlesim.rotate import normalized

    feedback = send(rotate, normalized(heading(node).theta + 3.0))
    wait_for(lambda: feedback, 10, what="the goal's feedback")
    ros.run(["rostopic", "pub", "-1", "/turtle1/cmd_vel", "geometry_msgs/Twist", "--", "[0, 0, 0]", "[0, 0, 0]"])
    assert rotate.wait_for_result(node.Duration(10))
    assert rotate.get_state() == GoalStatus.ABORTED
    assert "drove turtle1: goal aborted" in rotate.get_goal_status_text()


@pytest.mark.parametrize("theta", [math.nan, math.inf])
def test_a_goal_that_is_not_a_number_is_aborted_with_the_reason(rotate, node, theta):
    from actionlib_msgs.msg import GoalStatus

    before = heading(node).theta
    send(rotate, theta)
    assert rotate.wait_for_result(node.Duration(5))
    assert rotate.get_state() == GoalStatus.ABORTED
    assert rotate.get_goal_status_text() == f"theta must be a finite number of radians, not {theta}"
    assert heading(node).theta == before
