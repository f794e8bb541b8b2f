"""The demo's optional nodes beside turtlesim_node, run as a user runs them (rosrun): turtle_tf (world -> each
turtle on /tf, the camera and lasers on /tf_static) and turtle_laser (a LaserScan per turtle)."""
import math

import pytest

from harness import wait_for

CENTRE = 5.544444561004639  # where turtle1 starts (m)


@pytest.fixture(scope="module")
def demo(ros):
    procs = [ros.spawn(["rosrun", "turtlesim", name], name) for name in ("turtlesim_node", "turtle_tf",
                                                                         "turtle_laser")]
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
        ("world", "turtle_camera"), ("turtle1", "turtle1/laser")}


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
    wait_for(lambda: "/turtle2/scan" not in dict(ros.master().getPublishedTopics("")), 15,
             what="turtle2's laser to go with it")
