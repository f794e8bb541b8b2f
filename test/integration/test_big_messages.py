"""Big messages through a real bridge: a 16 MB occupancy grid, fragmented as a client asks, arrives whole at the
default limits; a small latched topic is not kept behind it; CBOR with fragment_size is one binary frame."""

import io
import json
import os
import struct
import time

import cbor2
import pytest

from bridge_client import WsClient
from fixtures import bridge_fixture
from harness import wait_for

pytestmark = pytest.mark.slow

bridge = bridge_fixture("big_messages_bridge")

SIDE = 4000  # cells: 16 MB, about 40 MB as JSON


def grid_class(payload):
    """nav_msgs/OccupancyGrid whose data is `payload` (bytes), serialized without a Python int per cell."""
    from nav_msgs.msg import OccupancyGrid

    class RawGrid(OccupancyGrid):
        def serialize(self, buff):
            head = io.BytesIO()
            OccupancyGrid.serialize(self, head)  # (its data is empty: the last 4 bytes are its length, 0)
            buff.write(head.getvalue()[:-4] + struct.pack("<I", len(payload)) + payload)

    return RawGrid


def test_a_fragmented_16_mb_map_arrives_whole_and_a_small_latched_topic_does_not_wait_for_it(bridge, node):
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    cells = os.urandom(SIDE * SIDE).translate(bytes((0xFF, 0, 100, 0) * 64))  # unknown, free, occupied
    grid = grid_class(cells)()
    grid.info.width = grid.info.height = SIDE
    grid.info.resolution = 0.05
    map_pub = node.Publisher("/big/map", grid_class(cells), queue_size=1, latch=True)
    tf_pub = node.Publisher("/big/tf_static", TFMessage, queue_size=1, latch=True)
    client = WsClient(f"ws://127.0.0.1:{bridge}/", timeout=60)
    try:
        tf_pub.publish(TFMessage([TransformStamped(child_frame_id="laser")]))
        map_pub.publish(grid)
        client.send(
            {"op": "subscribe", "topic": "/big/map", "type": "nav_msgs/OccupancyGrid", "fragment_size": 100_000}
        )
        wait_for(lambda: map_pub.get_num_connections(), 20, what="the bridge to subscribe to the map")
        time.sleep(0.5)  # the map is on its way (read, encoded)
        asked = time.monotonic()
        client.send({"op": "subscribe", "topic": "/big/tf_static", "type": "tf2_msgs/TFMessage"})
        parts, total, tf_at, statuses = {}, None, None, []
        while total is None or len(parts) < total:
            frame = client.recv(timeout=60)
            if frame["op"] == "fragment":
                parts[frame["num"]] = frame["data"]
                total = frame["total"]
            elif frame["op"] == "publish" and frame["topic"] == "/big/tf_static":
                tf_at = time.monotonic() - asked
                map_left = None if total is None else total - len(parts)
            else:
                statuses.append(frame)
        whole = json.loads("".join(parts[n] for n in range(total)))
    finally:
        client.close()
        map_pub.unregister()
        tf_pub.unregister()
    assert not statuses, statuses
    assert whole["topic"] == "/big/map" and len(whole["msg"]["data"]) == SIDE * SIDE
    assert bytes(v & 0xFF for v in whole["msg"]["data"][:100_000]) == cells[:100_000]
    assert tf_at is not None and tf_at < 1.0, f"/tf_static came {tf_at} s after it was asked for"
    assert map_left is None or map_left > 0  # (it came while the map was still on its way, or before it)


def test_cbor_with_fragment_size_is_one_whole_binary_frame(bridge, node):
    """roslibjs reassembles only text fragments, so a CBOR message goes whole, whatever fragment_size says."""
    from std_msgs.msg import String

    pub = node.Publisher("/big/text", String, queue_size=1, latch=True)
    client = WsClient(f"ws://127.0.0.1:{bridge}/")
    try:
        pub.publish(String("x" * 100_000))
        client.send(
            {
                "op": "subscribe",
                "topic": "/big/text",
                "type": "std_msgs/String",
                "compression": "cbor",
                "fragment_size": 1000,
            }
        )
        frame = client.recv_raw(timeout=20)
    finally:
        client.close()
        pub.unregister()
    assert isinstance(frame, bytes)
    message = cbor2.loads(frame)
    assert message["op"] == "publish" and message["msg"]["data"] == "x" * 100_000


small_bound_bridge = bridge_fixture("small_bound_bridge", max_queue=30)


def test_a_client_behind_loses_whole_fragmented_messages_only_and_is_told(small_bound_bridge, node):
    """Messages of 10 fragments each for a client that does not read: what the bridge leaves out (the older
    messages of a topic that is behind, or the oldest beyond the client's bound) are whole messages: every
    fragmented message that arrives is complete, and the client is told."""
    from std_msgs.msg import String

    from bridge_client import RawWebSocket

    pub = node.Publisher("/big/parts", String, queue_size=1000)
    client = RawWebSocket(small_bound_bridge, recv_buffer=4096)
    try:
        client.send_text(json.dumps({"op": "set_level", "level": "warning"}))
        client.send_text(
            json.dumps(
                {
                    "op": "subscribe",
                    "topic": "/big/parts",
                    "type": "std_msgs/String",
                    "fragment_size": 10_000,
                    "queue_length": 1000,
                }
            )
        )
        wait_for(lambda: pub.get_num_connections(), 20, what="the bridge to subscribe")
        for n in range(100):  # ~100 kB each, 10 fragments: far more than the client's socket and its 30 frames
            pub.publish(String(f"{n:03d}" + "x" * 95_000))
        time.sleep(2)
        parts, statuses, done = {}, [], set()
        client.sock.settimeout(5)
        while "099" not in done:
            _, payload = client.recv_frame()
            frame = json.loads(payload)
            if frame["op"] == "status":
                statuses.append(frame)
                continue
            assert frame["op"] == "fragment"
            pieces = parts.setdefault(frame["id"], {})
            pieces[frame["num"]] = frame["data"]
            if len(pieces) == frame["total"]:
                message = json.loads("".join(pieces[n] for n in range(frame["total"])))
                done.add(message["msg"]["data"][:3])
                del parts[frame["id"]]
    finally:
        client.close()
        pub.unregister()
    assert not parts, f"{len(parts)} message(s) cut: only whole messages may be dropped"
    assert 0 < len(done) < 100
    told = [s for s in statuses if s["msg"].startswith(("skipped ", "dropped ")) and "/big/parts" in s["msg"]]
    assert told, statuses
