"""One client never hurts another: while a hostile client (hostile.py, a process of its own) abuses the bridge,
a well-behaved client subscribed to turtlesim's 62.5 Hz pose keeps receiving it with no gap over 0.5 s, and its
/rosapi/get_time calls are answered within 1 s; the bridge's memory stays bounded and it keeps running."""
import asyncio
import json
import sys
import threading
import time
from pathlib import Path

import pytest
from tornado.websocket import websocket_connect

from harness import ProcStat, node_pid, start_bridge
from test_security import SECRET, auth_frame

HOSTILE = Path(__file__).with_name("hostile.py")
ATTACK_SECONDS = 6.0
MAX_GAP = 0.5
MAX_CALL_TIME = 1.0


class Victim:
    """A well-behaved client on a thread of its own: the largest gap between poses, the slowest get_time."""

    def __init__(self, url, auth=None):
        self.url, self.auth = url, auth
        self.arrivals, self.call_times = [], []
        self.ready, self._stop = threading.Event(), threading.Event()
        self._thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)
        self._thread.start()
        assert self.ready.wait(30), "the victim could not start"

    async def _run(self):
        ws = await websocket_connect(self.url)
        if self.auth is not None:
            await ws.write_message(json.dumps(self.auth))
        await ws.write_message(json.dumps({"op": "subscribe", "topic": "/turtle1/pose", "type": "turtlesim/Pose"}))
        calls = {}

        async def reader():
            while True:
                frame = await ws.read_message()
                if frame is None:
                    return
                message, now = json.loads(frame), time.monotonic()
                if message.get("topic") == "/turtle1/pose":
                    self.arrivals.append(now)
                    self.ready.set()
                elif message.get("op") == "service_response" and message.get("id") in calls:
                    self.call_times.append(now - calls.pop(message["id"]))
        reading = asyncio.ensure_future(reader())
        n = 0
        while not self._stop.is_set():
            n += 1
            calls[n] = time.monotonic()
            await ws.write_message(json.dumps({"op": "call_service", "service": "/rosapi/get_time", "id": n}))
            await asyncio.sleep(0.25)
        self.unanswered = [time.monotonic() - sent for sent in calls.values()]
        ws.close()
        reading.cancel()

    def largest_gap(self, since):
        times = [t for t in self.arrivals if t >= since]
        return max((b - a for a, b in zip(times, times[1:])), default=float("inf"))

    def stop(self):
        self._stop.set()
        self._thread.join(10)


@pytest.fixture(scope="module")
def turtlesim(ros):
    turtle = ros.spawn(["rosrun", "turtlesim", "turtlesim_node", "__name:=isolation_turtle"], "isolation_turtle")
    turtle.wait_output("Spawning turtle [turtle1]", timeout=30)
    yield
    turtle.stop()


ABUSES = ["flood", "subscribe_many", "advertise_many", "publish_unknown", "huge_throttle", "silent_service",
          "auth_flood", "pings_never_read"]


@pytest.mark.parametrize("abuse", ABUSES)
def test_a_hostile_client_does_not_hurt_a_well_behaved_one(ros, turtlesim, abuse, tmp_path):
    args = {}
    if abuse == "auth_flood":  # the attacker is not authenticated, the victim is
        secret = tmp_path / "secret"
        secret.write_text(SECRET)
        args = {"authenticate": "true", "secret_file": secret}
    proc, port = start_bridge(ros, node_name=f"isolation_{abuse}", unregister_timeout=1, **args)
    url = f"ws://127.0.0.1:{port}/"
    stat = ProcStat(node_pid(ros, f"/isolation_{abuse}"))
    try:
        victim = Victim(url, auth=auth_frame() if args else None)
        time.sleep(1.0)
        rss_before = stat.rss_mb()
        started = time.monotonic()
        attacker = ros.spawn([sys.executable, str(HOSTILE), url, abuse, str(ATTACK_SECONDS)], f"hostile_{abuse}")
        assert attacker.popen.wait(ATTACK_SECONDS + 90) == 0, attacker.output()
        time.sleep(0.5)
        victim.stop()
        gap = victim.largest_gap(started)
        slowest = max(victim.call_times + victim.unanswered, default=float("inf"))
        growth = stat.rss_mb() - rss_before
        print(f"{abuse}: {attacker.output().strip()}; victim's largest gap {gap:.3f} s, slowest get_time "
              f"{slowest:.3f} s, bridge RSS {growth:+.0f} MB")
        assert gap < MAX_GAP, f"{abuse}: the victim went {gap:.2f} s without a pose"
        assert slowest < MAX_CALL_TIME, f"{abuse}: a get_time took {slowest:.2f} s"
        assert growth < 200, f"{abuse}: the bridge grew by {growth:.0f} MB"
        assert proc.alive()
    finally:
        proc.stop()

