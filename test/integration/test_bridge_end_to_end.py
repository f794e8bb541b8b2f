"""The bridge end to end with a real client library (roslibpy) and real ROS nodes: turtlesim_node, rospy
publishers/subscribers/services in the test process, and the rosservice CLI."""

import math
import threading

import pytest
import roslibpy

from fixtures import bridge_fixture
from harness import wait_for

bridge = bridge_fixture()


@pytest.fixture(scope="module")
def turtlesim(ros):
    with ros.spawn(["rosrun", "turtlesim", "turtlesim_node"], "turtlesim_node") as proc:
        wait_for(lambda: "/turtle1/pose" in dict(ros.master().getTopicTypes()), 30, what="/turtle1/pose")
        yield proc


@pytest.fixture
def client(bridge):
    ros = roslibpy.Ros(host="127.0.0.1", port=bridge)
    ros.run(timeout=20)
    yield ros
    ros.close()


def call(client, name, args=None, service_type=None):
    """A blocking call_service; returns the values, raises roslibpy's error for result:false."""
    return roslibpy.Service(client, name, service_type).call(roslibpy.ServiceRequest(args or {}), timeout=20)


def test_publish_twist_moves_the_turtle(client, turtlesim, node):
    from turtlesim.msg import Pose

    start = node.wait_for_message("/turtle1/pose", Pose, timeout=20)
    cmd = roslibpy.Topic(client, "/turtle1/cmd_vel", "geometry_msgs/Twist")
    twist = roslibpy.Message({"linear": {"x": 2.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0, "y": 0, "z": 0}})

    def moved():
        cmd.publish(twist)
        pose = node.wait_for_message("/turtle1/pose", Pose, timeout=20)
        return math.hypot(pose.x - start.x, pose.y - start.y) > 0.3

    wait_for(moved, 30, interval=0.1, what="the turtle to move")


def test_subscribe_to_pose(client, turtlesim):
    poses = []
    topic = roslibpy.Topic(client, "/turtle1/pose", "turtlesim/Pose")
    topic.subscribe(poses.append)
    wait_for(lambda: len(poses) >= 3, 20, what="three poses")
    topic.unsubscribe()
    assert set(poses[0]) == {"x", "y", "theta", "linear_velocity", "angular_velocity"}
    assert 0 <= poses[0]["x"] <= 12


def test_subscribe_without_type_infers_it(client, turtlesim):
    poses = []
    roslibpy.Topic(client, "/turtle1/pose", None).subscribe(poses.append)
    wait_for(lambda: poses, 20, what="a pose")
    assert "theta" in poses[0]


def test_call_spawn_and_clear(client, turtlesim, ros):
    reply = call(client, "/spawn", {"x": 3.0, "y": 4.0, "theta": 0.5, "name": "bridged"})
    assert reply == {"name": "bridged"}
    wait_for(lambda: "/bridged/pose" in dict(ros.master().getTopicTypes()), 20, what="/bridged/pose")
    assert call(client, "/clear") == {}
    assert call(client, "/kill", {"name": "bridged"}) == {}


def test_missing_service_fails_with_its_name(client):
    with pytest.raises(Exception, match="Service /no_such_service does not exist"):
        call(client, "/no_such_service")


def test_service_error_text_reaches_the_client(client, turtlesim):
    with pytest.raises(Exception, match="(?i)kill"):
        call(client, "/kill", {"name": "nobody_has_this_name"})


def test_publish_reaches_a_rospy_subscriber(client, node):
    from std_msgs.msg import String

    got = []
    sub = node.Subscriber("/bridge_test/chatter", String, lambda m: got.append(m.data))
    topic = roslibpy.Topic(client, "/bridge_test/chatter", "std_msgs/String")

    def received():
        topic.publish(roslibpy.Message({"data": "hello ros"}))
        return got

    assert wait_for(received, 20, interval=0.2, what="the message in rospy")[0] == "hello ros"
    sub.unregister()


def test_header_stamp_is_filled_when_missing(client, node):
    from geometry_msgs.msg import PointStamped

    got = []
    sub = node.Subscriber("/bridge_test/point", PointStamped, got.append)
    topic = roslibpy.Topic(client, "/bridge_test/point", "geometry_msgs/PointStamped")

    def received():
        topic.publish(roslibpy.Message({"header": {"frame_id": "map"}, "point": {"x": 1, "y": 2, "z": 3}}))
        return got

    msg = wait_for(received, 20, interval=0.2, what="the point")[0]
    sub.unregister()
    assert msg.header.frame_id == "map" and msg.point.y == 2.0
    assert abs(msg.header.stamp.to_sec() - node.Time.now().to_sec()) < 60


def test_header_seq_counts_as_rospy_publishers_count(client, node):
    """A client's header.seq is replaced by the publisher's count (1, 2, 3, ...), as rospy does for its nodes."""
    from geometry_msgs.msg import PointStamped

    got = []
    sub = node.Subscriber("/bridge_test/seq", PointStamped, got.append)
    topic = roslibpy.Topic(client, "/bridge_test/seq", "geometry_msgs/PointStamped")
    stamp = {"secs": 5, "nsecs": 6}

    def received():
        topic.publish(roslibpy.Message({"header": {"seq": 77, "stamp": stamp, "frame_id": "first"}}))
        return got

    wait_for(received, 20, interval=0.2, what="the first point")
    for n in range(3):
        topic.publish(roslibpy.Message({"header": {"seq": 77, "stamp": stamp, "frame_id": f"p{n}"}, "point": {"x": n}}))
    wait_for(lambda: got[-1].header.frame_id == "p2", 10, what="three more points")
    sub.unregister()
    seqs = [m.header.seq for m in got]
    assert 77 not in seqs and seqs == list(range(seqs[0], seqs[0] + len(seqs)))
    assert [m.header.frame_id for m in got[-3:]] == ["p0", "p1", "p2"]
    assert [m.point.x for m in got[-3:]] == [0.0, 1.0, 2.0] and got[-1].header.stamp.secs == 5


