"""The dead-man stop: when a client that has been driving (publishing geometry_msgs/Twist or TwistStamped)
goes away - it closes, its connection drops, or it goes silent past deadman_timeout - the bridge publishes one
zero message on each such topic it drove, so a real robot does not go on with its last command."""

import json
import time

import pytest
from geometry_msgs.msg import Twist, TwistStamped

from bridge_client import RawWebSocket, WsClient
from fixtures import bridge_fixture
from harness import wait_for, wait_publisher_connected

TIMEOUT = 1.0  # the bridge's deadman_timeout in these tests

bridge = bridge_fixture("deadman_bridge", deadman_timeout=TIMEOUT)
off_bridge = bridge_fixture("deadman_off_bridge", scope="function", deadman_timeout=0)


class Recorder:
    """A rospy subscriber keeping (arrival time, message) of a topic."""

    def __init__(self, node, topic, cls):
        self.got = []
        self.sub = node.Subscriber(topic, cls, lambda msg: self.got.append((time.monotonic(), msg)))

    def zeros_after(self, moment):
        return [t for t, msg in self.got if t >= moment and _twist(msg) == [0.0] * 6]


def _twist(msg):
    twist = getattr(msg, "twist", msg)
    return [twist.linear.x, twist.linear.y, twist.linear.z, twist.angular.x, twist.angular.y, twist.angular.z]


def drive(ros, client_send, topic, type_name, recorder, bridge_node="/deadman_bridge"):
    """Advertises and publishes one moving command; returns once the recorder has it."""
    client_send({"op": "advertise", "topic": topic, "type": type_name})
    wait_publisher_connected(ros, bridge_node, topic, _me())
    moving = {"linear": {"x": 2.0}, "angular": {"z": 1.0}}
    client_send({"op": "publish", "topic": topic, "msg": moving if type_name.endswith("/Twist") else {"twist": moving}})
    wait_for(lambda: any(_twist(msg)[0] == 2.0 for _, msg in recorder.got), 10, what="the moving command")


def _me():
    import rospy

    return rospy.get_name()


@pytest.mark.parametrize("ending", ["close", "drop"])
def test_a_driver_that_leaves_stops_its_robot_at_once(bridge, ros, node, ending):
    topic = f"/deadman/{ending}/cmd_vel"
    recorder = Recorder(node, topic, Twist)
    ws = WsClient(f"ws://127.0.0.1:{bridge}/")
    drive(ros, ws.send, topic, "geometry_msgs/Twist", recorder)
    ended = time.monotonic()
    if ending == "close":
        ws.close()
    else:
        ws.abort()  # no close handshake: the TCP connection just ends
    wait_for(lambda: recorder.zeros_after(ended), 5, what="a zero Twist")
    assert recorder.zeros_after(ended)[0] - ended < 0.5
    time.sleep(0.5)
    assert len(recorder.zeros_after(ended)) == 1


def test_a_silent_driver_is_stopped_within_the_timeout_and_drives_again_when_heard(bridge, ros, node):
    topic = "/deadman/silent/cmd_vel"
    recorder = Recorder(node, topic, TwistStamped)
    client = RawWebSocket(bridge)  # answers no ping: a phone whose Wi-Fi dropped sends nothing at all
    try:
        send = lambda op: client.sock.sendall(RawWebSocket.frame(json.dumps(op).encode()))  # noqa: E731
        drive(ros, send, topic, "geometry_msgs/TwistStamped", recorder)
        silent_from = time.monotonic()
        wait_for(lambda: recorder.zeros_after(silent_from), 5, what="a zero TwistStamped")
        stopped_after = recorder.zeros_after(silent_from)[0] - silent_from
        assert TIMEOUT * 0.5 <= stopped_after <= TIMEOUT + 0.1, stopped_after  # (checked when its lease ends)
        zero = [msg for t, msg in recorder.got if t >= silent_from][0]
        assert zero.header.stamp.to_sec() > 0  # stamped like any message a client publishes
        time.sleep(TIMEOUT * 2)
        assert len(recorder.zeros_after(silent_from)) == 1  # once per silence
    finally:
        client.close()


def test_a_client_that_only_watches_or_publishes_other_types_stops_nothing(bridge, ros, node):
    from std_msgs.msg import String

    recorder = Recorder(node, "/deadman/chatter", String)
    ws = WsClient(f"ws://127.0.0.1:{bridge}/")
    ws.send({"op": "advertise", "topic": "/deadman/chatter", "type": "std_msgs/String"})
    ws.send({"op": "publish", "topic": "/deadman/chatter", "msg": {"data": "hi"}})
    wait_for(lambda: recorder.got, 10, what="the message")
    ws.close()
    time.sleep(TIMEOUT + 0.5)
    assert [msg.data for _, msg in recorder.got] == ["hi"]


def test_off_with_a_timeout_of_zero(ros, node, off_bridge):
    topic = "/deadman/off/cmd_vel"
    recorder = Recorder(node, topic, Twist)
    ws = WsClient(f"ws://127.0.0.1:{off_bridge}/")
    drive(ros, ws.send, topic, "geometry_msgs/Twist", recorder, "/deadman_off_bridge")
    ended = time.monotonic()
    ws.close()
    time.sleep(1.0)
    assert not recorder.zeros_after(ended)


idle_bridge = bridge_fixture("deadman_idle_bridge", scope="function", deadman_timeout=TIMEOUT)


def _loop_wakes(pid, seconds):
    """How many times the bridge's loop thread (its main thread) slept and woke in `seconds`: a count, not a
    time (what wakes an idle bridge costs the same on any machine)."""

    def switches():
        with open(f"/proc/{pid}/task/{pid}/status") as status:
            return next(int(line.split()[1]) for line in status if line.startswith("voluntary_ctxt_switches"))

    before = switches()
    time.sleep(seconds)
    return switches() - before


def test_the_leases_wake_the_loop_only_while_someone_drives(ros, node, idle_bridge):
    """A bridge left running for days with nobody driving is not woken to check leases (four times a second
    before). Once a driver has come and gone, it sleeps again."""
    from harness import node_pid

    pid = node_pid(ros, "/deadman_idle_bridge")
    time.sleep(1.0)  # (start-up settles)
    assert _loop_wakes(pid, 3.0) <= 2
    topic = "/deadman/idle/cmd_vel"
    recorder = Recorder(node, topic, Twist)
    ws = WsClient(f"ws://127.0.0.1:{idle_bridge}/")
    drive(ros, ws.send, topic, "geometry_msgs/Twist", recorder, "/deadman_idle_bridge")
    wait_for(lambda: recorder.zeros_after(0), TIMEOUT * 3, what="the dead-man stop of a silent driver")
    ws.close()
    time.sleep(TIMEOUT)  # (its unregister and last checks)
    assert _loop_wakes(pid, 3.0) <= 2
