"""Hostile Foxglove WebSocket clients, one abuse each, run as a process of their own as hostile.py's are:

    python3 foxglove_hostile.py ws://127.0.0.1:PORT/ ABUSE SECONDS

Each abuse runs for at most SECONDS and the process exits, printing one line of what it did. The victims that
hostile.measure runs beside them: FoxgloveVictim (the pose through the Foxglove protocol, getParameters calls) and
BothVictims (it and a rosbridge hostile.Victim at once). The world they expect (test_foxglove_hostile.py's):
turtlesim, the demo camera, SLOW_SERVICE (a service that never answers) and BIG_ASSET (a 30 MB mesh)."""

import asyncio
import json
import struct
import sys
import threading
import time
from pathlib import Path

from tornado.websocket import websocket_connect

import hostile

SUBPROTOCOL = "foxglove.websocket.v1"
SLOW_SERVICE = "/foxglove_hostile/silent"
BIG_ASSET = Path(__file__).resolve().parents[1] / "test" / "artifacts" / "foxglove_hostile" / "big.stl"
BIG_ASSET_URI = "package://turtlesim/test/artifacts/foxglove_hostile/big.stl"
PARAMETERS = "/foxglove_hostile"  # where the abuses set parameters (the test deletes them)


def connect(url, recv_buffer=None):
    """A raw Foxglove connection (hostile.raw_connect), its handshake answer read."""
    sock = hostile.raw_connect(url, recv_buffer=recv_buffer, subprotocol=SUBPROTOCOL)
    answer = b""
    while b"\r\n\r\n" not in answer:
        chunk = sock.recv(1)  # (byte by byte: nothing after the handshake is taken)
        if not chunk:
            raise OSError("closed during the handshake")
        answer += chunk
    return sock


def text(obj):
    return hostile.raw_frame(json.dumps(obj).encode())


def binary(data):
    return hostile.raw_frame(data, opcode=0x2)


def read_all(sock):
    """Reads (and drops) what the bridge sends on a thread of its own, until the socket ends: a client that
    keeps up, so that its abuse goes on at full speed."""

    def run():
        try:
            while sock.recv(1 << 20):
                pass
        except OSError:
            pass

    threading.Thread(target=run, daemon=True).start()
    return sock


def until(end, send):
    """send() again and again until `end` (or the bridge closes the connection); how many times."""
    count = 0
    try:
        while time.monotonic() < end:
            send()
            count += 1
    except OSError:
        pass
    return count


class Scout:
    """A Foxglove client that learns the channels and services (their ids hold while a Foxglove client stays), and
    asks for parameters (request) and assets (fetch)."""

    def __init__(self, url):
        self.channels, self.services = {}, {}
        self._answers = {}  # request id -> the future of its parameterValues, or fetchAssetResponse
        self.ws = asyncio.run_coroutine_threadsafe(self._connect(url), _loop()).result(30)

    async def _connect(self, url):
        ws = await websocket_connect(url, subprotocols=[SUBPROTOCOL], max_message_size=64 << 20)
        deadline = time.monotonic() + 20
        while not (self.channels and self.services) and time.monotonic() < deadline:
            message = await asyncio.wait_for(ws.read_message(), 20)
            message = json.loads(message) if isinstance(message, str) else {}
            for channel in message.get("channels", ()) if message.get("op") == "advertise" else ():
                self.channels[channel["topic"]] = channel["id"]
            for service in message.get("services", ()) if message.get("op") == "advertiseServices" else ():
                self.services[service["name"]] = service["id"]
        asyncio.ensure_future(self._read(ws))
        return ws

    async def _read(self, ws):
        while (message := await ws.read_message()) is not None:
            if isinstance(message, bytes):
                if message[0] == 4 and (answer := self._answers.pop(struct.unpack_from("<I", message, 1)[0], None)):
                    answer.set_result(message)
                continue
            message = json.loads(message)
            if message.get("op") == "parameterValues" and message.get("id") in self._answers:
                self._answers.pop(message["id"]).set_result(message)
            elif message.get("op") == "status" and message["level"] == 2:
                for answer in self._answers.values():
                    answer.set_exception(AssertionError(message))
                self._answers.clear()

    def request(self, request, timeout=30):
        """Sends a request; the parameterValues that answers its id (AssertionError: an error status came first)."""
        return asyncio.run_coroutine_threadsafe(self._request(request), _loop()).result(timeout)

    def fetch(self, uri, request_id=1, timeout=30):
        """The bytes of an asset (AssertionError: the bridge refused it)."""
        request = {"op": "fetchAsset", "uri": uri, "requestId": request_id, "id": request_id}
        answer = asyncio.run_coroutine_threadsafe(self._request(request), _loop()).result(timeout)
        assert answer[5] == 0, answer[10:]
        return answer[10:]

    async def _request(self, request):
        answer = self._answers[request["id"]] = asyncio.get_running_loop().create_future()
        await self.ws.write_message(json.dumps(request))
        return await answer