def test_client_advertised_service_answers_rosservice(client, ros):
    service = roslibpy.Service(client, "/bridge_test/flip", "std_srvs/SetBool")
    requests = []

    def handler(request, response):
        requests.append(request)
        response.update(success=not request["data"], message="flipped")
        return True

    service.advertise(handler)
    wait_for(lambda: "/bridge_test/flip" in ros.run(["rosservice", "list"]).stdout, 20, what="the service")
    out = ros.run(["rosservice", "call", "/bridge_test/flip", "data: true"]).stdout
    assert "success: False" in out and "flipped" in out
    assert requests == [{"data": True}]
    service.unadvertise()
    wait_for(lambda: "/bridge_test/flip" not in ros.run(["rosservice", "list"]).stdout, 20, what="unadvertised")


def test_a_handler_returning_false_still_answers_its_values(client, ros):
    """roslibpy's own add_two_ints example fills the response and returns False: the ROS caller still gets it."""
    service = roslibpy.Service(client, "/bridge_test/add_two_ints", "std_srvs/SetBool")

    def handler(request, response):
        response.update(success=True, message="sum 42")
        return False

    service.advertise(handler)
    wait_for(lambda: "/bridge_test/add_two_ints" in ros.run(["rosservice", "list"]).stdout, 20, what="the service")
    out = ros.run(["rosservice", "call", "/bridge_test/add_two_ints", "data: true"]).stdout
    assert "success: True" in out and 'message: "sum 42"' in out
    service.unadvertise()


def test_rosapi_is_answered_inside_the_bridge(client, turtlesim):
    reply = call(client, "/rosapi/topics")
    assert "/turtle1/pose" in reply["topics"]
    assert reply["types"][reply["topics"].index("/turtle1/pose")] == "turtlesim/Pose"


def test_client_count_counts_connections(bridge, client, node):
    from std_msgs.msg import Int32

    through_bridge = []
    roslibpy.Topic(client, "/client_count", "std_msgs/Int32").subscribe(lambda m: through_bridge.append(m["data"]))
    wait_for(lambda: through_bridge, 20, what="the latched client count through the bridge")
    # other bridges on this master (other test modules) publish their own counts: keep this bridge's only
    counts = []
    sub = node.Subscriber(
        "/client_count",
        Int32,
        lambda m: m._connection_header["callerid"] == "/rosbridge_websocket" and counts.append(m.data),
    )
    try:
        wait_for(lambda: counts, 20, what="the latched client count")
        before = counts[-1]
        assert before >= 1  # `client` itself
        other = roslibpy.Ros(host="127.0.0.1", port=bridge)
        other.run(timeout=20)
        wait_for(lambda: counts[-1] == before + 1, 20, what="count + 1")
        other.close()
        wait_for(lambda: counts[-1] == before, 20, what="count back")
    finally:
        sub.unregister()


def test_rospy_service_called_and_bad_args_refused(client, node):
    from std_srvs.srv import SetBool, SetBoolResponse

    server = node.Service("/bridge_test/set_bool", SetBool, lambda req: SetBoolResponse(req.data, "ok"))
    try:
        assert call(client, "/bridge_test/set_bool", {"data": True}) == {"success": True, "message": "ok"}
        assert call(client, "/bridge_test/set_bool", {"data": False}) == {"success": False, "message": "ok"}
        with pytest.raises(Exception, match="data"):
            call(client, "/bridge_test/set_bool", {"data": "yes"})
    finally:
        server.shutdown()


def test_subscribe_receives_from_rospy_publisher(client, node):
    from std_msgs.msg import Int32

    pub = node.Publisher("/bridge_test/numbers", Int32, queue_size=10)
    got = []
    roslibpy.Topic(client, "/bridge_test/numbers", "std_msgs/Int32").subscribe(lambda m: got.append(m["data"]))
    stop = threading.Event()

    def publish():
        n = 0
        while not stop.is_set():
            pub.publish(Int32(n))
            n += 1
            stop.wait(0.05)

    thread = threading.Thread(target=publish, daemon=True)
    thread.start()
    try:
        wait_for(lambda: len(got) >= 5, 20, what="five numbers")
    finally:
        stop.set()
        thread.join()
        pub.unregister()
    assert got == sorted(got)


def test_first_message_after_advertise_reaches_subscribers(client, node):
    """roslibjs/roslibpy advertise and publish at once, before subscribers have connected to the bridge's new
    publisher: the message must still arrive (a page's first Publish must move the turtle)."""
    from std_msgs.msg import String

    received = []
    sub = node.Subscriber("/bridge_test/first_message", String, lambda m: received.append(m.data))
    try:
        roslibpy.Topic(client, "/bridge_test/first_message", "std_msgs/String").publish(
            roslibpy.Message({"data": "first"})
        )
        wait_for(lambda: received, 10, what="the first message")
        assert received == ["first"]
    finally:
        sub.unregister()
