"""Hostile websocket clients, one abuse each, run as a process of their own (so that they compete with the
bridge, not with the measuring client, for the CPU and the GIL):

    python3 hostile.py ws://127.0.0.1:PORT/ ABUSE SECONDS

Each abuse runs for at most SECONDS (or until done) and the process exits; it prints one line of what it did.
`measure` runs one beside a well-behaved Victim (used by test_isolation.py and bench/suite.py)."""
import asyncio
import json
import socket
import struct
import sys
import threading
import time
import urllib.parse

from tornado.websocket import WebSocketClosedError, websocket_connect


async def flood(ws, seconds):
    """Cheap frames as fast as the socket takes them (each one answered with an error)."""
    sent, end = 0, time.monotonic() + seconds
    while time.monotonic() < end:
        for _ in range(100):
            ws.write_message('{"op":"no_such_op"}')  # (not awaited: as fast as the socket takes them)
        sent += 100
        await asyncio.sleep(0)
    return f"{sent} frames"


async def subscribe_many(ws, seconds):
    for i in range(2000):
        await ws.write_message(json.dumps({"op": "subscribe", "topic": f"/hostile/s{i}", "type": "std_msgs/String"}))
    return "2000 subscribes"


async def advertise_many(ws, seconds):
    for i in range(1000):
        await ws.write_message(json.dumps({"op": "advertise", "topic": f"/hostile/a{i}", "type": "std_msgs/String"}))
    return "1000 advertises"


async def publish_unknown(ws, seconds):
    sent, end = 0, time.monotonic() + seconds
    while time.monotonic() < end:
        await ws.write_message(json.dumps({"op": "publish", "topic": f"/hostile/p{sent}", "msg": {}}))
        sent += 1
    return f"{sent} publishes to unknown topics"


async def huge_throttle(ws, seconds):
    await ws.write_message('{"op":"subscribe","topic":"/turtle1/pose","throttle_rate":1' + "0" * 400 + "}")
    await asyncio.sleep(seconds)
    return "one subscribe with a 401-digit throttle_rate"


async def silent_service(ws, seconds):
    """Provides a service, calls it many times and never answers."""
    await ws.write_message(json.dumps({"op": "advertise_service", "service": "/hostile/silent",
                                       "type": "std_srvs/Empty"}))
    await asyncio.sleep(1)
    for i in range(100):
        await ws.write_message(json.dumps({"op": "call_service", "service": "/hostile/silent", "id": f"c{i}"}))
    await asyncio.sleep(seconds)
    return "100 calls of its own silent service"


async def auth_flood(ws, seconds):
    sent, end = 0, time.monotonic() + seconds
    while time.monotonic() < end:
        await ws.write_message(json.dumps({"op": "auth", "mac": "x", "client": "c", "dest": "d", "rand": "r",
                                           "t": int("9" * 400), "level": "admin", "end": 0}))
        sent += 1
    return f"{sent} auth frames"


