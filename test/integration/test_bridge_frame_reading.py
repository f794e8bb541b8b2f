"""How the bridge reads a client's websocket frames, whatever pieces they reach it in: many frames in one
packet, frames cut anywhere (in the header, the mask, the payload), a payload larger than one read, a
fragmented message with a ping between its fragments, frames sent with the handshake. What a client sees:
every message arrives whole, in order, and the ping is answered with its own payload. And what breaks the
protocol ends that connection as RFC 6455 says; a client over its frame budget is slowed down, not cut off."""

import json
import random
import struct
import time

import pytest

from bridge_client import RawWebSocket
from fixtures import bridge_fixture
from harness import wait_for, wait_publisher_connected

TOPIC = "/frame_reading/text"
BIG = 300_000  # characters: several of the bridge's reads (64 KB each)

port = bridge_fixture("frame_reading_bridge")


def publish(text, topic=TOPIC):
    return json.dumps({"op": "publish", "topic": topic, "msg": {"data": text}}).encode()


def advertise(topic):
    return RawWebSocket.frame(json.dumps({"op": "advertise", "topic": topic, "type": "std_msgs/String"}).encode())


ADVERTISE = advertise(TOPIC)


def client_bytes():
    """A small publish; a big one; a publish in three fragments with a ping after the first; a last small
    publish. Returns the bytes and the texts the topic should carry."""
    big = "".join(random.choice("abcdefghij") for _ in range(BIG))
    split = publish("in fragments")
    parts = [split[:10], split[10:25], split[25:]]
    stream = b"".join(
        [
            RawWebSocket.frame(publish("first")),
            RawWebSocket.frame(publish(big)),
            RawWebSocket.frame(parts[0], fin=False),
            RawWebSocket.frame(b"are you there", opcode=0x9),
            RawWebSocket.frame(parts[1], opcode=0x0, fin=False),
            RawWebSocket.frame(parts[2], opcode=0x0),
            RawWebSocket.frame(publish("last")),
        ]
    )
    return stream, ["first", big, "in fragments", "last"]


def pieces(data, sizes):
    """data cut into pieces of the given sizes in turn (the last piece takes the rest)."""
    at, index = 0, 0
    while at < len(data):
        size = sizes[index % len(sizes)]
        yield data[at : at + size]
        at, index = at + size, index + 1


@pytest.mark.parametrize(
    "sizes",
    [None, [1], [3, 7, 1, 2], [5000, 70_000, 13]],
    ids=["one-write", "byte-by-byte-start", "tiny-pieces", "odd-pieces"],
)
def test_frames_are_read_whole_whatever_pieces_they_come_in(ros, port, node, sizes):
    from std_msgs.msg import String

    got = []
    sub = node.Subscriber(TOPIC, String, lambda m: got.append(m.data))
    client = RawWebSocket(port)
    try:
        client.sock.sendall(ADVERTISE)
        wait_publisher_connected(ros, "/frame_reading_bridge", TOPIC, node.get_name())
        stream, expected = client_bytes()
        if sizes is None:
            client.sock.sendall(stream)
        else:
            for index, piece in enumerate(pieces(stream, sizes)):
                client.sock.sendall(piece)
                if index < 200:  # (a pause now and then: the bridge gets the first pieces one read each)
                    time.sleep(0.001)
        assert client.recv_frame() == (0xA, b"are you there")  # the pong
        wait_for(lambda: len(got) >= len(expected), 20, what="every message on the topic")
        assert got == expected
    finally:
        client.close()
        sub.unregister()


def test_frames_sent_with_the_handshake_are_read(port, node):
    from std_msgs.msg import String

    got = []
    sub = node.Subscriber(TOPIC, String, lambda m: got.append(m.data))
    client = RawWebSocket(port, early=ADVERTISE + RawWebSocket.frame(b"are you there", opcode=0x9))
    try:
        assert client.recv_frame() == (0xA, b"are you there")

        def delivered():  # (again until the link is up: what is published before is not delivered)
            client.sock.sendall(RawWebSocket.frame(publish("after the handshake")))
            time.sleep(0.1)
            return got

        wait_for(delivered, 20, what="the message")
        assert set(got) == {"after the handshake"}
    finally:
        client.close()
        sub.unregister()


