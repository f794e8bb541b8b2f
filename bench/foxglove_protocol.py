"""A small client of the Foxglove WebSocket protocol (`foxglove.websocket.v1`), for the benchmarks that measure
foxglove_bridge (bench/peers.py starts it), the bridge's own Foxglove path (src/rosbridge/foxglove/, on the
bridge's port) and their ceiling (foxglove_ceiling.py) beside each other. The server sends `serverInfo`, then
`advertise`s its channels (id, topic, encoding `ros1`, schemaName, schema), and new ones as topics appear (the
master polled every few seconds by foxglove_bridge, twice a second by the bridge); a client subscribes with
{"op": "subscribe", "subscriptions": [{"id": N, "channelId": C}]} and gets each message as a binary frame: opcode
0x01, the subscription id (u32 LE), the receive time (u64 LE, ns), the message's ROS 1 bytes. A client publishes
by advertising a channel of its own ({"op": "advertise", "channels": [{"id": N, "topic", "encoding": "ros1",
"schemaName"}]}), then sending binary frames: opcode 0x01, the channel id (u32 LE), the message's ROS 1 bytes."""

import asyncio
import json
import struct
import time

SUBPROTOCOL = "foxglove.websocket.v1"
MESSAGE_DATA = 0x01
_HEAD = struct.Struct("<BIQ")
_CLIENT_HEAD = struct.Struct("<BI")  # a client's message: opcode 0x01, its channel id


def message_data(frame):
    """A binary frame -> (subscription id, receive time in ns, the message's ROS bytes as a memoryview), or None
    if it is not a message."""
    if len(frame) < _HEAD.size or frame[0] != MESSAGE_DATA:
        return None
    _, subscription, receive_ns = _HEAD.unpack_from(frame)
    return subscription, receive_ns, memoryview(frame)[_HEAD.size :]


def client_message(channel_id, payload):
    """A client's message on its channel `channel_id`: the binary frame, payload its ROS 1 bytes."""
    return _CLIENT_HEAD.pack(MESSAGE_DATA, channel_id) + payload


class Client:
    """One connection. on_message(topic, payload, frame_bytes, arrived) is called for each message of a topic it
    subscribed to (arrived: time.time() when the frame was read); the text ops that say something (status ...,
    not the advertisements and the server's info) go to on_text(op)."""

    def __init__(self, on_message, on_text=lambda op: None):
        self.on_message, self.on_text = on_message, on_text
        self.channels = {}  # topic -> channel id, as advertised
        self.advertised = asyncio.Event()
        self.topic_of = {}  # subscription id -> topic
        self.ws = None

    async def connect(self, url, timeout=30):
        from tornado.websocket import websocket_connect

        self.ws = await websocket_connect(
            url,
            subprotocols=[SUBPROTOCOL],
            max_message_size=64 << 20,
            on_message_callback=self._frame,
            connect_timeout=timeout,
        )
        return self

    def _frame(self, frame):
        arrived = time.time()
        if frame is None:
            self.on_text({"op": "closed"})
        elif isinstance(frame, bytes):
            found = message_data(frame)
            if found and found[0] in self.topic_of:
                self.on_message(self.topic_of[found[0]], found[2], len(frame), arrived)
        else:
            op = json.loads(frame)
            if op.get("op") == "advertise":
                self.channels.update({channel["topic"]: channel["id"] for channel in op["channels"]})
                self.advertised.set()
            elif op.get("op") == "unadvertise":
                gone = set(op.get("channelIds", []))
                self.channels = {t: c for t, c in self.channels.items() if c not in gone}
            elif op.get("op") not in ("serverInfo", "advertiseServices", "unadvertiseServices"):
                self.on_text(op)

    async def subscribe(self, topics, timeout=30):
        """Subscribes to each topic once the server advertises it (it learns new topics by polling the master)."""
        deadline = time.monotonic() + timeout
        while not all(topic in self.channels for topic in topics):
            if time.monotonic() > deadline:
                missing = [t for t in topics if t not in self.channels]
                raise TimeoutError(f"foxglove_bridge did not advertise {missing} in {timeout} s")
            self.advertised.clear()
            try:
                await asyncio.wait_for(self.advertised.wait(), 1.0)
            except TimeoutError:
                pass
        subscriptions = []
        for topic in topics:
            subscription = len(self.topic_of) + 1
            self.topic_of[subscription] = topic
            subscriptions.append({"id": subscription, "channelId": self.channels[topic]})
        await self.ws.write_message(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))

    async def advertise(self, topic, schema_name, channel_id=1):
        """Advertises a client channel (encoding ros1) to publish on with client_message(channel_id, ...)."""
        channel = {"id": channel_id, "topic": topic, "encoding": "ros1", "schemaName": schema_name}
        await self.ws.write_message(json.dumps({"op": "advertise", "channels": [channel]}))

    def close(self):
        if self.ws is not None:
            self.ws.close()
