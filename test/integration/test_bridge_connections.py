"""Clients coming and going: abrupt disconnects, page reloads, 200 clients at once, a client too slow to read
(test_freshness.py: what a slow link keeps)."""

import asyncio
import json
import time

import pytest
from tornado.websocket import websocket_connect

from bridge_client import WsClient, ping
from fixtures import bridge_fixture
from harness import wait_for

UNREGISTER_TIMEOUT = 3.0

bridge = bridge_fixture("clients_bridge", unregister_timeout=UNREGISTER_TIMEOUT, max_queue=20)


def connect(port):
    return WsClient(f"ws://127.0.0.1:{port}/")


def client_count(node):
    from std_msgs.msg import Int32

    return node.wait_for_message("/client_count", Int32, timeout=20).data


def publishers_of(ros, topic):
    for name, nodes in ros.master().getSystemState()[0]:
        if name == topic:
            return nodes
    return []


def subscribers_of(ros, topic):
    for name, nodes in ros.master().getSystemState()[1]:
        if name == topic:
            return nodes
    return []


def test_abrupt_disconnect_releases_everything(bridge, ros, node):
    before = client_count(node)
    ws = connect(bridge)
    ws.send({"op": "advertise", "topic": "/clients_test/abrupt_pub", "type": "std_msgs/String"})
    ws.send({"op": "subscribe", "topic": "/clients_test/abrupt_sub", "type": "std_msgs/String"})
    ws.send({"op": "advertise_service", "service": "/clients_test/abrupt_srv", "type": "std_srvs/Trigger"})
    assert ping(ws)
    wait_for(lambda: client_count(node) == before + 1, 20, what="count + 1")
    assert "/clients_bridge" in publishers_of(ros, "/clients_test/abrupt_pub")
    assert "/clients_bridge" in subscribers_of(ros, "/clients_test/abrupt_sub")
    ws.abort()
    wait_for(lambda: client_count(node) == before, 20, what="count back")
    wait_for(lambda: not subscribers_of(ros, "/clients_test/abrupt_sub"), 20, what="subscriber released")
    wait_for(
        lambda: "/clients_test/abrupt_srv" not in ros.run(["rosservice", "list"]).stdout, 20, what="service released"
    )
    # the publisher lingers for unregister_timeout, then goes
    wait_for(
        lambda: not publishers_of(ros, "/clients_test/abrupt_pub"), UNREGISTER_TIMEOUT + 20, what="publisher released"
    )


def test_page_reload_keeps_the_topic_working(bridge, ros, node):
    from std_msgs.msg import String

    got = []
    sub = node.Subscriber("/clients_test/reload", String, lambda m: got.append(m.data))

    def publish_until_received(ws, text):
        def received():
            ws.send({"op": "publish", "topic": "/clients_test/reload", "msg": {"data": text}})
            return text in got

        wait_for(received, 20, interval=0.2, what=f"{text!r} in rospy")

    first = connect(bridge)
    first.send({"op": "advertise", "topic": "/clients_test/reload", "type": "std_msgs/String"})
    publish_until_received(first, "before reload")
    first.close()
    second = connect(bridge)  # the reloaded page, within unregister_timeout
    second.send({"op": "advertise", "topic": "/clients_test/reload", "type": "std_msgs/String"})
    second.send({"op": "publish", "topic": "/clients_test/reload", "msg": {"data": "after reload"}})
    wait_for(lambda: "after reload" in got, 20, what="the first message after the reload")  # no reconnect needed
    second.abort()
    time.sleep(UNREGISTER_TIMEOUT + 1)  # the publisher is gone now; a later client gets a new one
    third = connect(bridge)
    publish_until_received(third, "much later")
    third.close()
    sub.unregister()


def test_200_clients_all_receive_a_message(bridge, node):
    from std_msgs.msg import String

    count, topic = 200, "/clients_test/broadcast"
    pub = node.Publisher(topic, String, queue_size=10, latch=True)

    async def run():
        url = f"ws://127.0.0.1:{bridge}/"
        conns = await asyncio.gather(*(websocket_connect(url) for _ in range(count)))
        for conn in conns:
            conn.write_message(json.dumps({"op": "subscribe", "topic": topic, "type": "std_msgs/String"}))
        await asyncio.sleep(0.5)
        pub.publish(String("to everyone"))

        async def first_publish(conn):
            while True:
                frame = json.loads(await conn.read_message())
                if frame["op"] == "publish":
                    return frame["msg"]["data"]

        received = await asyncio.wait_for(asyncio.gather(*(first_publish(c) for c in conns)), 60)
        for conn in conns:
            conn.close()
        return received

    received = asyncio.new_event_loop().run_until_complete(run())
    assert received == ["to everyone"] * count
    pub.unregister()


