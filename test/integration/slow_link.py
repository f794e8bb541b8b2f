"""What the freshness and deflate tests share: a rover publishing a small topic and a camera from the test
process, and a reader behind a slow link."""

import os
import struct
import threading
import time

from harness import wait_for

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
        self._thread = None  # (start)
        self.sent = {"small": 0, "camera": 0}

    def wait_connected(self):
        wait_for(
            lambda: self.small.get_num_connections() and self.camera.get_num_connections(),
            20,
            what="the bridge to subscribe",
        )

    def run(self, seconds=None, small_count=None, camera_count=None):
        import rospy
        from sensor_msgs.msg import Image
        from std_msgs.msg import Float64

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
                picture = Image(
                    height=HEIGHT,
                    width=WIDTH,
                    encoding="rgb8",
                    step=WIDTH * 3,
                    data=self.pictures[self.sent["camera"] % 4],
                )
                picture.header.stamp = rospy.Time.from_sec(time.time())
                self.camera.publish(picture)
                self.sent["camera"] += 1
                next_camera += 1 / self.camera_hz
            time.sleep(max(0.0, min(next_small, next_camera) - time.monotonic()))

    def start(self, **kwargs):
        self._thread = threading.Thread(target=self.run, kwargs=kwargs, daemon=True)
        self._thread.start()
        return self._thread

    def stop(self):
        self._stop.set()
        if self._thread is not None:
            self._thread.join(10)  # (rospy fails a publish to a topic unregistered meanwhile)
        self.small.unregister()
        self.camera.unregister()


def paced_frames(sock, rate, seconds):
    """The server's frames (their first byte: FIN, RSV1 and opcode; their payload) read off `sock` at `rate`
    bytes/s at most (None: as fast as they come), for `seconds`: with a small receive buffer, a client behind a
    slow link (the bridge's socket stays backed up)."""
    buffer, start, got = bytearray(), time.monotonic(), 0
    sock.settimeout(0.2)
    while time.monotonic() - start < seconds:
        allowed = 65536 if rate is None else rate * (time.monotonic() - start) - got
        if allowed < 4096:
            time.sleep(0.004)
            continue
        try:
            chunk = sock.recv(min(int(allowed), 65536))
        except TimeoutError:
            continue
        assert chunk, "the bridge closed the connection"
        got += len(chunk)
        buffer += chunk
        while (frame := _parse(buffer)) is not None:
            first, payload, used = frame
            del buffer[:used]
            yield first, payload


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
    return buffer[0], bytes(buffer[used : used + length]), used + length