_LOOP = []


def _loop():
    if not _LOOP:
        _LOOP.append(asyncio.new_event_loop())
        threading.Thread(target=_LOOP[0].run_forever, daemon=True).start()
    return _LOOP[0]


# ---- the abuses ------------------------------------------------------------------------------------------------
def wrong_lengths(url, seconds, scout):
    """Binary messages of every opcode (0-3, 255) at every length from 0 to 24 bytes, and service calls whose
    encoding length runs past their end, as fast as the bridge takes them."""
    burst = b"".join(binary(bytes([op]) + bytes(n)) for op in (0, 1, 2, 3, 255) for n in range(25))
    burst += b"".join(
        binary(b"\x02" + struct.pack("<III", 1, 7, length) + b"ros1") for length in (5, 100, 2**31, 2**32 - 1)
    )
    sock, end = read_all(connect(url)), time.monotonic() + seconds
    sent = until(end, lambda: sock.sendall(burst))
    return f"{sent * 129} binary messages of wrong lengths"


def subscribe_10k(url, seconds, scout):
    """A subscription to 10,000 channels (the graph's among them) and its unsubscribe, again and again."""
    ids = range(1, 10_001)
    pair = text({"op": "subscribe", "subscriptions": [{"id": i, "channelId": i} for i in ids]}) + text(
        {"op": "unsubscribe", "subscriptionIds": list(ids)}
    )
    sock, end = read_all(connect(url)), time.monotonic() + seconds
    return f"{until(end, lambda: sock.sendall(pair))} subscriptions to 10,000 channels"


def advertise_churn(url, seconds, scout):
    """200 client channels on new topics advertised then unadvertised, again and again."""
    sock, end, rounds = read_all(connect(url)), time.monotonic() + seconds, []

    def churn():
        first = len(rounds) * 200
        channels = [
            {"id": first + i, "topic": f"/hostile/c{first + i}", "encoding": "ros1", "schemaName": "std_msgs/String"}
            for i in range(200)
        ]
        sock.sendall(
            text({"op": "advertise", "channels": channels})
            + text({"op": "unadvertise", "channelIds": [c["id"] for c in channels]})
        )
        rounds.append(1)

    until(end, churn)
    return f"{len(rounds) * 200} client channels advertised and unadvertised"


def big_publishes(url, seconds, scout):
    """A new topic advertised, three messages of 7.9 MB published on it at once (nobody subscribes yet), again and
    again."""
    sock, end, topics = read_all(connect(url)), time.monotonic() + seconds, []
    data = struct.pack("<I", 7_900_000) + b"x" * 7_900_000  # (a std_msgs/String)

    def publish():
        channel = len(topics)
        advertise = {
            "id": channel,
            "topic": f"/hostile/big{channel}",
            "encoding": "ros1",
            "schemaName": "std_msgs/String",
        }
        sock.sendall(text({"op": "advertise", "channels": [advertise]}))
        for _ in range(3):
            sock.sendall(binary(b"\x01" + struct.pack("<I", channel) + data))
        topics.append(channel)

    until(end, publish)
    return f"{len(topics) * 3} messages of 7.9 MB published on {len(topics)} new topics"


BAD_ASSETS = [
    "package://no_such_package_{n}/mesh.stl",
    "package://turtlesim/../../../etc/passwd.stl",
    "package://turtlesim/%2e%2e/%2e%2e/etc/passwd.stl",
    "package://turtlesim/meshes/" + "x" * 5000 + ".stl",
    "file:///etc/passwd",
    "package://turtlesim/meshes/turtle_shell.stl",
]


