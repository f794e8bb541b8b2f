"""How the bridge reads a client's websocket frames, whatever pieces they reach it in: many frames in one
packet, frames cut anywhere (in the header, the mask, the payload), a payload larger than one read, a
fragmented message with a ping between its fragments. What a client sees: every message arrives whole, in
order, and the ping is answered with its own payload."""
import json
import random
import time

import pytest

from bridge_client import RawWebSocket
from harness import start_bridge, wait_for

TOPIC = "/frame_reading/text"
BIG = 300_000  # characters: several of the bridge's reads (64 KB each)


@pytest.fixture(scope="module")
def port(ros):
    proc, port = start_bridge(ros, node_name="frame_reading_bridge")
    yield port
    proc.stop()


def publish(text):
    return json.dumps({"op": "publish", "topic": TOPIC, "msg": {"data": text}}).encode()


ADVERTISE = RawWebSocket.frame(json.dumps({"op": "advertise", "topic": TOPIC, "type": "std_msgs/String"}).encode())


def client_bytes():
    """A small publish; a big one; a publish in three fragments with a ping after the first; a last small
    publish. Returns the bytes and the texts the topic should carry."""
    big = "".join(random.choice("abcdefghij") for _ in range(BIG))
    split = publish("in fragments")
    parts = [split[:10], split[10:25], split[25:]]
    stream = b"".join([
        RawWebSocket.frame(publish("first")),
        RawWebSocket.frame(publish(big)),
        RawWebSocket.frame(parts[0], fin=False),
        RawWebSocket.frame(b"are you there", opcode=0x9),
        RawWebSocket.frame(parts[1], opcode=0x0, fin=False),
        RawWebSocket.frame(parts[2], opcode=0x0),
        RawWebSocket.frame(publish("last")),
    ])
    return stream, ["first", big, "in fragments", "last"]


def pieces(data, sizes):
    """data cut into pieces of the given sizes in turn (the last piece takes the rest)."""
    at, index = 0, 0
    while at < len(data):
        size = sizes[index % len(sizes)]
        yield data[at:at + size]
        at, index = at + size, index + 1


@pytest.mark.parametrize("sizes", [None, [1], [3, 7, 1, 2], [5000, 70_000, 13]],
                         ids=["one-write", "byte-by-byte-start", "tiny-pieces", "odd-pieces"])
def test_frames_are_read_whole_whatever_pieces_they_come_in(port, node, sizes):
    from std_msgs.msg import String
    got = []
    sub = node.Subscriber(TOPIC, String, lambda m: got.append(m.data))
    client = RawWebSocket(port)
    try:
        client.sock.sendall(ADVERTISE)
        wait_for(lambda: sub.get_num_connections() >= 1, 20, what="the bridge's publisher connected")
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
