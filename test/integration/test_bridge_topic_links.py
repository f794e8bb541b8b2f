"""The bridge's own TCPROS connections (ros_side/links.py) against nodes that misbehave the way networks and
nodes do: a publisher that drops the bridge's first connection before answering (rospy tries again; so must
the bridge), one that refuses it, a subscriber that stops reading."""

import socket
import struct
import threading
import time
import xmlrpc.client
from xmlrpc.server import SimpleXMLRPCServer

import pytest
from std_msgs.msg import String

from rosbridge.ros_side import tcpros
from rosbridge.ros_side.links import LINK_QUEUE_BYTES

from bridge_client import WsClient
from fixtures import bridge_fixture
from harness import ProcStat, node_pid, wait_for, wait_publisher_connected

bridge = bridge_fixture("links_bridge")


class FakePublisher:
    """A node that publishes one std_msgs/String on `topic` (registered with the master), whose TCPROS server
    first drops `drops` connections without answering, then answers with `reply` and sends the message."""

    def __init__(self, ros, topic, drops=0, refuse=False):
        self.topic, self.drops, self.refuse = topic, drops, refuse
        self.connections = 0
        self.tcp = socket.create_server(("127.0.0.1", 0))
        self.xmlrpc = SimpleXMLRPCServer(("127.0.0.1", 0), logRequests=False, allow_none=True)
        self.xmlrpc.register_function(self.request_topic, "requestTopic")
        self.uri = f"http://127.0.0.1:{self.xmlrpc.server_address[1]}/"
        self.name = f"/fake_publisher_{self.tcp.getsockname()[1]}"
        for target in (self.xmlrpc.serve_forever, self.serve_tcp):
            threading.Thread(target=target, daemon=True).start()
        self.master = xmlrpc.client.ServerProxy(ros.master().master_uri)
        self.master.registerPublisher(self.name, topic, "std_msgs/String", self.uri)

    def request_topic(self, caller_id, topic, protocols):
        return [1, "ready", ["TCPROS", "127.0.0.1", self.tcp.getsockname()[1]]]

    def serve_tcp(self):
        while True:
            try:
                conn, _ = self.tcp.accept()
            except OSError:
                return
            self.connections += 1
            with conn:
                (size,) = struct.unpack("<I", conn.recv(4))
                while size:
                    size -= len(conn.recv(size))
                if self.connections <= self.drops:
                    continue  # closed before answering
                if self.refuse:
                    conn.sendall(tcpros.encode_header({"error": "not today"}))
                    continue
                conn.sendall(
                    tcpros.encode_header(
                        tcpros.publisher_reply(
                            {"topic": self.topic, "md5sum": String._md5sum, "callerid": "/x"},
                            self.topic,
                            String,
                            False,
                            self.name,
                        )
                    )
                )
                conn.sendall(tcpros.frame(struct.pack("<I", 5) + b"hello"))
                conn.recv(1)  # until the bridge leaves

    def close(self):
        self.master.unregisterPublisher(self.name, self.topic, self.uri)
        self.xmlrpc.shutdown()
        self.tcp.close()


def test_a_connection_dropped_before_the_answer_is_tried_again(bridge, ros):
    publisher = FakePublisher(ros, "/links_test/flaky", drops=2)
    try:
        ws = WsClient(f"ws://127.0.0.1:{bridge}/")
        ws.send({"op": "subscribe", "topic": "/links_test/flaky", "type": "std_msgs/String"})
        got = ws.recv_until(lambda f: f.get("op") == "publish", timeout=15)
        assert got["msg"] == {"data": "hello"}
        assert publisher.connections == 3
        ws.close()
    finally:
        publisher.close()


def test_a_refusal_is_final_and_the_bridge_goes_on(bridge, ros):
    publisher = FakePublisher(ros, "/links_test/refusing", refuse=True)
    try:
        ws = WsClient(f"ws://127.0.0.1:{bridge}/")
        ws.send({"op": "subscribe", "topic": "/links_test/refusing", "type": "std_msgs/String"})
        with pytest.raises(TimeoutError):
            ws.recv_until(lambda f: f.get("op") == "publish", timeout=3)
        assert publisher.connections == 1
        ws.send({"op": "call_service", "service": "/rosapi/get_time", "id": "t"})
        assert ws.recv_until(lambda f: f.get("id") == "t", timeout=10)["result"] is True
        ws.close()
    finally:
        publisher.close()


