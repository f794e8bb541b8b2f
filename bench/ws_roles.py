"""Lean websocket clients for the benchmarks (Tornado's client; no ROS imports), one role per process. They speak
rosbridge, or with --protocol foxglove the Foxglove protocol (foxglove_protocol.py).

  publish    advertises a topic, then on cue sends `count` publish ops as fast as the socket takes them (Foxglove: a
             client channel's binary messages, the ROS bytes), or at --publish-rate; with --one-frame-per-write,
             from a blocking socket that masks and sends each frame by itself, as synchronous clients do
             (websocket-client, which roslibpy's users and scripts often use)
  subscribe  subscribes (optionally with compression) and counts the messages and bytes that arrive, and their age
             (arrival - an image's header stamp, or the send time of a Twist published with ros_roles.py --stamp)
  rtt        round trips: publishes pings at `rate` Hz and times the echoes coming back on another topic
  fanout     opens `clients` connections, all subscribed to one topic, and checks every one gets every message

Same protocol with bench/suite.py as bench/ros_roles.py: READY, a line on stdin as the cue, `RESULT <json>`."""

import argparse
import asyncio
import base64
import json
import os
import resource
import socket
import struct
import sys
import time

import cbor2
import foxglove_protocol
from tornado.util import _websocket_mask  # (the client's masking cost is not what is measured)
from tornado.websocket import websocket_connect

import payloads
import stats

MAX_FRAME = 64 << 20


def main():
    p = argparse.ArgumentParser()
    p.add_argument("role", choices=["publish", "subscribe", "rtt", "fanout"])
    p.add_argument("--url", required=True)
    p.add_argument("--topic", default="/bench/data")
    p.add_argument("--out", default="/bench/pong", help="rtt: the topic the echoes come back on")
    p.add_argument("--kind", default="twist", choices=sorted(payloads.TYPES))
    p.add_argument("--count", type=int, default=1000)
    p.add_argument("--rate", type=float, default=100.0, help="rtt: pings per second")
    p.add_argument("--publish-rate", type=float, default=0.0, help="publish: Hz; 0 = as fast as possible")
    p.add_argument("--compression", default="none", choices=["none", "png", "cbor", "cbor-raw"])
    p.add_argument(
        "--protocol",
        default="rosbridge",
        choices=["rosbridge", "foxglove"],
        help="subscribe, publish: rosbridge, or the Foxglove protocol (foxglove_protocol.py: the ROS bytes; to "
        "foxglove_bridge, the bridge or foxglove_ceiling.py)",
    )
    p.add_argument("--clients", type=int, default=1)
    p.add_argument("--idle", type=float, default=2.0)
    p.add_argument("--timeout", type=float, default=60.0)
    p.add_argument("--one-frame-per-write", action="store_true", help="publish: a blocking client, a send per frame")
    a = p.parse_args()
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    asyncio.run({"publish": publish, "subscribe": subscribe, "rtt": rtt, "fanout": fanout}[a.role](a))


def send(ws, op):
    return ws.write_message(json.dumps(op, separators=(",", ":")))


def decode(frame):
    """A frame from the bridge -> (op, msg or None, bytes on the wire). Binary frames are CBOR."""
    if isinstance(frame, bytes):
        op = cbor2.loads(frame)
        return op.get("op"), op.get("msg"), len(frame)
    op = json.loads(frame)
    if op.get("op") in ("png", "fragment"):  # one message in one or more parts: count it once, at its last part
        last = op.get("num", 0) == op.get("total", 1) - 1
        return (op["op"] if last else "part"), None, len(frame.encode())
    return op.get("op"), op.get("msg"), len(frame.encode())


