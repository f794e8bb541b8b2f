"""permessage-deflate through a real bridge with its default settings (compress_slow_links): a client that offers it
(as every browser and roslibjs in Node do) gets its big messages deflated while its link is slow, whole, and as
they are while it keeps up; a client that does not offer it is unchanged; the client's own compressed messages
(each on its own: client_no_context_takeover) are taken."""

import base64
import contextlib
import json
import threading
import time
import zlib

import pytest

import hostile
from bridge_client import RawWebSocket, WsClient, ping
from fixtures import bridge_fixture
from harness import launch_bridge, wait_for, wait_publisher_connected
from slow_link import Rover, paced_frames

bridge = bridge_fixture("deflate_bridge")

OFFER = "permessage-deflate; client_max_window_bits"  # what Chromium and Tornado offer
ANSWER = "permessage-deflate; server_no_context_takeover; client_no_context_takeover"
RSV1 = 0x40


def read_in_background(client, rate, seconds):
    """Reads the client's frames in a thread: (arrival, first byte, payload) into the list returned."""
    got = []

    def read():
        for first, payload in paced_frames(client.sock, rate, seconds):
            got.append((time.monotonic(), first, payload))

    thread = threading.Thread(target=read, daemon=True)
    thread.start()
    return thread, got


def camera_frames(got, rover, topic):
    """(arrival, compressed, size on the wire) of each camera frame, each checked whole: inflated on its own (a
    fresh inflater: no context between messages) when RSV1 says so, its picture one the rover published."""
    frames = []
    for arrived, first, payload in got:
        compressed = bool(first & RSV1)
        text = zlib.decompressobj(-15).decompress(payload + b"\x00\x00\xff\xff") if compressed else payload
        frame = json.loads(text)
        if frame.get("topic") != topic:
            assert not compressed or len(text) >= 65536, frame  # (small messages go as they are)
            continue
        assert base64.b64decode(frame["msg"]["data"]) in rover.pictures
        frames.append((arrived, compressed, len(payload), len(text)))
    return frames


@pytest.mark.slow
def test_behind_a_slow_link_big_messages_arrive_deflated_and_whole_and_without_the_offer_as_before(bridge, node):
    rover = Rover(node, "/deflate_slow")
    offering = RawWebSocket(bridge, recv_buffer=65536, extensions=OFFER)
    plain = RawWebSocket(bridge, recv_buffer=65536)
    try:
        for client in (offering, plain):
            for request in (
                {"op": "subscribe", "topic": "/deflate_slow/camera", "type": "sensor_msgs/Image"},
                {"op": "subscribe", "topic": "/deflate_slow/small", "type": "std_msgs/Float64"},
            ):
                client.send_text(json.dumps(request))
        rover.wait_connected()
        rover.start(seconds=10)
        start = time.monotonic()
        readers = [read_in_background(client, 1_000_000, 9) for client in (offering, plain)]  # 8 Mbit/s each
        for thread, _ in readers:
            thread.join(20)
    finally:
        rover.stop()
        offering.close()
        plain.close()
    assert offering.extensions == ANSWER and plain.extensions is None
    deflated, as_before = (camera_frames(got, rover, "/deflate_slow/camera") for _, got in readers)
    # once its link is measured (a frame or two), every picture goes deflated: a quarter smaller (noise in base64)
    late = [frame for frame in deflated if frame[0] - start > 3]
    assert len(late) >= 5 and all(compressed for _, compressed, _, _ in late), deflated
    assert all(wire < 0.8 * size for _, compressed, wire, size in deflated if compressed)
    assert len(as_before) >= 5 and not any(first & RSV1 for _, first, _ in readers[1][1])


def test_a_reader_that_keeps_up_gets_big_messages_as_they_are(bridge, node):
    rover = Rover(node, "/deflate_fast", small_hz=50, camera_hz=15)
    client = RawWebSocket(bridge, extensions=OFFER)
    try:
        client.send_text(json.dumps({"op": "subscribe", "topic": "/deflate_fast/camera", "type": "sensor_msgs/Image"}))
        wait_for(lambda: rover.camera.get_num_connections(), 20, what="the bridge to subscribe")
        thread, got = read_in_background(client, None, 4)  # (reading before the first picture comes)
        rover.start(camera_count=30, small_count=0)
        thread.join(20)
    finally:
        rover.stop()
        client.close()
    assert client.extensions == ANSWER
    frames = camera_frames(got, rover, "/deflate_fast/camera")
    assert len(frames) >= 25 and not any(compressed for _, compressed, _, _ in frames)


