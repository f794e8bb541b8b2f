"""Hostile websocket clients, one abuse each, run as a process of their own (so that they compete with the
bridge, not with the measuring client, for the CPU and the GIL):

    python3 hostile.py ws://127.0.0.1:PORT/ ABUSE SECONDS

Each abuse runs for at most SECONDS (or until done) and the process exits; it prints one line of what it did.
`measure` runs one beside a well-behaved Victim (used by test_isolation.py and bench/suite.py)."""

import asyncio
import itertools
import json
import socket
import struct
import sys
import threading
import time
import urllib.parse
import zlib

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
    await ws.write_message(
        json.dumps({"op": "advertise_service", "service": "/hostile/silent", "type": "std_srvs/Empty"})
    )
    await asyncio.sleep(1)
    for i in range(100):
        await ws.write_message(json.dumps({"op": "call_service", "service": "/hostile/silent", "id": f"c{i}"}))
    await asyncio.sleep(seconds)
    return "100 calls of its own silent service"


async def auth_flood(ws, seconds):
    sent, end = 0, time.monotonic() + seconds
    while time.monotonic() < end:
        await ws.write_message(
            json.dumps(
                {
                    "op": "auth",
                    "mac": "x",
                    "client": "c",
                    "dest": "d",
                    "rand": "r",
                    "t": int("9" * 400),
                    "level": "admin",
                    "end": 0,
                }
            )
        )
        sent += 1
    return f"{sent} auth frames"


def raw_connect(url, extensions="", recv_buffer=None, subprotocol=None):
    """A raw socket after the websocket handshake (sent, its answer not read), offering `extensions` (and
    `subprotocol`); with recv_buffer, its receive buffer that small (a client that reads nothing then takes almost
    nothing)."""
    parts = urllib.parse.urlparse(url)
    sock = socket.socket()
    if recv_buffer:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, recv_buffer)
    sock.connect((parts.hostname, parts.port))
    offer = f"Sec-WebSocket-Extensions: {extensions}\r\n" if extensions else ""
    offer += f"Sec-WebSocket-Protocol: {subprotocol}\r\n" if subprotocol else ""
    sock.sendall(
        f"GET / HTTP/1.1\r\nHost: {parts.hostname}:{parts.port}\r\nUpgrade: websocket\r\n"
        "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
        f"Sec-WebSocket-Version: 13\r\n{offer}\r\n".encode()
    )
    return sock


def raw_frame(payload, opcode=0x1, fin=True, rsv1=False):
    """A client frame with the mask key 0 (its payload as is)."""
    first = (0x80 if fin else 0) | (0x40 if rsv1 else 0) | opcode
    if len(payload) < 126:
        head = struct.pack("!BB", first, 0x80 | len(payload))
    elif len(payload) < 1 << 16:
        head = struct.pack("!BBH", first, 0x80 | 126, len(payload))
    else:
        head = struct.pack("!BBQ", first, 0x80 | 127, len(payload))
    return head + bytes(4) + payload


def pings_never_read(url, seconds):
    """A raw socket: the handshake, then small masked pings as fast as the bridge takes them, never reading the
    pongs."""
    sock = raw_connect(url)
    pings = raw_frame(b"ping", opcode=0x9) * 10_000
    sock.settimeout(1.0)
    sent, end = 0, time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            sock.sendall(pings)
            sent += 10_000
        except OSError:  # the bridge closed us (or our send buffer stays full)
            break
    return f"{sent} pings of 4 bytes"


def on_connections(count, url, seconds, extensions, abuse, recv_buffer=None):
    """Runs abuse(sock, end) on `count` raw connections at once, each on a new connection whenever the bridge
    closes its last one, until `seconds` have passed; returns how many connections were made and what the abuses
    returned, added up."""
    end, totals = time.monotonic() + seconds, []

    def run():
        connections = done = 0
        while time.monotonic() < end:
            sock = raw_connect(url, extensions, recv_buffer)
            connections += 1
            try:
                done += abuse(sock, end)
            except OSError:  # the bridge closed it
                pass
            finally:
                sock.close()
        totals.append((connections, done))

    threads = [threading.Thread(target=run) for _ in range(count)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return tuple(map(sum, zip(*totals)))


def inflate_bombs(url, seconds):
    """Four connections that offer permessage-deflate, each sending a 30 kB compressed text message that unpacks
    to 31 MB, again and again as fast as the bridge takes them."""
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15)
    packed = (compressor.compress(bytes(31_000_000)) + compressor.flush(zlib.Z_SYNC_FLUSH))[:-4]
    bomb = raw_frame(packed, rsv1=True)

    def send(sock, end):
        sent = 0
        try:
            while time.monotonic() < end:
                sock.settimeout(max(0.1, end - time.monotonic()))
                sock.sendall(bomb)
                sent += 1
        except OSError:  # the bridge closed it
            pass
        return sent

    connections, sent = on_connections(4, url, seconds, "permessage-deflate", send)
    return f"{sent} bombs of {len(bomb)} bytes (31 MB unpacked) on {connections} connections"