def test_slow_client_skips_to_the_newest_and_is_told(bridge, node):
    from std_msgs.msg import String

    topic = "/clients_test/firehose"
    pub = node.Publisher(topic, String, queue_size=1000)
    slow = connect(bridge)
    slow.send({"op": "set_level", "level": "warning"})
    slow.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
    wait_for(lambda: pub.get_num_connections(), 20, what="the bridge to subscribe")
    payload = "x" * 200_000
    for n in range(300):  # 60 MB: far more than the socket buffers hold while the client does not read
        pub.publish(String(f"{n}:{payload}"))
    warning = slow.recv_until(lambda f: f.get("op") == "status", timeout=60, limit=400)
    assert warning["level"] == "warning" and warning["msg"].startswith("skipped ") and topic in warning["msg"]
    numbers = []
    while True:
        frame = slow.recv_until(lambda f: f.get("op") == "publish", timeout=30, limit=400)
        numbers.append(int(frame["msg"]["data"].split(":")[0]))
        if numbers[-1] == 299:
            break
    assert len(numbers) < 300 and numbers == sorted(numbers)  # the newest arrive, in order
    assert ping(slow)
    slow.close()
    pub.unregister()


def test_a_latched_message_lives_with_its_publisher_and_each_publisher_gives_its_own(bridge, node, ros):
    """As ROS does: a later subscriber gets the latched message of every publisher still there (two static TF
    broadcasters each latch their own /tf_static), and none of one that left ("Publishers: None")."""
    from std_msgs.msg import String

    topic = "/clients_test/latched_two"
    here = node.Publisher(topic, String, queue_size=1, latch=True)
    here.publish(String("from the test"))
    there = ros.spawn(["rostopic", "pub", "-l", topic, "std_msgs/String", "data: 'from rostopic'"], "latched_pub")
    wait_for(lambda: len(publishers_of(ros, topic)) == 2, 20, what="two publishers")
    first, second = connect(bridge), connect(bridge)
    try:
        first.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
        texts = {first.recv_op("publish")["msg"]["data"] for _ in range(2)}
        assert texts == {"from the test", "from rostopic"}
        second.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})  # the bridge keeps both
        assert {second.recv_op("publish")["msg"]["data"] for _ in range(2)} == texts
        there.stop()
        wait_for(lambda: len(publishers_of(ros, topic)) == 1, 20, what="rostopic pub to leave")
        time.sleep(1.0)  # (its connection to the bridge has closed by then)
        here.unregister()
        wait_for(lambda: not publishers_of(ros, topic), 20, what="the test's publisher to leave")
        time.sleep(1.0)
        third = connect(bridge)
        try:
            third.send({"op": "subscribe", "topic": topic, "type": "std_msgs/String"})
            with pytest.raises(TimeoutError):
                got = third.recv_op("publish", timeout=2.0)
                print("a message of a publisher gone:", got)
        finally:
            third.close()
    finally:
        first.close()
        second.close()
        here.unregister()


def test_a_later_subscriber_gets_the_latched_message(bridge, node):
    from std_msgs.msg import String

    pub = node.Publisher("/clients_test/latched", String, queue_size=1, latch=True)
    pub.publish(String("latched once"))
    first, second = connect(bridge), connect(bridge)
    try:
        first.send({"op": "subscribe", "topic": "/clients_test/latched", "type": "std_msgs/String"})
        assert first.recv_op("publish")["msg"] == {"data": "latched once"}
        # the bridge is subscribed already, so rospy will not deliver it again: the bridge keeps it
        second.send({"op": "subscribe", "topic": "/clients_test/latched", "type": "std_msgs/String"})
        assert second.recv_op("publish")["msg"] == {"data": "latched once"}
    finally:
        first.close()
        second.close()
        pub.unregister()