def asset_flood(url, seconds, scout):
    """Four connections asking fetchAsset as fast as the bridge answers: packages that do not exist (a new name
    each time), paths out of the package, a huge name, another scheme, and a mesh."""
    end, counts = time.monotonic() + seconds, []

    def flood():
        sock, n = read_all(connect(url)), 0

        def ask():
            nonlocal n
            n += 1
            uri = BAD_ASSETS[n % len(BAD_ASSETS)].format(n=n)
            sock.sendall(text({"op": "fetchAsset", "uri": uri, "requestId": n}))

        counts.append(until(end, ask))

    threads = [threading.Thread(target=flood) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return f"{sum(counts)} fetchAsset requests on 4 connections"


def big_assets(url, seconds, scout):
    """Ten connections that never read, each fetching the 30 MB mesh four times at once."""
    socks = [connect(url, recv_buffer=4096) for _ in range(10)]
    for sock in socks:
        sock.sendall(b"".join(text({"op": "fetchAsset", "uri": BIG_ASSET_URI, "requestId": i}) for i in range(4)))
    time.sleep(seconds)
    return "40 fetches of a 30 MB mesh on 10 connections that never read"


def parameter_names(url, seconds, scout):
    """getParameters of 10,000 names, and a subscription to 10,000 more names, again and again."""
    sock, end, rounds = read_all(connect(url)), time.monotonic() + seconds, []
    names = [f"{PARAMETERS}/unset/p{i}" for i in range(10_000)]

    def ask():
        more = [f"{PARAMETERS}/watched/r{len(rounds)}/p{i}" for i in range(10_000)]
        sock.sendall(
            text({"op": "getParameters", "parameterNames": names, "id": str(len(rounds))})
            + text({"op": "subscribeParameterUpdates", "parameterNames": more})
        )
        rounds.append(1)

    until(end, ask)
    return f"{len(rounds)} getParameters of 10,000 names, and as many subscriptions to 10,000 names"


def huge_parameters(url, seconds, scout):
    """Four parameters of 7 MB set, a subscription to the updates of one small parameter, then getParameters of
    every parameter asked 100 times on a connection that never reads."""
    setter = read_all(connect(url))
    for i in range(4):
        value = {"name": f"{PARAMETERS}/huge{i}", "value": "H" * 7_000_000}
        setter.sendall(text({"op": "setParameters", "parameters": [value]}))
    setter.sendall(text({"op": "subscribeParameterUpdates", "parameterNames": ["/rosdistro"]}))
    time.sleep(1)
    sock = connect(url, recv_buffer=4096)
    sock.sendall(text({"op": "getParameters", "parameterNames": [], "id": "all"}) * 100)
    time.sleep(max(0.0, seconds - 1))
    return "4 parameters of 7 MB, getParameters of them all 100 times, never read"


def slow_calls(url, seconds, scout):
    """Connections one after another, each calling a service that never answers 20 times, then leaving."""
    service_id, end, connections = scout.services[SLOW_SERVICE], time.monotonic() + seconds, []
    calls = b"".join(binary(b"\x02" + struct.pack("<III", service_id, i, 4) + b"ros1") for i in range(20))

    def one():
        sock = connect(url)
        sock.sendall(calls)
        time.sleep(0.3)
        sock.close()
        connections.append(1)

    until(end, one)
    return f"{len(connections) * 20} calls of a silent service on {len(connections)} connections that left"


def camera_never_reads(url, seconds, scout):
    """Twenty connections subscribed to the camera that never read."""
    channel = scout.channels["/turtle_camera/image_raw"]
    socks = [connect(url, recv_buffer=4096) for _ in range(20)]
    for sock in socks:
        sock.sendall(text({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel}]}))
    time.sleep(seconds)
    return "20 camera subscriptions never read"


def connect_churn(url, seconds, scout):
    """Connects, reads the serverInfo, leaves; again and again."""

    def one():
        sock = connect(url)
        sock.recv(65536)
        sock.close()

    return f"{until(time.monotonic() + seconds, one)} connections"