async def publish(a):
    if a.one_frame_per_write:
        return publish_frame_by_frame(a)
    statuses = []
    if a.protocol == "foxglove":  # a client channel (encoding ros1): the message's ROS bytes in binary frames
        client = await foxglove_protocol.Client(lambda *_: None, statuses.append).connect(a.url)
        await client.advertise(a.topic, payloads.TYPES[a.kind])
        ws, frame = client.ws, foxglove_protocol.client_message(1, payloads.ros_bytes(a.kind))
    else:
        ws = await websocket_connect(a.url, max_message_size=MAX_FRAME)
        await send(ws, {"op": "advertise", "topic": a.topic, "type": payloads.TYPES[a.kind]})
        frame = payloads.publish_frame(a.kind, a.topic)
    binary = isinstance(frame, bytes)
    print("READY", flush=True)
    await stats.cue()
    period = 1.0 / a.publish_rate if a.publish_rate else 0.0
    start = time.monotonic()
    for i in range(a.count):
        await ws.write_message(frame, binary=binary)
        if period:
            await asyncio.sleep(max(0.0, start + (i + 1) * period - time.monotonic()))
    elapsed = time.monotonic() - start
    stats.result(sent=a.count, seconds=elapsed, frame_bytes=len(frame), statuses=[str(s)[:200] for s in statuses[:3]])
    await stats.cue()  # stay connected until the suite has counted (closing early could cut the bridge's backlog)
    ws.close()
    await asyncio.sleep(0.2)


def publish_frame_by_frame(a):
    """The publish role as a synchronous client: each frame masked with a fresh key and sent with its own
    sendall (no batching, no event loop), waiting for nothing from the server."""
    host, port = a.url.split("//")[1].rstrip("/").split(":")
    sock = socket.create_connection((host, int(port)))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode()
    )
    answer = b""
    while b"\r\n\r\n" not in answer:
        answer += sock.recv(4096)
    assert answer.startswith(b"HTTP/1.1 101"), answer

    def frame(text):
        data, mask = text.encode(), os.urandom(4)
        head = (
            struct.pack("!BB", 0x81, 0x80 | len(data))
            if len(data) < 126
            else struct.pack("!BBH", 0x81, 0x80 | 126, len(data))
        )
        return head + mask + _websocket_mask(mask, data)

    sock.sendall(frame(json.dumps({"op": "advertise", "topic": a.topic, "type": payloads.TYPES[a.kind]})))
    text = payloads.publish_frame(a.kind, a.topic)
    print("READY", flush=True)
    sys.stdin.readline()
    start = time.monotonic()
    for _ in range(a.count):
        sock.sendall(frame(text))
    elapsed = time.monotonic() - start
    stats.result(sent=a.count, seconds=elapsed, frame_bytes=len(text))
    sys.stdin.readline()
    sock.close()


async def subscribe(a):
    seen = stats.Arrivals()
    statuses, ages = [], []

    def message(msg, size, arrived):
        seen.add(payloads.seq_of(a.kind, msg) if a.kind != "string" else 0, size)
        stamp = payloads.stamp_of(a.kind, msg)
        if stamp:
            ages.append(arrived - stamp)

    def on_frame(frame):
        if frame is None:
            return
        arrived = time.time()
        op, msg, size = decode(frame)
        if op == "publish":
            message(msg, size, arrived)
        elif op in ("png", "fragment"):
            seen.add(0, size)
        elif op == "status":
            statuses.append(msg or frame)

    if a.protocol == "foxglove":
        ws = await foxglove_protocol.Client(
            lambda topic, payload, size, arrived: message(payload, size, arrived), statuses.append
        ).connect(a.url)
        await ws.subscribe([a.topic], timeout=a.timeout)
    else:
        ws = await websocket_connect(a.url, max_message_size=MAX_FRAME, on_message_callback=on_frame)
        await send(
            ws,
            {
                "op": "subscribe",
                "topic": a.topic,
                "type": payloads.TYPES[a.kind],
                "compression": a.compression,
                "queue_length": 0,
            },
        )
    print("READY", flush=True)
    deadline = time.monotonic() + a.timeout
    while seen.n < a.count and time.monotonic() < deadline:
        if seen.last is not None and time.monotonic() - seen.last > a.idle:
            break
        await asyncio.sleep(0.02)
    stats.result(
        **seen.summary(),
        statuses=[str(s)[:200] for s in statuses[:3]],
        age_p50=stats.percentile(ages, 0.5),
        age_p95=stats.percentile(ages, 0.95),
    )
    ws.close()


