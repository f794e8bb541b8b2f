"""The transport ceiling: a bare Tornado websocket server that does the least any JSON-over-websocket bridge
must do (parse each incoming frame, JSON-encode each outgoing message) and nothing else - no ROS.

It speaks just enough of the rosbridge protocol for the bench clients in ws_roles.py:
  publish    counted (the count is reported when the connection closes) and echoed back to its sender; with
             `--forward`, also written to a plain TCP reader (tcp_sink.py) as a TCPROS-sized frame: the least a
             bridge to ROS adds, one send per message to a subscriber's socket
  subscribe  the connection gets the pushed messages: on a line on stdin, `--count` publish ops of `--kind`
             (sequence numbers 0..count-1), as fast as each socket takes them, or at `--rate` Hz; JSON text, or
             CBOR with `--cbor` (each message encoded for each push, as a bridge must)"""

import argparse
import asyncio
import json
import socket
import struct

import tornado.web
import tornado.websocket

import payloads
import stats

# what a bridge writes to a ROS subscriber for one Twist: the 4-byte length, then 6 float64s
TWIST_FRAME = struct.pack("<I", 48) + bytes(48)


class Bench(tornado.websocket.WebSocketHandler):
    subscribers = set()
    echo = True
    sink = None  # the socket of tcp_sink.py with --forward

    def open(self):
        self.seen = stats.Arrivals()
        self.set_nodelay(True)  # as the bridge does: small frames go out at once

    def on_message(self, frame):
        op = json.loads(frame)
        if op.get("op") == "publish":
            self.seen.add(0)
            if Bench.sink is not None:
                Bench.sink.send(TWIST_FRAME)
            if Bench.echo:
                self.write_message(frame)
        elif op.get("op") == "subscribe":
            Bench.subscribers.add(self)
            print("SUBSCRIBED", flush=True)

    def on_close(self):
        Bench.subscribers.discard(self)
        if self.seen.n:
            stats.result(**self.seen.summary())


async def push(a):
    await stats.cue()
    period = 1.0 / a.rate if a.rate else 0.0
    loop = asyncio.get_running_loop()
    start = loop.time()
    for seq in range(a.count):
        if a.cbor:
            frame = payloads.cbor_frame(a.kind, "/bench/data", seq)
        else:
            frame = payloads.publish_frame(a.kind, "/bench/data", seq)
        writes = [ws.write_message(frame, binary=a.cbor) for ws in list(Bench.subscribers)]
        for w in writes:
            try:
                await w
            except tornado.websocket.WebSocketClosedError:
                pass
        if period:
            await asyncio.sleep(max(0.0, start + (seq + 1) * period - loop.time()))


async def main():
    p = argparse.ArgumentParser()
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--kind", default="twist", choices=sorted(payloads.TYPES))
    p.add_argument("--count", type=int, default=1000)
    p.add_argument("--rate", type=float, default=0.0)
    p.add_argument("--cbor", action="store_true", help="push CBOR (binary) frames instead of JSON text")
    p.add_argument("--no-echo", action="store_true", help="count published frames without echoing them")
    p.add_argument("--forward", type=int, metavar="PORT", help="write each published message to tcp_sink.py there")
    a = p.parse_args()
    Bench.echo = not a.no_echo
    if a.forward:
        Bench.sink = socket.create_connection(("127.0.0.1", a.forward))
    tornado.web.Application([("/", Bench)], websocket_max_message_size=64 << 20).listen(a.port, "127.0.0.1")
    print("READY", flush=True)
    await push(a)
    await asyncio.Event().wait()


if __name__ == "__main__":
    asyncio.run(main())