WRONG = [None, True, -1, 2**32, 2**64, 1.5, "", "x", [], [1], {}, {"a": 1}, [None], [{}], "\ud800"]
REQUESTS = {
    "subscribe": {"subscriptions": [{"id": 1, "channelId": 1}]},
    "unsubscribe": {"subscriptionIds": [1]},
    "advertise": {
        "channels": [{"id": 1, "topic": "/hostile/fuzz", "encoding": "json", "schemaName": "std_msgs/String"}]
    },
    "unadvertise": {"channelIds": [1]},
    "getParameters": {"parameterNames": ["/rosdistro"], "id": "g"},
    "setParameters": {"parameters": [{"name": f"{PARAMETERS}/fuzz", "value": 1}], "id": "s"},
    "subscribeParameterUpdates": {"parameterNames": [f"{PARAMETERS}/fuzz"]},
    "unsubscribeParameterUpdates": {"parameterNames": [f"{PARAMETERS}/fuzz"]},
    "subscribeConnectionGraph": {},
    "unsubscribeConnectionGraph": {},
    "fetchAsset": {"uri": "package://turtlesim/meshes/turtle_shell.stl", "requestId": 1},
}


def wrongly_typed(value):
    """value with one field (at any depth) replaced by each WRONG value, or left out."""
    if isinstance(value, dict):
        for key, field in value.items():
            for wrong in WRONG:
                yield {**value, key: wrong}
            for changed in wrongly_typed(field):
                yield {**value, key: changed}
            yield {k: v for k, v in value.items() if k != key}
    elif isinstance(value, list):
        for i, item in enumerate(value):
            for changed in wrongly_typed(item):
                yield [*value[:i], changed, *value[i + 1 :]]


def wrong_types(url, seconds, scout):
    """Every request with each of its fields (at any depth) of every wrong type, or left out, and ops of every
    wrong type, again and again."""
    requests = [{"op": op, **changed} for op, body in REQUESTS.items() for changed in wrongly_typed(body)]
    requests += [{"op": wrong} for wrong in WRONG] + WRONG
    burst = b"".join(text(request) for request in requests)
    sock = read_all(connect(url))
    return f"{until(time.monotonic() + seconds, lambda: sock.sendall(burst)) * len(requests)} wrongly typed requests"


ABUSES = {
    f.__name__: f
    for f in (
        wrong_lengths,
        subscribe_10k,
        advertise_churn,
        big_publishes,
        asset_flood,
        big_assets,
        parameter_names,
        huge_parameters,
        slow_calls,
        camera_never_reads,
        connect_churn,
        wrong_types,
    )
}


# ---- the victims ---------------------------------------------------------------------------------------------
class FoxgloveVictim(hostile.Victim):
    """hostile.Victim through the Foxglove protocol: the pose's channel subscribed, getParameters for calls."""

    async def _open(self):
        ws = await websocket_connect(self.url, subprotocols=[SUBPROTOCOL])
        while True:
            message = json.loads(await ws.read_message())
            if message["op"] == "advertise":
                pose = [c["id"] for c in message["channels"] if c["topic"] == "/turtle1/pose"]
                if pose:
                    break
        await ws.write_message(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": pose[0]}]}))
        return ws

    def _heard(self, frame):
        if isinstance(frame, bytes):
            return hostile.POSE if frame[:5] == b"\x01\x01\x00\x00\x00" else None
        message = json.loads(frame)
        return int(message["id"]) if message.get("op") == "parameterValues" and "id" in message else None

    async def _ask(self, ws, n):
        await ws.write_message(json.dumps({"op": "getParameters", "parameterNames": ["/rosdistro"], "id": str(n)}))


class BothVictims:
    """A rosbridge hostile.Victim and a FoxgloveVictim at once, as one victim for hostile.measure: the worse of
    the two (each one's own in `victims`)."""

    def __init__(self, url, auth=None):
        self.victims = (hostile.Victim(url, auth), FoxgloveVictim(url))

    def __getattr__(self, name):  # (arrivals, call_times, ping_times, unanswered: both victims' together)
        return [value for victim in self.victims for value in getattr(victim, name)]

    def largest_gap(self, since):
        return max(victim.largest_gap(since) for victim in self.victims)

    def stop(self):
        for victim in self.victims:
            victim.stop()


if __name__ == "__main__":
    url, abuse, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    scout = Scout(url)  # (kept connected: the channels' ids hold)
    print(ABUSES[abuse](url, seconds, scout), flush=True)
