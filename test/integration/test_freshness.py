"""Per-topic freshness through a real bridge: a client behind a slow link keeps its small topic fresh while a
camera is subscribed (the bridge skips older messages of a topic that is behind, and says so); a client that
keeps up loses nothing."""

import json
import time

import pytest

from bridge_client import RawWebSocket, WsClient
from fixtures import bridge_fixture
from slow_link import Rover, paced_frames

bridge = bridge_fixture("freshness_bridge")


def percentile(values, fraction):
    values = sorted(values)
    return values[min(len(values) - 1, int(fraction * len(values)))]


@pytest.mark.slow
def test_a_slow_reader_keeps_its_small_topic_fresh_while_a_camera_is_subscribed(bridge, node):
    rover = Rover(node, "/fresh_slow")
    client = RawWebSocket(bridge, recv_buffer=65536)
    try:
        for request in (
            {"op": "set_level", "level": "warning"},
            {"op": "subscribe", "topic": "/fresh_slow/camera", "type": "sensor_msgs/Image"},
            {"op": "subscribe", "topic": "/fresh_slow/small", "type": "std_msgs/Float64"},
        ):
            client.send_text(json.dumps(request))
        rover.wait_connected()
        rover.start(seconds=12)
        small_ages, camera_ages, statuses = [], [], []
        start = time.monotonic()
        for _, payload in paced_frames(client.sock, rate=1_000_000, seconds=10):  # a third of the camera's rate
            frame = json.loads(payload)
            now, warm = time.time(), time.monotonic() - start > 3
            if frame["op"] == "status":
                statuses.append(frame)
            elif frame["topic"] == "/fresh_slow/small" and warm:
                small_ages.append(now - frame["msg"]["data"])
            elif frame["topic"] == "/fresh_slow/camera" and warm:
                stamp = frame["msg"]["header"]["stamp"]
                camera_ages.append(now - stamp["secs"] - stamp["nsecs"] / 1e9)
    finally:
        rover.stop()
        client.close()
    # the old oldest-first queue: both ages grew by ~0.7 s every second, to 5 s and more
    assert len(small_ages) >= 0.6 * 7 * 50, f"small topic: {len(small_ages)} of ~350 delivered"
    assert percentile(small_ages, 0.95) < 1.0 and max(small_ages) < 2.0, sorted(small_ages)[-10:]
    assert len(camera_ages) >= 5 and percentile(camera_ages, 0.95) < 2.0, camera_ages
    skipped = [s for s in statuses if s["msg"].startswith("skipped ")]
    assert skipped and skipped[0]["level"] == "warning" and "/fresh_slow/camera" in skipped[0]["msg"], statuses


def test_a_client_that_keeps_up_loses_nothing(bridge, node):
    rover = Rover(node, "/fresh_fast", small_hz=1000, camera_hz=15)
    client = WsClient(f"ws://127.0.0.1:{bridge}/")
    try:
        client.send({"op": "set_level", "level": "warning"})
        client.send({"op": "subscribe", "topic": "/fresh_fast/camera", "type": "sensor_msgs/Image"})
        client.send({"op": "subscribe", "topic": "/fresh_fast/small", "type": "std_msgs/Float64"})
        rover.wait_connected()
        thread = rover.start(small_count=2000, camera_count=30)
        small, camera, statuses = [], 0, []
        while len(small) < 2000 or camera < 30:
            frame = client.recv(timeout=20)
            if frame["op"] == "status":
                statuses.append(frame)
            elif frame["topic"] == "/fresh_fast/small":
                small.append(frame["msg"]["data"])
            else:
                camera += 1
        thread.join(10)
    finally:
        rover.stop()
        client.close()
    assert small == sorted(small) and len(set(small)) == 2000 and camera == 30
    assert not statuses
