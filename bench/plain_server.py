"""The bad-link benchmark's plain baseline (bench/badlink.py): a bare Tornado websocket server over rospy that
forwards every message of the topics a client subscribes to, at once, skipping nothing and queueing without
bound (Tornado's write buffer), as a naive bridge does. It speaks just enough of the rosbridge protocol for the
bench's clients:

  {"op": "subscribe", "topic": ..., "compression": "none" | "cbor" | "jpeg"}
      none: rosbridge JSON publish ops (an image's data as base64); cbor: the same op as CBOR (binary frames);
      jpeg: (sensor_msgs/Image only) each frame as JPEG at quality 50, encoded once per frame with Pillow and
      sent as a binary frame of its own: what rosboard does (it also cuts to 800 px a side, which a 640x480
      picture is within), with no per-client queue and no adapting

throttle_rate and queue_length are ignored: this is the server that keeps nothing back. `/` serves a minimal
page that shows the camera as JPEG in an <img> and the small topic's value as text, for the headless browser:
the console's baseline (rosboard's way of showing a camera). The websocket is at /ws.

Prints READY when it listens."""

import argparse
import asyncio
import base64
import io
import json
import threading

import cbor2
import rospy
import tornado.web
import tornado.websocket
from PIL import Image as PILImage
from sensor_msgs.msg import Image
from std_msgs.msg import Float64

PAGE = """<!doctype html>
<html><head><meta charset="utf-8"><title>plain camera page</title><link rel="icon" href="data:,"></head>
<body style="margin:0;padding:12px;background:#141a2e;color:#eee;font:15px sans-serif">
<h1 style="font-size:18px">plain baseline: JPEG q50, every frame (rosboard's way)</h1>
<img id="camera" alt="camera" style="width:640px;height:480px;background:#000">
<p>%(small)s: <span id="small">waiting</span></p>
<script>
const ws = new WebSocket(`ws://${location.host}/ws`);
ws.binaryType = 'blob';
const img = document.getElementById('camera'), small = document.getElementById('small');
let shown = null;
ws.onopen = () => {
  ws.send(JSON.stringify({op: 'subscribe', topic: '%(camera)s', compression: 'jpeg'}));
  ws.send(JSON.stringify({op: 'subscribe', topic: '%(small)s'}));
};
ws.onmessage = event => {
  if (typeof event.data !== 'string') {
    const url = URL.createObjectURL(event.data);
    img.onload = () => { if (shown) URL.revokeObjectURL(shown); shown = url; };
    img.src = url;
  } else {
    small.textContent = `data: ${JSON.parse(event.data).msg.data}`;
  }
};
</script></body></html>"""


class Forwarder(tornado.websocket.WebSocketHandler):
    clients = set()

    def check_origin(self, origin):
        return True

    def open(self):
        self.topics = {}  # topic -> compression
        self.set_nodelay(True)
        Forwarder.clients.add(self)

    def on_message(self, frame):
        op = json.loads(frame)
        if op.get("op") == "subscribe":
            self.topics[op["topic"]] = op.get("compression") or "none"
        elif op.get("op") == "unsubscribe":
            self.topics.pop(op["topic"], None)

    def on_close(self):
        Forwarder.clients.discard(self)


class Page(tornado.web.RequestHandler):
    def initialize(self, html):
        self.html = html

    def get(self):
        self.set_header("Content-Type", "text/html; charset=utf-8")
        self.write(self.html)


def as_dict(msg):
    if isinstance(msg, Float64):
        return {"data": msg.data}
    h = msg.header
    return {
        "header": {"seq": h.seq, "stamp": {"secs": h.stamp.secs, "nsecs": h.stamp.nsecs}, "frame_id": h.frame_id},
        "height": msg.height,
        "width": msg.width,
        "encoding": msg.encoding,
        "is_bigendian": msg.is_bigendian,
        "step": msg.step,
        "data": msg.data,
    }


def encode(topic, msg, compression):
    """One message for every client that asked for it this way: (frame, binary)."""
    if compression == "jpeg" and isinstance(msg, Image):
        out = io.BytesIO()
        PILImage.frombytes("RGB", (msg.width, msg.height), msg.data).save(out, "JPEG", quality=50)
        return out.getvalue(), True
    body = as_dict(msg)
    if compression == "cbor":
        return cbor2.dumps({"op": "publish", "topic": topic, "msg": body}), True
    if "data" in body and isinstance(body["data"], bytes):
        body["data"] = base64.b64encode(body["data"]).decode()
    return json.dumps({"op": "publish", "topic": topic, "msg": body}, separators=(",", ":")), False


def forward(loop, topic):
    """A rospy callback (rospy's thread): encode once per way asked for, then write to each client (the loop)."""

    def received(msg):
        wanted = {ws.topics[topic] for ws in list(Forwarder.clients) if topic in ws.topics}
        frames = {c: encode(topic, msg, c) for c in wanted}
        loop.add_callback(send, topic, frames)

    return received


def send(topic, frames):
    for ws in list(Forwarder.clients):
        compression = ws.topics.get(topic)
        if compression in frames:
            frame, binary = frames[compression]
            try:
                ws.write_message(frame, binary=binary)  # (not awaited: Tornado buffers whatever the link holds up)
            except tornado.websocket.WebSocketClosedError:
                pass


async def main():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--address", default="127.0.0.1")
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--small", default="/rover/stamp")
    p.add_argument("--camera", default="/rover/camera")
    a = p.parse_args()
    rospy.init_node("plain_server", anonymous=True, disable_signals=True)
    loop = tornado.ioloop.IOLoop.current()
    rospy.Subscriber(a.small, Float64, forward(loop, a.small), queue_size=None)
    rospy.Subscriber(a.camera, Image, forward(loop, a.camera), queue_size=None, buff_size=1 << 24)
    app = tornado.web.Application(
        [("/", Page, {"html": PAGE % {"small": a.small, "camera": a.camera}}), ("/ws", Forwarder)],
        websocket_max_message_size=64 << 20,
    )
    app.listen(a.port, a.address)
    print("READY", flush=True)
    await asyncio.Event().wait()


if __name__ == "__main__":
    threading.current_thread().name = "plain_server"
    asyncio.run(main())