def unfinished_messages(url, seconds):
    """Five connections, each starting a text message of 30 MB in frames of 1 MB (FIN=0) that it never
    finishes, then waiting."""
    part = bytes(1_000_000)
    message = raw_frame(part, fin=False) + raw_frame(part, opcode=0x0, fin=False) * 29

    def hold(sock, end):
        sock.sendall(message)
        sock.settimeout(max(0.0, end - time.monotonic()))
        try:
            while sock.recv(65536):  # (until the bridge closes it)
                pass
        except TimeoutError:
            pass
        return 1

    connections, _ = on_connections(5, url, seconds, "", hold)
    return f"{connections} unfinished messages of 30 MB"


def never_reads(url, seconds):
    """Ten connections that never read (a receive buffer of 4 kB), each asking for twelve answers of 7 MB, one
    connection after the other: /rosapi/get_param of a parameter that is not set answers the default the client
    gave."""
    default, end, socks, asked = json.dumps("B" * 7_000_000), time.monotonic() + seconds, [], 0
    try:
        for _ in range(10):
            socks.append(raw_connect(url, recv_buffer=4096))
            for call in range(12):
                socks[-1].sendall(
                    raw_frame(
                        json.dumps(
                            {
                                "op": "call_service",
                                "service": "/rosapi/get_param",
                                "id": call,
                                "args": {"name": "/hostile/unset", "default": default},
                            }
                        ).encode()
                    )
                )
                asked += 1
        time.sleep(max(0.0, end - time.monotonic()))
    except OSError as error:  # the bridge closed one
        return f"{asked} answers of 7 MB asked, then {error}"
    finally:
        for sock in socks:
            sock.close()
    return f"{asked} answers of 7 MB asked on 10 connections that never read"


def parked_fragments(url, seconds):
    """Forty connections, each sending the first of two `fragment` ops of 8 MB, never the second, then waiting."""

    def park(sock, end):
        sock.sendall(
            raw_frame(
                json.dumps({"op": "fragment", "id": "parked", "num": 0, "total": 2, "data": "F" * 7_990_000}).encode()
            )
        )
        time.sleep(max(0.0, end - time.monotonic()))
        return 1

    _, parked = on_connections(40, url, seconds, "", park)
    return f"{parked} fragments of 8 MB parked"


ABUSES_IN_PROCESS = {
    f.__name__: f
    for f in (flood, subscribe_many, advertise_many, publish_unknown, huge_throttle, silent_service, auth_flood)
}


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


POSE = object()  # (Victim._heard: a frame is a pose)


