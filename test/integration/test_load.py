"""The bridge under many clients (loopback only): a thousand websocket clients connecting, subscribing,
publishing and leaving (half of them cleanly, half by dropping the connection) must leave no trace: no
growth in the bridge's threads or ROS registrations, memory within a bound, /client_count back to 0."""

import asyncio
import json
import threading

import pytest
from tornado.websocket import websocket_connect

from fixtures import bridge_fixture
from harness import ProcStat, node_pid, wait_for

pytestmark = pytest.mark.slow  # (deselect with -m 'not slow' for a quick run)

CLIENTS_PER_ROUND = 250
load_bridge = bridge_fixture("bridge_load", scope="function", yields="bridge", unregister_timeout=1)


def registrations(ros, node_name):
    """(topic, role) pairs the bridge node holds at the master, apart from the ones it always has."""
    pubs, subs, _ = ros.master().getSystemState()
    held = {(t, "pub") for t, nodes in pubs if node_name in nodes} | {
        (t, "sub") for t, nodes in subs if node_name in nodes
    }
    return {r for r in held if r[0].startswith("/load/")}


async def crowd(url, n):
    """n clients connect (50 at a time); each subscribes to /load/tick, publishes once on one of ten /load/cmd
    topics, waits for a tick; then half close cleanly and half drop their TCP connection."""
    gate = asyncio.Semaphore(50)

    async def one(i):
        async with gate:
            ws = await websocket_connect(url, connect_timeout=60)
            await ws.write_message(json.dumps({"op": "subscribe", "topic": "/load/tick", "type": "std_msgs/Int32"}))
            await ws.write_message(
                json.dumps({"op": "advertise", "topic": f"/load/cmd{i % 10}", "type": "std_msgs/Int32"})
            )
            await ws.write_message(json.dumps({"op": "publish", "topic": f"/load/cmd{i % 10}", "msg": {"data": i}}))
        while True:
            frame = await asyncio.wait_for(ws.read_message(), 60)
            assert frame is not None, f"client {i} was disconnected"
            if json.loads(frame).get("topic") == "/load/tick":
                break
        return ws

    sockets = await asyncio.gather(*(one(i) for i in range(n)))
    for i, ws in enumerate(sockets):
        if i % 2:
            ws.close()
        else:
            ws.stream.close()  # no close handshake: a client that vanished
    await asyncio.sleep(0.5)


def test_a_thousand_clients_coming_and_going_leave_no_trace(ros, node, load_bridge):
    from std_msgs.msg import Int32

    proc, port = load_bridge.proc, load_bridge.port
    tick = node.Publisher("/load/tick", Int32, queue_size=10)
    stop = threading.Event()

    def ticking():  # 20 Hz, so every new subscriber soon gets one
        while not stop.wait(0.05):
            tick.publish(Int32(1))

    threading.Thread(target=ticking, daemon=True).start()
    counts = []
    count_sub = node.Subscriber("/client_count", Int32, lambda m: counts.append(m.data))
    loop = asyncio.new_event_loop()
    try:
        pid = node_pid(ros, "/bridge_load")
        url = f"ws://127.0.0.1:{port}/"

        def round_of_clients():
            loop.run_until_complete(crowd(url, CLIENTS_PER_ROUND))
            wait_for(lambda: counts and counts[-1] == 0, 30, what="/client_count back to 0")
            wait_for(
                lambda: not registrations(ros, "/bridge_load"),
                30,
                what="the bridge to drop the clients' topics at the master",
            )

        round_of_clients()  # warm-up: the allocator and the thread pools reach their working size
        baseline_rss, baseline_threads = ProcStat(pid).rss_mb(), ProcStat(pid).threads()
        for _ in range(1000 // CLIENTS_PER_ROUND):
            round_of_clients()

        assert ProcStat(pid).threads() <= baseline_threads
        grown = ProcStat(pid).rss_mb() - baseline_rss
        assert grown < 15, f"bridge RSS grew {grown:.1f} MB over 1000 clients that came and went"
        assert proc.alive()
    finally:
        stop.set()
        loop.close()
        count_sub.unregister()
        tick.unregister()
