"""The rover bench's ceiling: the bytes the bridge sends for each of the rover's streams, pushed at the stream's
rate over a bare Tornado websocket, with no ROS and no conversion. They are made once at start, by the bridge's
own encoders (rosbridge.protocol.encoded.TopicMessage: JSON, CBOR, cbor-raw, fragments) from the message nav_messages.py
builds, stamped with nav_messages.SENTINEL, and cut where the stamps are: a push only writes the time into a copy
of the frame. What no bridge over Tornado can beat, for each stream and encoding.

It speaks just enough of rosbridge v2 for nav_clients.py: {"op": "subscribe", "topic": T, "compression": "none" |
"cbor" | "cbor-raw", "fragment_size": N}; a latched stream (tf_static, the map) is sent once, as it is made.

Prints READY when it listens. Commands on stdin (answered by `RESULT <json>`): `count T0 T1`, how many messages of
each stream it pushed stamped in [T0, T1); `quit`."""

import argparse
import asyncio
import json
import re
import struct
import threading
import time

import genpy
import nav_messages
import tornado.web
import tornado.websocket

from rosbridge.protocol.encoded import SplicedFrame, TopicMessage, Utf8Text

import stats

SECS, NSECS = nav_messages.SENTINEL
_BIG_ENDIAN_UINT32 = b"\x1a"  # (CBOR's head of a 4-byte unsigned integer)
FILL = {  # a stamp's sentinel as each encoding writes it -> the same for a time (secs, nsecs)
    str(SECS).encode(): lambda secs, nsecs: str(secs).encode(),  # JSON
    str(NSECS).encode(): lambda secs, nsecs: str(nsecs).encode(),
    _BIG_ENDIAN_UINT32 + struct.pack(">I", SECS): lambda secs, nsecs: _BIG_ENDIAN_UINT32 + struct.pack(">I", secs),
    _BIG_ENDIAN_UINT32 + struct.pack(">I", NSECS): lambda secs, nsecs: _BIG_ENDIAN_UINT32 + struct.pack(">I", nsecs),
    nav_messages.SENTINEL_RAW: lambda secs, nsecs: struct.pack("<II", secs, nsecs),  # ROS bytes (cbor-raw)
}
_SENTINELS = re.compile(b"(" + b"|".join(re.escape(token) for token in FILL) + b")")


class Frames:
    """One stream's frames for one way of asking: [(pieces, text)], the pieces alternating bytes and the
    sentinel tokens to fill."""

    def __init__(self, stream, compression, fragment_size):
        msg = stream.build()
        data, places = nav_messages.sentinel_bytes(msg)
        made = TopicMessage(stream.topic, genpy.message.get_message_class(stream.type), data, time.time()).frames(
            compression, fragment_size
        )
        self.frames = [(_SENTINELS.split(bytes(frame)), _is_text(frame)) for frame in made]
        found = sum(len(pieces) // 2 for pieces, _ in self.frames)
        per_stamp = 1 if compression == "cbor-raw" else 2
        if stream.hz and found != per_stamp * len(places):
            raise ValueError(f"{stream.name} as {compression}: {found} sentinels, {per_stamp * len(places)} wanted")

    def stamped(self, now):
        secs = int(now)
        nsecs = int((now - secs) * 1e9)
        return [
            (b"".join(FILL[piece](secs, nsecs) if i % 2 else piece for i, piece in enumerate(pieces)), text)
            for pieces, text in self.frames
        ]

    def as_made(self):
        return [(b"".join(pieces), text) for pieces, text in self.frames]


def _is_text(frame):
    return isinstance(frame, Utf8Text) or (isinstance(frame, SplicedFrame) and frame.text)


class Ceiling(tornado.websocket.WebSocketHandler):
    frames = {}  # (stream, compression, fragment_size) -> Frames, made at start
    pushed = {stream.name: [] for stream in nav_messages.STREAMS}  # the stamps of what was pushed

    def open(self):
        self.set_nodelay(True)  # (as the bridge does)
        self.tasks = []

    def on_message(self, frame):
        op = json.loads(frame)
        if op.get("op") != "subscribe" or op.get("topic") not in nav_messages.BY_TOPIC:
            return
        stream = nav_messages.BY_TOPIC[op["topic"]]
        frames = Ceiling.frames[(stream.name, op.get("compression") or "none", op.get("fragment_size"))]
        self.tasks.append(asyncio.ensure_future(self.push(stream, frames)))

    async def push(self, stream, frames):
        if not stream.hz:
            for data, text in frames.as_made():
                await self.write_message(data, binary=not text)
            return
        loop = asyncio.get_running_loop()
        period, due = 1.0 / stream.hz, loop.time()
        while True:
            due = max(due + period, loop.time() - period)
            await asyncio.sleep(max(0.0, due - loop.time()))
            now = time.time()
            try:
                for data, text in frames.stamped(now):
                    await self.write_message(data, binary=not text)
            except tornado.websocket.WebSocketClosedError:
                return
            Ceiling.pushed[stream.name].append(now)

    def on_close(self):
        for task in self.tasks:
            task.cancel()


def ways(streams):
    """The ways nav_bench.py asks for each stream: JSON, CBOR, cbor-raw; the map also in fragments."""
    for stream in streams:
        for compression in ("none", "cbor", "cbor-raw"):
            yield stream, compression, None
        if stream.name == "map":
            yield stream, "none", 100_000


async def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--streams", nargs="+", default=list(nav_messages.BY_NAME), choices=list(nav_messages.BY_NAME))
    a = p.parse_args()
    for stream, compression, fragment_size in ways(nav_messages.BY_NAME[name] for name in a.streams):
        Ceiling.frames[(stream.name, compression, fragment_size)] = Frames(stream, compression, fragment_size)
    tornado.web.Application([("/", Ceiling)], websocket_max_message_size=64 << 20).listen(a.port, "127.0.0.1")
    loop = asyncio.get_running_loop()
    done = loop.create_future()

    def serve():
        stats.commands(
            {
                "count": lambda t0, t1: {
                    name: stats.count_between(list(stamps), float(t0), float(t1))
                    for name, stamps in Ceiling.pushed.items()
                }
            }
        )
        loop.call_soon_threadsafe(lambda: done.done() or done.set_result(None))

    print("READY", flush=True)
    threading.Thread(target=serve, daemon=True).start()
    await done


if __name__ == "__main__":
    asyncio.run(main())
