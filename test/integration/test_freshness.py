"""Per-topic freshness through a real bridge: a client behind a slow link keeps its small topic fresh while a
camera is subscribed (the bridge skips older messages of a topic that is behind, and says so); a client that
keeps up loses nothing."""
import json
import os
import socket
import struct
import threading
import time

from bridge_client import RawWebSocket, WsClient
from fixtures import bridge_fixture
from harness import wait_for

bridge = bridge_fixture("freshness_bridge")

WIDTH, HEIGHT = 320, 240  # rgb8: about 307 kB a picture as JSON (base64)


class Rover:
    """Publishes, from the test process, a small topic at `small_hz` whose data is its publish time, and a camera
    of noise at `camera_hz` stamped with its publish time, for `seconds` or until stopped."""

    def __init__(self, node, prefix, small_hz=50, camera_hz=15):
        from sensor_msgs.msg import Image
        from std_msgs.msg import Float64
        self.small = node.Publisher(prefix + "/small", Float64, queue_size=2000)
        self.camera = node.Publisher(prefix + "/camera", Image, queue_size=100)
        self.small_hz, self.camera_hz = small_hz, camera_hz
        self.pictures = [os.urandom(WIDTH * HEIGHT * 3) for _ in range(4)]
        self._stop = threading.Event()
        self.sent = {"small": 0, "camera": 0}

    def wait_connected(self):
        wait_for(lambda: self.small.get_num_connections() and self.camera.get_num_connections(), 20,
                 what="the bridge to subscribe")

    def run(self, seconds=None, small_count=None, camera_count=None):
        from sensor_msgs.msg import Image
        from std_msgs.msg import Float64
        import rospy
        start = time.monotonic()
        next_small = next_camera = start
        while not self._stop.is_set():
            now = time.monotonic()
            if seconds is not None and now - start > seconds:
                break
            if small_count is not None and self.sent["small"] >= small_count and self.sent["camera"] >= camera_count:
                break
            if now >= next_small and (small_count is None or self.sent["small"] < small_count):
                self.small.publish(Float64(time.time()))
                self.sent["small"] += 1
                next_small += 1 / self.small_hz
            if now >= next_camera and (camera_count is None or self.sent["camera"] < camera_count):
                picture = Image(height=HEIGHT, width=WIDTH, encoding="rgb8", step=WIDTH * 3,
                                data=self.pictures[self.sent["camera"] % 4])
                picture.header.stamp = rospy.Time.from_sec(time.time())
                self.camera.publish(picture)
                self.sent["camera"] += 1
                next_camera += 1 / self.camera_hz
            time.sleep(max(0.0, min(next_small, next_camera) - time.monotonic()))

    def start(self, **kwargs):
        thread = threading.Thread(target=self.run, kwargs=kwargs, daemon=True)
        thread.start()
        return thread

    def stop(self):
        self._stop.set()
        self.small.unregister()
        self.camera.unregister()


def paced_frames(sock, rate, seconds):
    """The server's frames (opcode, payload) read off `sock` at `rate` bytes/s at most, for `seconds`: a client
    behind a slow link (its small receive buffer keeps the bridge's socket backed up)."""
    buffer, start, got = bytearray(), time.monotonic(), 0
    sock.settimeout(0.2)
    while time.monotonic() - start < seconds:
        allowed = rate * (time.monotonic() - start) - got
        if allowed < 4096:
            time.sleep(0.004)
            continue
        try:
            chunk = sock.recv(min(int(allowed), 65536))
        except socket.timeout:
            continue
        assert chunk, "the bridge closed the connection"
        got += len(chunk)
        buffer += chunk
        while (frame := _parse(buffer)) is not None:
            opcode, payload, used = frame
            del buffer[:used]
            yield opcode, payload


def _parse(buffer):
    if len(buffer) < 2:
        return None
    length, used = buffer[1] & 0x7F, 2
    if length == 126:
        if len(buffer) < 4:
            return None
        length, used = struct.unpack_from("!H", buffer, 2)[0], 4
    elif length == 127:
        if len(buffer) < 10:
            return None
        length, used = struct.unpack_from("!Q", buffer, 2)[0], 10
    if len(buffer) < used + length:
        return None
    return buffer[0] & 0x0F, bytes(buffer[used:used + length]), used + length


def percentile(values, fraction):
    values = sorted(values)
    return values[min(len(values) - 1, int(fraction * len(values)))]


def test_a_slow_reader_keeps_its_small_topic_fresh_while_a_camera_is_subscribed(bridge, node):
    rover = Rover(node, "/fresh_slow")
    client = RawWebSocket(bridge, recv_buffer=65536)
    try:
        for request in ({"op": "set_level", "level": "warning"},
                        {"op": "subscribe", "topic": "/fresh_slow/camera", "type": "sensor_msgs/Image"},
                        {"op": "subscribe", "topic": "/fresh_slow/small", "type": "std_msgs/Float64"}):
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
