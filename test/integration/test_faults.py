"""The bridge when things go wrong around it: a client that stops reading during a flood, a client that dies
in the middle of a frame, the bridge itself killed and restarted under a reconnecting roslibpy client,
turtlesim_node killed and restarted while a client drives it, and roscore restarted. Loopback only."""

import os
import signal
import threading
import time

import pytest
import roslibpy

from bridge_client import RawWebSocket, WsClient, ping
from fixtures import bridge_fixture
from harness import ProcStat, RosMaster, node_pid, start_bridge, wait_for

pytestmark = pytest.mark.slow  # (deselect with -m 'not slow' for a quick run)


@pytest.fixture(autouse=True, scope="module")
def quick_reconnects():
    """roslibpy retries after 1 s, then backs off exponentially up to an hour: cap it for restarts."""
    factory = roslibpy.comm.RosBridgeClientFactory
    before = factory.maxDelay
    factory.set_max_delay(2.0)
    yield
    factory.set_max_delay(before)


def bridge_topics(ros, node_name):
    """The topics the bridge node is registered on with the master (as publisher or subscriber)."""
    pubs, subs, _ = ros.master().getSystemState()
    return {topic for topic, nodes in [*pubs, *subs] if node_name in nodes}


def publish_in_thread(publisher, make_msg, rate, count=None, stop=None):
    """Publishes make_msg(i) at `rate` Hz from a thread, `count` times or until `stop` is set."""

    def run():
        period, start, i = 1.0 / rate, time.monotonic(), 0
        while (count is None or i < count) and not (stop and stop.is_set()):
            publisher.publish(make_msg(i))
            i += 1
            time.sleep(max(0.0, start + i * period - time.monotonic()))

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


stuck_bridge = bridge_fixture("bridge_stuck", scope="function", yields="bridge")