async def rtt(a):
    sent, rtts = {}, []
    echoed = asyncio.Event()

    def on_frame(frame):
        if frame is None:
            return
        op, msg, _ = decode(frame)
        if op != "publish":
            return
        seq = payloads.seq_of(a.kind, msg)
        if seq < 0:
            echoed.set()
        elif seq in sent:
            rtts.append(time.monotonic() - sent.pop(seq))

    ws = await websocket_connect(a.url, max_message_size=MAX_FRAME, on_message_callback=on_frame)
    ws.stream.set_nodelay(True)  # (a latency-minded client; rospy's tcp_nodelay in the baseline)
    ping_type = payloads.TYPES[a.kind]
    await send(ws, {"op": "subscribe", "topic": a.out, "type": ping_type})
    await send(ws, {"op": "advertise", "topic": a.topic, "type": ping_type})
    deadline = time.monotonic() + a.timeout
    while not echoed.is_set():  # until the whole path (bridge -> echo node -> bridge) is connected
        if time.monotonic() > deadline:
            raise SystemExit("no echo came back")
        await ws.write_message(payloads.publish_frame(a.kind, a.topic, -1))
        try:
            await asyncio.wait_for(echoed.wait(), 0.2)
        except TimeoutError:
            pass
    print("READY", flush=True)
    period = 1.0 / a.rate
    start = time.monotonic()
    for i in range(a.count):
        sent[i] = time.monotonic()
        await ws.write_message(payloads.publish_frame(a.kind, a.topic, i))
        await asyncio.sleep(max(0.0, start + (i + 1) * period - time.monotonic()))
    end = time.monotonic() + 3.0
    while sent and time.monotonic() < end:
        await asyncio.sleep(0.01)
    stats.result(**stats.latency_summary(rtts, a.count))
    ws.close()


async def fanout(a):
    """Every client must receive every sequence number 0..count-1 (the publisher sends -1 until all are live)."""
    received = [[] for _ in range(a.clients)]
    warm = [False] * a.clients
    closed = []

    def handler(i):
        def on_frame(frame):
            if frame is None:
                closed.append(i)
                return
            op, msg, _ = decode(frame)
            if op == "publish":
                seq = payloads.seq_of(a.kind, msg)
                if seq < 0:
                    warm[i] = True
                else:
                    received[i].append(seq)

        return on_frame

    sub = json.dumps({"op": "subscribe", "topic": a.topic, "type": payloads.TYPES[a.kind]})
    sockets = [None] * a.clients
    gate = asyncio.Semaphore(50)  # connect in parallel, but not all at once

    async def connect(i):
        async with gate:
            sockets[i] = await websocket_connect(a.url, on_message_callback=handler(i), connect_timeout=30)
            await sockets[i].write_message(sub)

    started = time.monotonic()
    await asyncio.gather(*(connect(i) for i in range(a.clients)))
    connect_seconds = time.monotonic() - started
    deadline = time.monotonic() + a.timeout
    while not all(warm):
        if time.monotonic() > deadline:
            raise SystemExit(f"only {sum(warm)} of {a.clients} clients got the topic")
        await asyncio.sleep(0.05)
    print("READY", flush=True)
    deadline = time.monotonic() + a.timeout
    while any(len(r) < a.count for r in received) and time.monotonic() < deadline:
        await asyncio.sleep(0.05)
    await asyncio.sleep(0.3)  # duplicates, if any, would arrive now
    expected = set(range(a.count))
    stats.result(
        clients=a.clients,
        connect_seconds=connect_seconds,
        expected=a.count * a.clients,
        delivered=sum(len(expected & set(r)) for r in received),
        duplicates=sum(len(r) - len(set(r)) for r in received),
        complete=sum(set(r) >= expected for r in received),
        closed=len(closed),
    )
    await stats.cue()  # hold the connections open while the suite reads the bridge's memory
    for ws in sockets:
        ws.close()
    await asyncio.sleep(0.5)


if __name__ == "__main__":
    main()
