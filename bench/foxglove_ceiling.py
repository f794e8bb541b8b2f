"""The ceiling of the bridge's Foxglove path: the same TCPROS bytes read and written to websocket clients as
Foxglove message data, and nothing else. What no Python server over Tornado that forwards them can beat.

- Reading: one TCPROS connection to the topic's publisher (bare_tcpros.py: no ROS node, no rospy objects), read
  on the Tornado loop as the bridge reads its publishers: a non-blocking socket the loop watches, the bridge's own
  framing (rosbridge.ros_side.tcpros.FrameReader: a big message read straight into its own buffer) and pace
  (read_pace.ReadPace: a publisher that keeps sending faster than 2000 msg/s is read once a millisecond).
- Writing: each read's messages to every subscribed client, each in one binary websocket frame (the 13-byte head:
  opcode, subscription id, receive time; then the bytes as they came), the small ones of a read joined into one
  send, a big one's bytes by reference, straight to the socket while nothing waits unsent (as the bridge's
  transport writes).
- The websocket: the handshake answered here on Tornado's HTTP server (rfc6455's accept key and frame heads, the
  bridge's), `foxglove.websocket.v1` only; serverInfo and the topic's one channel advertised; `subscribe` taken,
  every other request ignored. No outbox, no bounds, no graph, parameters or services.

Prints READY when it listens; it connects to the publisher as soon as the master knows one. Runs until stopped."""

import argparse
import asyncio
import json
import struct
import time

import bare_tcpros
import foxglove_protocol
import genpy
import tornado.ioloop
import tornado.iostream
import tornado.web

from rosbridge.codec import BIG_BYTES
from rosbridge.ros_side import tcpros
from rosbridge.ros_side.read_pace import ReadPace
from rosbridge.transport import rfc6455 as ws

import payloads

CHANNEL = 1  # the one channel's id
READ_CHUNK = 1 << 16  # bytes read from the publisher at once (the bridge's links.READ_CHUNK)
_HEAD = struct.Struct("<BIQ")  # opcode, subscription id, receive time (ns)


class Client:
    """One websocket client after the handshake: its stream, and its subscription to the channel (None: none)."""

    subscribed = set()

    def __init__(self, stream):
        self.stream, self.subscription = stream, None

    async def serve(self):
        """Reads the client's frames until it closes: a subscription to the channel makes it a receiver."""
        reader = ws.FrameReader(1 << 20)
        try:
            while True:
                reader.receive(await self.stream.read_bytes(READ_CHUNK, partial=True))
                while (event := reader.next_event()) is not None:
                    opcode, payload, _ = event
                    if opcode == ws.CLOSE:
                        return
                    if opcode == ws.TEXT:
                        self.request(json.loads(payload))
        except (tornado.iostream.StreamClosedError, ws.ProtocolError):
            pass
        finally:
            Client.subscribed.discard(self)
            self.stream.close()

    def request(self, op):
        if op.get("op") == "subscribe":
            for entry in op["subscriptions"]:
                if entry["channelId"] == CHANNEL:
                    self.subscription = entry["id"]
                    Client.subscribed.add(self)

    def send_messages(self, messages, receive_ns):
        head = _HEAD.pack(foxglove_protocol.MESSAGE_DATA, self.subscription, receive_ns)
        joined = []
        for data in messages:
            joined += (ws.frame_header(len(head) + len(data), ws.BINARY), head)
            if len(data) < BIG_BYTES:
                joined.append(data)
            else:
                self.send(b"".join(joined))
                joined.clear()
                self.send(data)
        if joined:
            self.send(b"".join(joined))

    def send(self, data):
        """To the socket at once while the stream holds nothing unsent; the rest through the stream."""
        stream = self.stream
        if stream.closed():
            return
        if not stream.writing():
            try:
                sent = stream.socket.send(data)
            except BlockingIOError:
                sent = 0
            except OSError:
                return
            if sent == len(data):
                return
            data = memoryview(data)[sent:]
        stream.write(data).add_done_callback(lambda written: written.exception())


