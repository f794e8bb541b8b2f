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
        client.send({"op": "subscribe", "topic": "/big/map", "type": "nav_msgs/OccupancyGrid",
                     "fragment_size": 100_000})
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
        client.send({"op": "subscribe", "topic": "/big/text", "type": "std_msgs/String", "compression": "cbor",
                     "fragment_size": 1000})
        frame = client.recv_raw(timeout=20)
    finally:
        client.close()
        pub.unregister()
    assert isinstance(frame, bytes)
    message = cbor2.loads(frame)
    assert message["op"] == "publish" and message["msg"]["data"] == "x" * 100_000