class Victim:
    """A well-behaved client on a thread of its own: the largest gap between poses, the slowest get_time, the
    round trips of its websocket pings. What it says and hears is rosbridge's (_open, _heard, _ask: another
    protocol's victim changes those)."""

    def __init__(self, url, auth=None):
        self.url, self.auth = url, auth
        self.arrivals, self.call_times, self.own_stalls, self.ping_times = [], [], [], []
        self.ready, self._stop = threading.Event(), threading.Event()
        self._thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)
        self._thread.start()
        assert self.ready.wait(30), "the victim could not start"

    async def _open(self):
        """The connection, subscribed to the pose."""
        ws = await websocket_connect(self.url)
        if self.auth is not None:
            await ws.write_message(json.dumps(self.auth))
        await ws.write_message(json.dumps({"op": "subscribe", "topic": "/turtle1/pose", "type": "turtlesim/Pose"}))
        return ws

    def _heard(self, frame):
        """POSE, the id of the call a frame answers, or None."""
        message = json.loads(frame)
        if message.get("topic") == "/turtle1/pose":
            return POSE
        return message.get("id") if message.get("op") == "service_response" else None

    async def _ask(self, ws, n):
        """Call n (answered within MAX_CALL_TIME by a bridge that serves everyone)."""
        await ws.write_message(json.dumps({"op": "call_service", "service": "/rosapi/get_time", "id": n}))

    async def _run(self):
        ws = await self._open()
        calls, pings = {}, {}

        def pong(data):
            if data in pings:
                self.ping_times.append(time.monotonic() - pings.pop(data))

        ws.on_pong = pong

        async def reader():
            while True:
                frame = await ws.read_message()
                if frame is None:
                    return
                heard, now = self._heard(frame), time.monotonic()
                if heard is POSE:
                    self.arrivals.append(now)
                    self.ready.set()
                elif heard in calls:
                    self.call_times.append(now - calls.pop(heard))

        async def ticker():  # how late this thread's own loop ran: a gap it causes is not the bridge's
            while True:
                before = time.monotonic()
                await asyncio.sleep(0.01)
                self.own_stalls.append((before, time.monotonic() - before - 0.01))

        async def pinger():  # a websocket ping every 50 ms: answered by the bridge as soon as it reads it
            for k in itertools.count():
                pings[b"%d" % k] = time.monotonic()
                ws.ping(b"%d" % k)
                await asyncio.sleep(0.05)

        tasks = [asyncio.ensure_future(task()) for task in (reader, ticker, pinger)]
        n = 0
        while not self._stop.is_set():
            n += 1
            calls[n] = time.monotonic()
            await self._ask(ws, n)
            await asyncio.sleep(0.25)
        self.unanswered = [time.monotonic() - sent for sent in calls.values()]
        self.ping_times += [time.monotonic() - sent for sent in pings.values()]
        ws.close()
        for task in tasks:
            task.cancel()

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


RAW_ABUSES = {
    f.__name__: f for f in (pings_never_read, inflate_bombs, unfinished_messages, never_reads, parked_fragments)
}
ABUSES = [*ABUSES_IN_PROCESS, *RAW_ABUSES]


def measure(ros, url, server, abuse, seconds, auth=None, victim=Victim, script=__file__):
    """Runs `abuse` (of `script`: this one's, or another's run alike) for `seconds` beside a victim
    (a Victim, or what `victim` makes of the url and auth: sending `auth` first if given) on the bridge at `url`
    whose server process is `server` (a ProcStat); returns what the attacker did and what the victim saw (times in
    seconds from the attacker's start: `attacked`, when it ended; `gap_at`, when the largest gap began;
    `victims_own_stall`, the victim's own loop's longest stall in that gap, which the bridge did not cause; its
    pings' round trips; the bridge's memory growth after the attack and at its peak; `victim`, the victim)."""
    victim = victim(url, auth)
    time.sleep(1.0)
    rss_before, started = server.rss_mb(), time.monotonic()
    server.reset_peak_rss()
    attacker = ros.spawn([sys.executable, script, url, abuse, str(seconds)], f"hostile_{abuse}")
    code = attacker.popen.wait(seconds + 90)
    attacked = time.monotonic() - started
    time.sleep(0.5)
    victim.stop()
    gap, gap_at, own_stall = victim.largest_gap(started)
    pings = sorted(victim.ping_times) or [float("inf")]
    return {
        "attacker": attacker.output().strip(),
        "attacker_exit": code,
        "attacked": attacked,
        "gap": gap,
        "gap_at": gap_at,
        "victims_own_stall": own_stall,
        "slowest_call": max(victim.call_times + victim.unanswered, default=float("inf")),
        "ping_p50": pings[len(pings) // 2],
        "ping_p95": pings[len(pings) * 95 // 100],
        "slowest_ping": pings[-1],
        "rss_growth": server.rss_mb() - rss_before,
        "peak_rss_growth": server.peak_rss_mb() - rss_before,
        "victim": victim,
    }


if __name__ == "__main__":
    url, abuse, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    if abuse in RAW_ABUSES:
        print(RAW_ABUSES[abuse](url, seconds), flush=True)
    else:
        print(asyncio.run(main(url, abuse, seconds)), flush=True)