class Handshake(tornado.web.RequestHandler):
    """GET /: the websocket handshake of a Foxglove client; then its Client."""

    def initialize(self, greeting):
        self.greeting = greeting

    def get(self):
        headers = self.request.headers
        offered = [name.strip() for name in headers.get("Sec-WebSocket-Protocol", "").split(",")]
        if ws.handshake_error(headers) or foxglove_protocol.SUBPROTOCOL not in offered:
            raise tornado.web.HTTPError(400)
        answer = (
            "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Accept: {ws.accept_key(headers['Sec-WebSocket-Key'])}\r\n"
            f"Sec-WebSocket-Protocol: {foxglove_protocol.SUBPROTOCOL}\r\n\r\n"
        )
        stream = self.detach()
        stream.set_nodelay(True)  # (as the bridge does: small frames go out at once)
        client = Client(stream)
        client.send(answer.encode() + self.greeting)
        asyncio.ensure_future(client.serve())


class Reader:
    """The publisher's socket on the loop: each read's complete messages go to every subscribed client."""

    def __init__(self, sock):
        self.sock, self.loop = sock, tornado.ioloop.IOLoop.current()
        self.frames, self.pace = tcpros.FrameReader(), ReadPace()
        sock.setblocking(False)
        self.loop.add_handler(sock, self.read, self.loop.READ)

    def read(self, fd=None, events=None):
        # (the bridge's read, links.InboundLink._on_events, which lives in a rospy Transport: written again)
        space = self.frames.into()
        try:
            if space is not None:  # the rest of a big message: straight into its buffer
                count = self.sock.recv_into(space)
            else:
                chunk = self.sock.recv(READ_CHUNK)
                count = len(chunk)
        except BlockingIOError:
            count = None
        finally:
            if space is not None:
                space.release()
        if count == 0:  # the publisher left
            self.loop.remove_handler(self.sock)
            return
        messages = []
        if count:
            messages = self.frames.received(count) if space is not None else self.frames.feed(chunk)
        if messages:
            receive_ns = time.time_ns()
            for client in list(Client.subscribed):
                client.send_messages(messages, receive_ns)
        polling, more = self.pace.polling, bool(count) and (space is not None or count == READ_CHUNK)
        wait = self.pace.after_read(time.monotonic(), len(messages), more)
        if wait is not None:
            if not polling:
                self.loop.update_handler(self.sock, 0)
            self.loop.call_later(wait, self.read)
        elif polling:
            self.loop.update_handler(self.sock, self.loop.READ)


def greeting(topic, cls):
    """serverInfo and the advertisement of the topic's channel, as text frames."""
    ops = (
        {"op": "serverInfo", "name": "foxglove_ceiling", "capabilities": [], "supportedEncodings": []},
        {
            "op": "advertise",
            "channels": [
                {
                    "id": CHANNEL,
                    "topic": topic,
                    "encoding": "ros1",
                    "schemaName": cls._type,
                    "schema": cls._full_text,
                    "schemaEncoding": "ros1msg",
                }
            ],
        },
    )
    texts = [json.dumps(op).encode() for op in ops]
    return b"".join(ws.frame_header(len(text), ws.TEXT) + text for text in texts)


async def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--topic", required=True)
    p.add_argument("--kind", default="twist", choices=sorted(payloads.TYPES))
    p.add_argument("--timeout", type=float, default=60.0, help="s to wait for the topic's publisher")
    a = p.parse_args()
    cls = genpy.message.get_message_class(payloads.TYPES[a.kind])
    app = tornado.web.Application([("/", Handshake, {"greeting": greeting(a.topic, cls)})])
    app.listen(a.port, "127.0.0.1")
    print("READY", flush=True)
    loop = asyncio.get_running_loop()
    sock = await loop.run_in_executor(None, bare_tcpros.subscribe, a.topic, cls, "/foxglove_ceiling", a.timeout)
    Reader(sock)
    await asyncio.Event().wait()


if __name__ == "__main__":
    asyncio.run(main())