def pings_never_read(url, seconds):
    """A raw socket: the handshake, then small masked pings as fast as the bridge takes them, never reading the
    pongs."""
    parts = urllib.parse.urlparse(url)
    sock = socket.create_connection((parts.hostname, parts.port))
    sock.sendall(f"GET / HTTP/1.1\r\nHost: {parts.hostname}:{parts.port}\r\nUpgrade: websocket\r\n"
                 "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                 "Sec-WebSocket-Version: 13\r\n\r\n".encode())
    pings = (struct.pack("!BB", 0x89, 0x80 | 4) + bytes(4) + b"ping") * 10_000  # mask key 0: as is
    sock.settimeout(1.0)
    sent, end = 0, time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            sock.sendall(pings)
            sent += 10_000
        except OSError:  # the bridge closed us (or our send buffer stays full)
            break
    return f"{sent} pings of 4 bytes"


ABUSES_IN_PROCESS = {f.__name__: f for f in (flood, subscribe_many, advertise_many, publish_unknown, huge_throttle,
                                  silent_service, auth_flood)}


def unawaited_writes_quiet(loop, context):
    """The flood's unawaited writes are cancelled when its connection closes; each would print a traceback
    (tens of thousands: seconds of the attacker's exit, after its flood)."""
    if not isinstance(context.get("exception"), asyncio.CancelledError):
        loop.default_exception_handler(context)


async def main(url, abuse, seconds):
    """Runs one abuse, again and again on a new connection when the bridge closes it, for `seconds`."""
    end, done = time.monotonic() + seconds, []
    asyncio.get_running_loop().set_exception_handler(unawaited_writes_quiet)
    while time.monotonic() < end:
        ws = await websocket_connect(url)
        try:
            done.append(await asyncio.wait_for(ABUSES_IN_PROCESS[abuse](ws, end - time.monotonic()), seconds + 60))
        except WebSocketClosedError:
            done.append("closed by the bridge")
            continue
        ws.close()
        break
    return "; ".join(done[:3]) + (f" (and {len(done) - 3} more connections)" if len(done) > 3 else "")


class Victim:
    """A well-behaved client on a thread of its own: the largest gap between poses, the slowest get_time."""

    def __init__(self, url, auth=None):
        self.url, self.auth = url, auth
        self.arrivals, self.call_times, self.own_stalls = [], [], []
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
        async def ticker():  # how late this thread's own loop ran: a gap it causes is not the bridge's
            while True:
                before = time.monotonic()
                await asyncio.sleep(0.01)
                self.own_stalls.append((before, time.monotonic() - before - 0.01))
        reading, ticking = asyncio.ensure_future(reader()), asyncio.ensure_future(ticker())
        n = 0
        while not self._stop.is_set():
            n += 1
            calls[n] = time.monotonic()
            await ws.write_message(json.dumps({"op": "call_service", "service": "/rosapi/get_time", "id": n}))
            await asyncio.sleep(0.25)
        self.unanswered = [time.monotonic() - sent for sent in calls.values()]
        ws.close()
        reading.cancel()
        ticking.cancel()

    def largest_gap(self, since):
        """The largest gap between poses after `since`, where it began (seconds after `since`) and this
        thread's own longest stall in it."""
        times = [t for t in self.arrivals if t >= since]
        gap, start = max(((b - a, a) for a, b in zip(times, times[1:])), default=(float("inf"), since))
        own = max((lag for t, lag in self.own_stalls if start <= t <= start + gap), default=0.0)
        return gap, start - since, own

    def stop(self):
        self._stop.set()
        self._thread.join(10)


ABUSES = [*ABUSES_IN_PROCESS, "pings_never_read"]


def measure(ros, url, server, abuse, seconds, auth=None):
    """Runs `abuse` for `seconds` beside a Victim (sending `auth` first if given) on the bridge at `url` whose
    server process is `server` (a ProcStat); returns what the attacker did and what the victim saw (times in
    seconds from the attacker's start: `attacked`, when it ended; `gap_at`, when the largest gap began; and
    `victims_own_stall`, the victim's own loop's longest stall in that gap, which the bridge did not cause)."""
    victim = Victim(url, auth)
    time.sleep(1.0)
    rss_before, started = server.rss_mb(), time.monotonic()
    attacker = ros.spawn([sys.executable, __file__, url, abuse, str(seconds)], f"hostile_{abuse}")
    code = attacker.popen.wait(seconds + 90)
    attacked = time.monotonic() - started
    time.sleep(0.5)
    victim.stop()
    gap, gap_at, own_stall = victim.largest_gap(started)
    return {"attacker": attacker.output().strip(), "attacker_exit": code, "attacked": attacked,
            "gap": gap, "gap_at": gap_at, "victims_own_stall": own_stall,
            "slowest_call": max(victim.call_times + victim.unanswered, default=float("inf")),
            "rss_growth": server.rss_mb() - rss_before}


if __name__ == "__main__":
    url, abuse, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    if abuse == "pings_never_read":
        print(pings_never_read(url, seconds), flush=True)
    else:
        print(asyncio.run(main(url, abuse, seconds)), flush=True)