def test_the_clients_own_compressed_messages_are_taken(ros, bridge, node):
    """A client that keeps no context between its messages, as agreed (browsers), and Tornado 6.2's client, which
    keeps it (its parser drops the answer's client_no_context_takeover)."""
    from std_msgs.msg import String

    received = []
    subscriber = node.Subscriber("/deflate_in", String, lambda msg: received.append(msg.data))
    texts = {
        name: [f"{name} " * 10_000, f"{name} " * 10_000 + "again", "short " + name]  # (the second may point
        for name in ("agreeing", "keeping")
    }  # back into the first)
    agreeing = RawWebSocket(bridge, extensions=OFFER)
    keeping = WsClient(f"ws://127.0.0.1:{bridge}/", compression_options={})  # (compresses every message)
    try:
        assert agreeing.extensions == ANSWER and keeping.conn.headers.get("Sec-WebSocket-Extensions") == ANSWER
        agreeing.send_text(
            json.dumps({"op": "advertise", "topic": "/deflate_in", "type": "std_msgs/String"}), deflated=True
        )
        # (from the bridge's side: after 1 s, what is published before the link is made is not replayed)
        wait_publisher_connected(ros, "/deflate_bridge", "/deflate_in", node.get_name())
        for text in texts["agreeing"]:
            agreeing.send_text(
                json.dumps({"op": "publish", "topic": "/deflate_in", "msg": {"data": text}}), deflated=True
            )
        for text in texts["keeping"]:
            keeping.send({"op": "publish", "topic": "/deflate_in", "msg": {"data": text}})
        wait_for(lambda: len(received) >= 6, 20, what="the messages")
        assert ping(keeping)
    finally:
        subscriber.unregister()
        agreeing.close()
        keeping.close()
    for name, sent in texts.items():
        assert [text for text in received if text.endswith(name) or text.startswith(name)] == sent


def test_compress_slow_links_false_negotiates_nothing(ros):
    proc, port = launch_bridge(ros, node_name="no_deflate_bridge", compress_slow_links="false")
    try:
        client = WsClient(f"ws://127.0.0.1:{port}/", compression_options={})
        assert client.conn.headers.get("Sec-WebSocket-Extensions") is None
        assert ping(client)
        client.close()
    finally:
        proc.stop()


budget_bridge = bridge_fixture("deflate_budget_bridge", scope="function", max_bytes_per_second=16_000_000)


def test_a_client_that_reconnects_after_each_bomb_is_held_to_one_clients_byte_budget(budget_bridge):
    """One address sends a compressed message that unpacks past max_message_size (8 MB), is closed, connects
    again, and again, for 4 s. Each new connection started with a full second's burst of max_bytes_per_second,
    so the loop unpacked as fast as the bridge could (75-80 % of a core in the attacker's run). A new connection
    now starts with what its address's last one left: at 16 MB/s, 11 bombs at most in 4 s (a 16 MB burst, then
    16 MB a second, 8 MB each)."""
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15)
    bomb = hostile.raw_frame(
        (compressor.compress(bytes(9_000_000)) + compressor.flush(zlib.Z_SYNC_FLUSH))[:-4], rsv1=True
    )
    url = f"ws://127.0.0.1:{budget_bridge}/"
    end, bombs = time.monotonic() + 4.0, 0
    while time.monotonic() < end:
        with contextlib.closing(hostile.raw_connect(url, "permessage-deflate")) as sock:
            sock.settimeout(10)
            sock.sendall(bomb)
            with contextlib.suppress(OSError):
                while sock.recv(65536):  # (until the bridge closes it)
                    pass
            bombs += 1
    print(f"{bombs} bombs unpacked in 4 s")
    assert bombs <= 11, f"{bombs} bombs unpacked in 4 s"
    with contextlib.closing(WsClient(url)) as client:  # (another client is served)
        ping(client)