def publishing_to_a_slow_and_a_stuck_subscriber(ros, node, bridge, topic, queue_size):
    """A client advertising `topic`, a rospy subscriber that reads (its arrivals: the numbers before ':'), and
    a raw TCPROS subscriber with a tiny receive buffer that has sent its header and reads nothing more.
    Returns (client, numbers read, the reading subscriber, the stuck socket, its frame reader)."""
    ws = WsClient(f"ws://127.0.0.1:{bridge}/")
    ws.send({"op": "advertise", "topic": topic, "type": "std_msgs/String", "queue_size": queue_size})
    got = []
    reader = node.Subscriber(topic, String, lambda m: got.append(int(m.data.split(":")[0])), queue_size=10)
    wait_publisher_connected(ros, "/links_bridge", topic, node.get_name())
    bridge_node = xmlrpc.client.ServerProxy(ros.master().lookupNode("/links_bridge"))
    _, _, (_, host, port) = bridge_node.requestTopic("/stuck_subscriber", topic, [["TCPROS"]])
    stuck = socket.socket()
    stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    stuck.connect((host, port))
    stuck.sendall(tcpros.encode_header(tcpros.subscriber_header(topic, String, "/stuck_subscriber")))
    frames = tcpros.FrameReader(max_size=tcpros.MAX_HEADER)
    while not frames.feed(stuck.recv(1), most=1):  # the bridge's answer, byte by byte: no message read yet
        pass
    return ws, got, reader, stuck, frames


def test_a_subscriber_that_stops_reading_holds_up_nobody_and_gets_whole_messages(bridge, ros, node):
    topic, count, filler = "/links_test/slow", 200, "x" * 100_000  # 20 MB: far more than socket buffers hold
    ws, got, reader, stuck, frames = publishing_to_a_slow_and_a_stuck_subscriber(ros, node, bridge, topic, 10)
    try:
        for i in range(count):
            ws.send({"op": "publish", "topic": topic, "msg": {"data": f"{i}:{filler}"}})
        wait_for(lambda: got and got[-1] == count - 1, 30, what="the reading subscriber to get the last message")
        assert got == sorted(set(got))  # in order (if it fell behind, its own queue of 10 dropped the oldest)

        stuck.settimeout(5)
        frames.max_size = tcpros.MAX_MESSAGE
        numbers = []
        while not numbers or numbers[-1] != count - 1:
            for message in frames.feed(stuck.recv(1 << 16)):
                (size,) = struct.unpack_from("<I", message)
                number, _, rest = bytes(message[4:]).decode().partition(":")
                assert size == len(message) - 4 and rest == filler, "a torn message"
                numbers.append(int(number))
        assert numbers == sorted(numbers) and len(numbers) < count, "the queue (10) held more than it may"
    finally:
        stuck.close()
        reader.unregister()
        ws.close()


def test_what_waits_for_a_stuck_subscriber_is_bounded_in_bytes_whatever_its_queue_size(bridge, ros, node):
    """A client may ask for any queue_size: the messages waiting for a subscriber that does not read stay within
    a byte bound (the newest kept), so big messages cannot pile up in the bridge."""
    topic, count, filler = "/links_test/stuck_big", 100, "x" * 3_000_000  # 300 MB in all
    ws, got, reader, stuck, _ = publishing_to_a_slow_and_a_stuck_subscriber(ros, node, bridge, topic, 2**62)
    bridge_memory = ProcStat(node_pid(ros, "/links_bridge"))
    try:
        time.sleep(1)
        before = bridge_memory.rss_mb()
        for i in range(count):
            ws.send({"op": "publish", "topic": topic, "msg": {"data": f"{i}:{filler}"}})
        wait_for(lambda: got and got[-1] == count - 1, 60, what="the reading subscriber to get the last message")
        grown = bridge_memory.rss_mb() - before
        bound = 2 * LINK_QUEUE_BYTES / 1e6 + 40  # waiting, in the stream's buffer, and the allocator's slack
        assert grown < bound, f"the bridge grew {grown:.0f} MB holding messages for a subscriber that does not read"
    finally:
        stuck.close()
        reader.unregister()
        ws.close()
