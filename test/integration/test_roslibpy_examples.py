"""What roslibpy's own ROS 1 example tests (its tests/ros1 and its connection and rosapi tests, which expect a
rosbridge at 127.0.0.1:9090) check, run against our bridge with roslibpy from .build/venv. Its wheel ships no
tests, so they are written again here, one for each. Differences: the bridge listens on a free port, and
rospy_tutorials/AddTwoInts (not packaged by Debian) is replaced by std_srvs/SetBool carrying the sum as text."""

import threading
import time

import pytest
import roslibpy

from fixtures import bridge_fixture

bridge = bridge_fixture("roslibpy_examples_bridge")


@pytest.fixture
def client(bridge):
    ros = roslibpy.Ros("127.0.0.1", bridge)
    ros.run(timeout=20)
    yield ros
    ros.close()


def test_topic_pubsub_on_one_connection(client):
    """tests/ros1/test_topic.py test_topic_pubsub: one client publishes /chatter and hears itself 3 times."""
    received = []
    three = threading.Event()
    listener = roslibpy.Topic(client, "/chatter", "std_msgs/String")
    publisher = roslibpy.Topic(client, "/chatter", "std_msgs/String")

    def receive(message):
        received.append(message["data"])
        if len(received) == 3:
            listener.unsubscribe()
            three.set()

    listener.subscribe(receive)
    deadline = time.monotonic() + 20
    while not three.is_set() and time.monotonic() < deadline:
        publisher.publish(roslibpy.Message({"data": "hello world"}))
        time.sleep(0.1)
    publisher.unadvertise()
    assert three.is_set() and received[:3] == ["hello world"] * 3


def test_topic_with_header(client):
    """tests/ros1/test_topic.py test_topic_with_header: a PointStamped with roslibpy's Header and Time.now()."""
    got = []
    arrived = threading.Event()
    listener = roslibpy.Topic(client, "/points", "geometry_msgs/PointStamped")
    publisher = roslibpy.Topic(client, "/points", "geometry_msgs/PointStamped")
    listener.subscribe(lambda message: (got.append(message), arrived.set()))
    for seq in range(50):
        header = roslibpy.Header(seq=seq, stamp=roslibpy.Time.now(), frame_id="base")
        publisher.publish(roslibpy.Message({"header": header, "point": {"x": 0.0, "y": 1.0, "z": 2.0}}))
        if arrived.wait(0.1):
            break
    listener.unsubscribe()
    publisher.unadvertise()
    assert got, "no PointStamped came back"
    assert got[0]["header"]["frame_id"] == "base" and got[0]["point"] == {"x": 0.0, "y": 1.0, "z": 2.0}


def test_a_service_advertised_and_called_by_one_client_whose_handler_returns_false(client):
    """tests/ros1/test_service.py test_add_two_ints_service: the handler fills the response, returns False."""

    def add_two_ints(request, response):
        response["success"] = True
        response["message"] = str(2 + 40)
        return False

    service = roslibpy.Service(client, "/test_sum_service", "std_srvs/SetBool")
    service.advertise(add_two_ints)
    time.sleep(1)
    result = roslibpy.Service(client, "/test_sum_service", "std_srvs/SetBool").call(
        roslibpy.ServiceRequest({"data": True}), timeout=20
    )
    assert result["message"] == "42"
    service.unadvertise()


def test_an_empty_service(client):
    """tests/ros1/test_service.py test_empty_service."""
    service = roslibpy.Service(client, "/test_empty_service", "std_srvs/Empty")
    service.advertise(lambda request, response: True)
    time.sleep(1)
    assert (
        roslibpy.Service(client, "/test_empty_service", "std_srvs/Empty").call(roslibpy.ServiceRequest(), timeout=20)
        == {}
    )
    service.unadvertise()


def test_param_manipulation_with_a_relative_name(client):
    """tests/ros1/test_param.py test_param_manipulation: "test_param" (relative) absent, set, read, deleted."""
    param = roslibpy.Param(client, "test_param")
    assert param.get(timeout=20) is None
    param.set("test_value", timeout=20)
    assert param.get(timeout=20) == "test_value"
    param.delete(timeout=20)
    assert param.get(timeout=20) is None


def test_rosapi_topics_with_a_callback_and_blocking(client):
    """tests/test_rosapi.py: get_topics lists /rosout, by callback and blocking."""
    listed = threading.Event()
    answer = {}
    client.get_topics(lambda result: (answer.update(result), listed.set()))
    assert listed.wait(20) and "/rosout" in answer["topics"]
    assert "/rosout" in client.get_topics()


def test_connections_by_host_and_port_and_by_url(bridge):
    """tests/test_ros.py test_connection, test_url_connection."""
    for ros in (roslibpy.Ros("127.0.0.1", bridge), roslibpy.Ros(f"ws://127.0.0.1:{bridge}")):
        ros.run(timeout=20)
        assert ros.is_connected
        ros.close()


def test_closing_runs_before_close_and_does_not_reconnect(bridge):
    """tests/test_ros.py test_closing_event, test_reconnect_does_not_trigger_on_client_close."""
    ros = roslibpy.Ros(f"ws://127.0.0.1:{bridge}")
    ros.run(timeout=20)
    seen = {}
    closed = threading.Event()
    ros.on("closing", lambda: seen.setdefault("connected while closing", ros.is_connected))
    ros.on("close", lambda message: closed.set())
    ros.close()
    assert closed.wait(5)
    assert seen == {"connected while closing": True}
    assert not ros.is_connected and not ros.is_connecting