def test_a_close_frame_is_answered_with_its_code_and_the_connection_closed(port):
    client = RawWebSocket(port)
    try:
        client.sock.sendall(RawWebSocket.frame(struct.pack("!H", 1001) + b"bye", opcode=0x8))
        assert client.recv_frame() == (0x8, struct.pack("!H", 1001))
        assert client.closed_by_server()
    finally:
        client.close()


@pytest.mark.parametrize(
    "frame",
    [
        RawWebSocket.frame(b"\xff\xfe not UTF-8"),
        bytes([0x80 | 0x40 | 0x1]) + RawWebSocket.frame(b"{}")[1:],  # a reserved bit no extension was agreed for
        RawWebSocket.frame(b"x" * 200, opcode=0x9),  # a control frame longer than 125 bytes
        RawWebSocket.frame(b"ping", opcode=0x9, fin=False),  # a fragmented control frame
        RawWebSocket.frame(b"nothing to continue", opcode=0x0),
        # after a turn's worth of frames (budget.FRAMES_PER_TURN) the rest is taken a moment later, from a timer
        b"".join(RawWebSocket.frame(b"%d" % i, opcode=0x9) for i in range(40))
        + RawWebSocket.frame(struct.pack("!H", 1000) + b"\xff reason", opcode=0x8),
    ],
    ids=["bad-utf8", "reserved-bit", "long-ping", "fragmented-ping", "stray-continuation", "bad-close-after-a-turn"],
)
def test_a_broken_frame_ends_that_connection_only(port, frame):
    other = RawWebSocket(port)
    client = RawWebSocket(port)
    try:
        client.sock.sendall(frame)
        assert client.closed_by_server()
        other.sock.sendall(RawWebSocket.frame(b"still here", opcode=0x9))
        assert other.recv_frame() == (0xA, b"still here")
    finally:
        client.close()
        other.close()


def test_a_frame_over_the_websocket_limit_is_refused_with_1009_before_its_payload(port):
    client = RawWebSocket(port)
    try:  # the default max_message_size is 8 MB: the bridge takes frames up to 4x that
        client.sock.sendall(RawWebSocket.header(40_000_000) + bytes(4) + b"only the start")
        opcode, payload = client.recv_frame()
        assert (opcode, payload[:2]) == (0x8, struct.pack("!H", 1009))
        assert client.closed_by_server()
    finally:
        client.close()


slow_port = bridge_fixture("frame_budget_bridge", max_frames_per_second=100)


def test_a_client_over_its_frame_budget_is_slowed_and_loses_nothing(ros, slow_port, node):
    from std_msgs.msg import String

    got, topic = [], "/frame_reading/budget"
    sub = node.Subscriber(topic, String, lambda m: got.append(m.data))
    client, other = RawWebSocket(slow_port), RawWebSocket(slow_port)
    try:
        client.sock.sendall(advertise(topic))
        # (seen from the bridge's side: what it publishes before that waits only as many as its queue_size, 100;
        # rospy's subscriber counts its connection before it has even connected)
        wait_publisher_connected(ros, "/frame_budget_bridge", topic, node.get_name())
        expected = [str(i) for i in range(300)]
        started = time.monotonic()
        client.sock.sendall(b"".join(RawWebSocket.frame(publish(text, topic)) for text in expected))
        other.sock.sendall(RawWebSocket.frame(b"meanwhile", opcode=0x9))
        assert other.recv_frame() == (0xA, b"meanwhile")
        answered = time.monotonic() - started
        wait_for(
            lambda: len(got) >= len(expected),
            20,
            what=lambda: (
                f"every message on the topic: {len(got)} came, missing {sorted(set(expected) - set(got), key=int)[:20]}"
            ),
        )
        took = time.monotonic() - started
        assert got == expected
        assert took > 1.5 and answered < 0.5, (took, answered)  # 100 at once, then 100 a second
    finally:
        client.close()
        other.close()
        sub.unregister()