def test_a_client_that_stops_reading_does_not_grow_the_bridge_or_starve_others(ros, node, stuck_bridge):
    from std_msgs.msg import String

    proc, port = stuck_bridge.proc, stuck_bridge.port
    pid = node_pid(ros, "/bridge_stuck")
    pub = node.Publisher("/faults/flood", String, queue_size=1000)
    stuck = RawWebSocket(port, recv_buffer=4096)
    stuck.send_text('{"op":"subscribe","topic":"/faults/flood","type":"std_msgs/String"}')
    got = []
    reader = roslibpy.Ros(host="127.0.0.1", port=port)
    reader.run(timeout=20)
    topic = roslibpy.Topic(reader, "/faults/flood", "std_msgs/String")
    topic.subscribe(lambda m: got.append(int(m["data"].split(":", 1)[0])))
    wait_for(lambda: pub.get_num_connections() >= 1, 20, what="the bridge subscribing to the flood")

    count, filler = 10_000, "x" * 10_000  # 10 s at 1 kHz of 10 kB messages: 100 MB if nothing were dropped
    flood = publish_in_thread(pub, lambda i: String(f"{i}:{filler}"), rate=1000, count=count)
    time.sleep(3)
    early = ProcStat(pid).rss_mb()
    flood.join(60)
    wait_for(lambda: got and got[-1] == count - 1, 60, what="the reading client to get the last message")
    grown = ProcStat(pid).rss_mb() - early
    topic.unsubscribe()
    reader.close()
    stuck.close()
    pub.unregister()

    assert grown < 40, f"bridge RSS grew {grown:.0f} MB while a client did not read"
    seconds = {seq // 1000 for seq in got}  # the flood's seconds the reading client got messages from
    assert len(seconds) >= count // 1000 // 2, f"the reading client only got messages of seconds {seconds}"
    assert proc.alive()


@pytest.mark.parametrize("reset", [False, True], ids=["fin", "rst"])
def test_a_client_dying_mid_frame_is_cleaned_up(ros, reset):
    node_name = f"bridge_midframe_{'rst' if reset else 'fin'}"
    proc, port = start_bridge(ros, node_name=node_name)
    try:
        dying = RawWebSocket(port)
        dying.send_text('{"op":"subscribe","topic":"/faults/midframe","type":"std_msgs/String"}')
        wait_for(
            lambda: "/faults/midframe" in bridge_topics(ros, f"/{node_name}"),
            20,
            what="the bridge subscribing for the client",
        )
        dying.send_text(
            '{"op":"publish","topic":"/faults/midframe","msg":{"data":"' + "y" * 50_000 + '"}}', cut_after=1000
        )
        dying.close(reset=reset)

        wait_for(
            lambda: "/faults/midframe" not in bridge_topics(ros, f"/{node_name}"),
            20,
            what="the bridge dropping the dead client's subscription",
        )
        client = WsClient(f"ws://127.0.0.1:{port}/")
        assert ping(client)
        client.close()
        assert proc.alive()
    finally:
        proc.stop()


restarted_bridge = bridge_fixture("bridge_restart", scope="function", yields="bridge")


def test_bridge_killed_and_restarted_under_a_reconnecting_client(ros, node, restarted_bridge):
    from std_msgs.msg import Int32

    port = restarted_bridge.port
    ticks = node.Publisher("/faults/ticks", Int32, queue_size=10)
    got_cmds = []
    sub = node.Subscriber("/faults/cmds", Int32, lambda m: got_cmds.append(m.data))
    stop = threading.Event()
    publish_in_thread(ticks, Int32, rate=10, stop=stop)
    client = roslibpy.Ros(host="127.0.0.1", port=port)
    try:
        client.run(timeout=20)
        got = []
        roslibpy.Topic(client, "/faults/ticks", "std_msgs/Int32").subscribe(lambda m: got.append(m["data"]))
        cmds = roslibpy.Topic(client, "/faults/cmds", "std_msgs/Int32")
        wait_for(lambda: got, 20, what="ticks before the restart")
        wait_for(
            lambda: cmds.publish(roslibpy.Message({"data": 1})) or 1 in got_cmds,
            20,
            interval=0.2,
            what="a command before the restart",
        )

        os.kill(node_pid(ros, "/bridge_restart"), signal.SIGKILL)  # (roslaunch runs it in a session of its own)
        restarted_bridge.proc.stop()
        wait_for(lambda: not client.is_connected, 20, what="the client to notice")
        before = len(got)
        restarted_bridge.start()  # (on the same port)

        wait_for(lambda: len(got) > before + 3, 60, what="ticks again after the restart")
        wait_for(
            lambda: cmds.publish(roslibpy.Message({"data": 2})) or 2 in got_cmds,
            60,
            interval=0.2,
            what="commands reaching ROS again after the restart",
        )
    finally:
        stop.set()
        client.close()
        ticks.unregister()
        sub.unregister()


turtle_restart_bridge = bridge_fixture("bridge_turtle_restart", scope="function")


def test_turtlesim_killed_and_restarted_while_a_client_drives(ros, node, turtle_restart_bridge):
    port = turtle_restart_bridge
    turtle = ros.spawn(["rosrun", "turtlesim", "turtlesim_node", "__name:=turtlesim_faults"], "turtlesim_faults")
    client = roslibpy.Ros(host="127.0.0.1", port=port)
    try:
        client.run(timeout=20)
        poses = []
        roslibpy.Topic(client, "/turtle1/pose", "turtlesim/Pose").subscribe(poses.append)
        cmd = roslibpy.Topic(client, "/turtle1/cmd_vel", "geometry_msgs/Twist")
        forward = roslibpy.Message({"linear": {"x": 1.0, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}})

        def driving():
            cmd.publish(forward)
            return poses and poses[-1]["linear_velocity"] == pytest.approx(1.0)

        wait_for(driving, 30, interval=0.1, what="the turtle driving")
        os.kill(node_pid(ros, "/turtlesim_faults"), signal.SIGKILL)
        turtle.stop()
        turtle = ros.spawn(["rosrun", "turtlesim", "turtlesim_node", "__name:=turtlesim_faults"], "turtlesim_faults")
        turtle.wait_output("Spawning turtle [turtle1]", timeout=30)
        wait_for(
            lambda: poses[-1]["x"] == pytest.approx(5.544445, abs=1e-3),
            30,
            what="poses from the new turtlesim (back at the centre)",
        )
        wait_for(driving, 30, interval=0.1, what="the new turtle driving")
    finally:
        client.close()
        turtle.stop()


def test_roscore_restarted_under_the_bridge(tmp_path):
    """A master of its own: restarting the session's master would disturb the other tests."""
    master = RosMaster(tmp_path).start()
    try:
        proc, port = start_bridge(master, node_name="bridge_master_restart")
        client = WsClient(f"ws://127.0.0.1:{port}/")
        master.core.stop()
        master.procs.remove(master.core)
        # the master is gone: a ROS request is answered with an error, and the connection goes on working
        reply = client.request({"op": "call_service", "service": "/rosapi/topics", "id": "down"}, timeout=30)
        assert reply["op"] in ("service_response", "status") and reply.get("result") is not True, reply
        assert ping(client)

        master.start()  # same port
        talker = master.spawn(
            ["rostopic", "pub", "-r", "10", "/faults/after", "std_msgs/String", "data: back"], "talker"
        )
        client.send({"op": "subscribe", "topic": "/faults/after", "type": "std_msgs/String"})
        msg = client.recv_op("publish", timeout=30, topic="/faults/after")
        assert msg["msg"] == {"data": "back"}
        reply = client.request({"op": "call_service", "service": "/rosapi/topics", "id": "up"}, timeout=30)
        assert reply["result"] is True and "/faults/after" in reply["values"]["topics"], reply
        client.close()
        talker.stop()
        assert proc.alive()
    finally:
        master.stop()


def test_after_a_roscore_restart_the_connected_client_drives_again(tmp_path):
    """A laptop's roscore restarts (and turtlesim with it) under a connected page: the bridge registers its
    publisher, subscriber and /client_count with the new master, so the same connection's cmd_vel moves the new
    turtle within 5 s and its pose subscription delivers again, to it and to new clients."""
    master = RosMaster(tmp_path).start()
    try:
        proc, port = start_bridge(master, node_name="bridge_recovery")
        turtle = master.spawn(["rosrun", "turtlesim", "turtlesim_node"], "turtle_before")
        turtle.wait_output("Spawning turtle [turtle1]", timeout=30)
        client = WsClient(f"ws://127.0.0.1:{port}/")
        client.send({"op": "subscribe", "topic": "/turtle1/pose", "type": "turtlesim/Pose"})
        client.send({"op": "advertise", "topic": "/turtle1/cmd_vel", "type": "geometry_msgs/Twist"})
        client.recv_op("publish", timeout=30, topic="/turtle1/pose")

        turtle.stop()
        master.core.stop()
        master.procs.remove(master.core)
        master.start()  # same port, a new master that knows nobody
        turtle = master.spawn(["rosrun", "turtlesim", "turtlesim_node"], "turtle_after")
        turtle.wait_output("Spawning turtle [turtle1]", timeout=30)
        started = time.monotonic()
        forward = {
            "op": "publish",
            "topic": "/turtle1/cmd_vel",
            "msg": {"linear": {"x": 1.0, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}},
        }

        def moving():
            client.send(forward)
            try:
                client.recv_until(
                    lambda f: f.get("topic") == "/turtle1/pose" and f["msg"]["linear_velocity"] == pytest.approx(1.0),
                    timeout=0.1,
                    limit=10**6,
                )
                return True
            except TimeoutError:
                return False

        wait_for(moving, 30, interval=0.01, what="the same connection driving the new turtle")
        assert time.monotonic() - started < 5.0

        newcomer = WsClient(f"ws://127.0.0.1:{port}/")
        newcomer.send({"op": "subscribe", "topic": "/turtle1/pose"})
        newcomer.recv_op("publish", timeout=10, topic="/turtle1/pose")
        newcomer.send({"op": "subscribe", "topic": "/client_count"})
        assert newcomer.recv_op("publish", timeout=10, topic="/client_count")["msg"]["data"] == 2
        for each in (client, newcomer):
            each.close()
        turtle.stop()
        assert proc.alive()
    finally:
        master.stop()


def test_a_master_that_stops_answering_does_not_stop_the_bridge_serving_its_clients(tmp_path):
    """The master is stopped (SIGSTOP: it accepts connections and never answers) while a client is connected:
    another client connects, and both are served. Before, the bridge's log line of that connection asked the
    master (rospy's rosout handler, for /rosout_disable_topics_generation, on every line) on the loop, and every
    client waited until the master answered."""
    master = RosMaster(tmp_path).start()
    try:
        _, port = start_bridge(master, node_name="bridge_master_stopped")
        first = WsClient(f"ws://127.0.0.1:{port}/")
        with master.unresponsive():
            second = WsClient(f"ws://127.0.0.1:{port}/", timeout=5)
            for client in (first, second):
                reply = client.request({"op": "set_level", "level": "bogus", "id": "ping"}, timeout=2)
                assert reply["op"] == "status" and "bogus" in reply["msg"], reply
            second.close()
        first.close()
    finally:
        master.stop()


def test_a_sigint_while_the_master_is_slow_stops_the_bridge(tmp_path):
    """SIGINT (Ctrl-C, roslaunch's stop) comes while the master is slow to answer and a client connects: the
    bridge exits once the master answers. Before, rospy's handler ran inside the loop's call to the master and its
    shutdown waited for the lock that call held, for ever (only SIGKILL ended it)."""
    master = RosMaster(tmp_path).start()
    try:
        proc, port = start_bridge(master, node_name="bridge_stopped_on_sigint")
        with master.unresponsive():
            client = RawWebSocket(port)
            time.sleep(0.5)  # (its log line is being written)
            os.kill(proc.popen.pid, signal.SIGINT)
            time.sleep(0.5)
        assert proc.popen.wait(10) == 0
        client.close()
    finally:
        master.stop()
