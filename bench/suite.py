"""The benchmark suite: runs every measurement `--rounds` times against baselines measured in the same run,
prints a markdown table of medians and writes bench/README.md. Start it with `bash bench/run`."""

import argparse
import itertools
import json
import os
import re
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BENCH = Path(__file__).resolve().parent
REPO = BENCH.parent
sys.path.insert(0, str(REPO / "testkit"))
import harness  # noqa: E402  (the tests' process tools, testkit/: private roscore, process groups, logs)
import hostile  # noqa: E402  (testkit/: the isolation tests' hostile clients and their victim)
import payloads  # noqa: E402
import peers  # noqa: E402
import reporting  # noqa: E402
import stats  # noqa: E402

PY = "/usr/bin/python3"


class Run:
    """One suite run: a private roscore and helpers to start roles and read their results."""

    def __init__(self, workdir, peer_args):
        self.workdir = Path(workdir)
        self.peers = peer_args  # (bench/peers.py: where the other bridges are)
        self.foxglove_missing = peers.foxglove_missing(peer_args)
        self.ros = harness.RosMaster(self.workdir).start()
        # (testkit/ for the messages the tests publish too: testkit/sensor_messages.py)
        self.ros.env["PYTHONPATH"] = f"{BENCH}:{REPO / 'testkit'}:{self.ros.env.get('PYTHONPATH', '')}"
        self.topics = 0
        self.spawned = 0

    def topic(self, stem):
        """A fresh topic name per measurement, so no publisher or latched message of an earlier one interferes."""
        self.topics += 1
        return f"/bench/{stem}{self.topics}"

    def role(self, script, *args, name=None, env=None):
        """Starts one bench role (ros_roles.py / ws_roles.py / transport_server.py); stdin is its cue."""
        self.spawned += 1  # (log files are named by this count: harness's own count shrinks as we stop procs)
        return self.ros.spawn(
            [PY, str(BENCH / script), *map(str, args)],
            f"{name or script.split('.')[0]}-{self.spawned}",
            env=env,
            stdin=subprocess.PIPE,
        )

    @staticmethod
    def ready(proc, timeout=30):
        harness.wait_for(lambda: "READY" in proc.output() or not proc.alive(), timeout, what=f"{proc.args} READY")
        if "READY" not in proc.output():
            raise RuntimeError(f"{proc.args[2:4]} failed:\n{proc.output()[-2000:]}")

    @staticmethod
    def go(proc):
        proc.popen.stdin.write(b"go\n")
        proc.popen.stdin.flush()

    @staticmethod
    def result(proc, timeout=120):
        def found():
            return re.findall(r"^RESULT (.*)$", proc.output(), re.M) or (not proc.alive() and ["dead"])

        last = harness.wait_for(found, timeout, what=f"RESULT of {proc.args[2:4]}")[-1]
        if last == "dead":
            raise RuntimeError(f"{proc.args[2:4]} died:\n{proc.output()[-2000:]}")
        return json.loads(last)

    def stop(self, *procs):
        for p in procs:
            p.stop()
            if p in self.ros.procs:
                self.ros.procs.remove(p)

    def bridge(self, env=None, **launch_args):
        """A fresh bridge (the launch file, as a user starts it): (Proc, websocket URL, ProcStat of the server)."""
        proc, port = harness.launch_bridge(self.ros, env=env, **launch_args)
        return proc, f"ws://127.0.0.1:{port}", harness.ProcStat(harness.node_pid(self.ros, "/rosbridge_websocket"))

    def foxglove(self):
        """A fresh foxglove_bridge (bench/peers.py): (Proc, websocket URL, ProcStat)."""
        proc, stat, url = peers.start_foxglove(self.ros, self.peers, name="bench_foxglove")
        return proc, url, stat

    def transport(self, *args):
        port = harness.free_port()
        proc = self.role("transport_server.py", "--port", port, *args)
        self.ready(proc)
        return proc, f"ws://127.0.0.1:{port}/", harness.ProcStat(proc.pid)

    def close(self):
        self.ros.stop()


class Cpu:
    """CPU seconds a process spends between start and stop (stats.CpuWindow: its threads' own counts, to the
    microsecond, or 10 ms ticks if a thread ended meanwhile)."""

    def __init__(self, proc_stat):
        self.window = stats.CpuWindow(proc_stat)

    def us_per(self, messages):
        # (rounded: two equal tick counts must compare equal after the float division)
        return round(self.window.seconds() * 1e6 / messages, 3) if messages else None


# ---- measurements: each returns a dict of figures for one round ------------------------------------------


def rospy_pubsub(run, kind, count, rate=0, queue_size=100):
    """Plain rospy publisher (queued, or synchronous with queue_size 0) -> rospy subscriber: delivered rate, and
    each node's CPU per message."""
    topic = run.topic("plain")
    sub = run.role("ros_roles.py", "count", "--topic", topic, "--kind", kind, "--count", count)
    pub = run.role(
        "ros_roles.py",
        "pub",
        "--topic",
        topic,
        "--kind",
        kind,
        "--count",
        count,
        "--rate",
        rate,
        "--queue-size",
        queue_size,
    )
    run.ready(pub), run.ready(sub)
    pub_cpu, sub_cpu = Cpu(harness.ProcStat(pub.pid)), Cpu(harness.ProcStat(sub.pid))
    run.go(pub)
    got = run.result(sub)
    figures = {
        "rate": got["rate"],
        "delivered": got["received"] / count,
        "pub_us": pub_cpu.us_per(count),
        "sub_us": sub_cpu.us_per(got["received"]),
    }
    run.stop(pub, sub)
    return figures


FRAME_BY_FRAME = ("--one-frame-per-write",)  # a synchronous client: one send per frame (ws_roles.py)


def bridge_in(run, url, server, kind, count, rate=0, client_args=(), protocol="rosbridge"):
    """Websocket client publishes (as fast as it can, or at `rate` Hz) through the bridge -> rospy subscriber.
    protocol "foxglove": the client advertises a channel of its own and sends the message's ROS bytes."""
    topic = run.topic("in")
    sub = run.role("ros_roles.py", "count", "--topic", topic, "--kind", kind, "--count", count)
    client = run.role(
        "ws_roles.py",
        "publish",
        "--url",
        url,
        "--topic",
        topic,
        "--kind",
        kind,
        "--count",
        count,
        "--publish-rate",
        rate,
        "--protocol",
        protocol,
        *client_args,
    )
    run.ready(client), run.ready(sub)
    cpu = Cpu(server)
    run.go(client)
    got = run.result(sub)
    figures = {
        "rate": got["received"] and got["rate"],
        "delivered": got["received"] / count,
        "server_us": cpu.us_per(got["received"]),
    }
    run.stop(client, sub)
    return figures


def bridge_out(
    run,
    url,
    server,
    kind,
    count,
    compression="none",
    rate=0,
    queue_size=100,
    clients=1,
    protocol="rosbridge",
    topic=None,
):
    """rospy publisher (at full speed, or `rate` Hz; queued, or synchronous with queue_size 0) -> the bridge ->
    `clients` subscribed websocket clients (one process each). With several, `delivered` is the least any client
    got and the CPU is per message published (`server_us_delivered`: per message delivered to any client), `age_p95`
    the highest client's (an image's age: arrival - its header stamp; a Twist's: arrival - the send time it
    carries, with protocol "foxglove" only). protocol "foxglove": the clients speak the Foxglove protocol, to
    foxglove_bridge, the bridge or foxglove_ceiling.py (which learn the topic from the master, or are told it:
    `topic`; the publisher comes first. Each subscription of foxglove_bridge's clients is a roscpp subscriber of its
    own, on the one connection roscpp keeps per topic, added a moment after the client's request)."""
    topic = topic or run.topic("out")
    pub = run.role(
        "ros_roles.py",
        "pub",
        "--topic",
        topic,
        "--kind",
        kind,
        "--count",
        count,
        "--rate",
        rate,
        "--queue-size",
        queue_size,
        *(["--stamp"] if protocol == "foxglove" else []),
    )
    subscribers = [
        run.role(
            "ws_roles.py",
            "subscribe",
            "--url",
            url,
            "--topic",
            topic,
            "--kind",
            kind,
            "--count",
            count,
            "--compression",
            compression,
            "--protocol",
            protocol,
        )
        for _ in range(clients)
    ]
    for client in subscribers:
        run.ready(client, timeout=60)
    run.ready(pub)
    if protocol == "foxglove":
        time.sleep(1.0)
    cpu = Cpu(server)
    run.go(pub)
    results = [run.result(client) for client in subscribers]
    got = min(results, key=lambda r: r["received"])
    ages = [r["age_p95"] for r in results if r.get("age_p95") is not None]
    spent, delivered = cpu.us_per(1), sum(r["received"] for r in results)  # (µs: all of it)
    figures = {
        "rate": got["rate"],
        "delivered": got["received"] / count,
        "server_us": spent / (got["received"] if clients == 1 else count) if got["received"] else None,
        "server_us_delivered": spent / delivered if delivered else None,
        "age_p95": max(ages) if ages else None,
        "wire_bytes": got["bytes"] / got["received"] if got["received"] else None,
    }
    if got["statuses"]:
        figures["status"] = got["statuses"]
    run.stop(*subscribers, pub)
    return figures


def on_foxglove(run, measure, kind, count, **options):
    """measure (bridge_out, bridge_in) through a fresh foxglove_bridge (bench/peers.py), or None when it is not
    built."""
    if run.foxglove_missing:
        return None
    proc, url, stat = run.foxglove()
    try:
        return measure(run, url, stat, kind, count, protocol="foxglove", **options)
    finally:
        run.stop(proc)


def foxglove_ceiling_out(run, kind, count, env=None, then=None, **options):
    """bridge_out through bench/foxglove_ceiling.py: the same TCPROS bytes read and written to the clients as
    Foxglove message data, nothing else. `then(stat)`, if given, runs before the ceiling stops."""
    topic, port = run.topic("out"), harness.free_port()
    server = run.role("foxglove_ceiling.py", "--port", port, "--topic", topic, "--kind", kind, env=env)
    run.ready(server)
    try:
        url, stat = f"ws://127.0.0.1:{port}/", harness.ProcStat(server.pid)
        result = bridge_out(run, url, stat, kind, count, protocol="foxglove", topic=topic, **options)
        return result if then is None else then(stat)
    finally:
        run.stop(server)


def at_most(mine, theirs, factor):
    return mine is not None and theirs is not None and mine <= factor * theirs


def foxglove_rows(run, table, label, bridged, fox_rounds, limit, key="server_us", lossless=False, age=False):
    """Rows of the bridge's figures (`bridged`: {client: medians}) beside foxglove_bridge's in the same run (its
    clients get the ROS bytes, as cbor-raw's do): CPU per message (key) against `limit`; with `lossless`, every
    message delivered by both; the p95 age at the client where both have one, with `age` no higher than
    foxglove's."""
    fox_rounds = [r for r in fox_rounds if r]
    if not fox_rounds:
        table.notes.append(f"{label}: {peers.FOXGLOVE_NAME} not measured ({run.foxglove_missing}).")
        return
    fox, peer = medians(fox_rounds), f"{peers.FOXGLOVE_NAME} (ROS bytes)"
    for client, r in bridged.items():
        table.row(
            f"{label} ({client}): bridge CPU per message{' delivered' if key != 'server_us' else ''}",
            r.get(key),
            "µs",
            peer,
            fox.get(key),
            f"<= {limit}x",
            at_most(r.get(key), fox.get(key), limit),
        )
        table.row(
            f"{label} ({client}): messages delivered",
            r["delivered"],
            "%",
            peer,
            fox["delivered"],
            "100%" if lossless else "",
            r["delivered"] >= 1.0 if lossless else None,
        )
        ms = [f.get("age_p95") and f["age_p95"] * 1e3 for f in (r, fox)]
        if age or None not in ms:
            table.row(
                f"{label} ({client}): age p95 at the client",
                ms[0],
                "ms",
                peer,
                ms[1],
                "no higher" if age else "",
                at_most(ms[0], ms[1], 1.0) if age else None,
            )


FOXGLOVE_CEILING = "bare TCPROS read -> Foxglove frames (foxglove_ceiling.py)"


def foxglove_protocol_rows(run, table, label, bridged, fox_rounds, against_ceiling, limit, key="server_us", **options):
    """Issue 36: the bridge speaking the Foxglove protocol (`bridged`: its rounds) beside foxglove_bridge speaking
    it to the same client (foxglove_rows: CPU per message, `key`, against `limit`), and against the bare ceiling
    where measured (`against_ceiling`: the bridge's rounds and the ceiling's, for that row; CPU per message at
    most 1.2x the ceiling's)."""
    foxglove_rows(run, table, label, {"Foxglove protocol": medians(bridged)}, fox_rounds, limit, key=key, **options)
    if against_ceiling:
        beside, ceiling = map(medians, against_ceiling)
        table.row(
            f"{label} (Foxglove protocol): bridge CPU per message, vs the bare ceiling",
            beside.get(key),
            "µs",
            FOXGLOVE_CEILING,
            ceiling.get(key),
            "<= 1.2x",
            at_most(beside.get(key), ceiling.get(key), 1.2),
        )


CEILING_SECONDS = 20.0  # each side of ceiling_pair


def ceiling_pair(run, url, server, kind, hz):
    """Issue 36's ceiling rows at a fixed rate: the bridge's Foxglove path for CEILING_SECONDS, on the bridge that
    served the round's other rows; the caller stops the bridge, then measures the ceiling (ceiling_pair_end) right
    after it. In runs of a few seconds, as the round's others, what the bridge spends once per run (a publisher
    coming and going changes the graph; a client leaves) counts as much as a tenth of the messages, and the ratio
    moved by more than its margin from one pair to the next on this VM (a 640x480 image at 30 Hz, 4 s each:
    1.01-1.73x in seven pairs, the bridge 500-721 µs an image; 20 s each: 1.06-1.42x in six, the bridge
    500-530)."""
    return bridge_out(run, url, server, kind, int(hz * CEILING_SECONDS), rate=hz, protocol="foxglove")


def ceiling_pair_end(run, kind, hz):
    return foxglove_ceiling_out(run, kind, int(hz * CEILING_SECONDS), rate=hz)


OPCODE_RATE = 200  # Hz: each message a read of its own, as at 1 kHz, and the traced server keeps up
OPCODE_MESSAGES = 1000


def section_opcodes(run, table):
    """What the ceiling rows measure, counted instead of timed: the Python opcodes the server's event loop runs
    per message (bench/opcount), the bridge's Foxglove path and the bare ceiling, Twist at OPCODE_RATE to one
    client. Each side runs OPCODE_MESSAGES and twice as many, each in a fresh process: the difference is what
    OPCODE_MESSAGES cost, without start-up, connection or subscription. The same from run to run, where the CPU
    ratios move by +-15 % on this VM; an opcode costs 20-30 ns here (perf: the interpreter's share of the two
    servers' time was in the ratio of their opcodes)."""
    per_message = {}
    for side in ("bridge", "ceiling"):
        counts = [traced_opcodes(run, side, n) for n in (OPCODE_MESSAGES, 2 * OPCODE_MESSAGES)]
        per_message[side] = (counts[1] - counts[0]) / OPCODE_MESSAGES
    table.row(
        f"ROS -> client at {OPCODE_RATE} Hz (Foxglove protocol): Python opcodes per message on the event loop, "
        "vs the bare ceiling",
        per_message["bridge"],
        "",
        FOXGLOVE_CEILING,
        per_message["ceiling"],
    )


def traced_opcodes(run, side, count):
    """The opcodes a fresh server (`side`: "bridge" or "ceiling") ran on its main thread by the time it had
    delivered `count` Twists."""
    out = run.workdir / f"opcodes-{side}-{count}-{run.spawned}"
    script = "rosbridge_websocket" if side == "bridge" else "foxglove_ceiling.py"
    env = {
        "PYTHONPATH": f"{BENCH / 'opcount'}:{run.ros.env['PYTHONPATH']}",  # (Run set it: bench/ and testkit/ first)
        "BENCH_OPCODES": str(out),
        "BENCH_OPCODES_OF": script,
    }

    def so_far(stat):
        os.kill(stat.pid, signal.SIGUSR2)
        return int(harness.wait_for(lambda: out.exists() and out.read_text(), 10, what=f"{script}'s opcodes"))

    if side == "ceiling":
        return foxglove_ceiling_out(run, "twist", count, env=env, then=so_far, rate=OPCODE_RATE)
    bridge, url, server = run.bridge(env=env)
    try:
        bridge_out(run, url, server, "twist", count, rate=OPCODE_RATE, protocol="foxglove")
        return so_far(server)
    finally:
        run.stop(bridge)


def foxglove_in_rows(run, table, label, bridged, fox_rounds, limit):
    """Issue 36: a Foxglove client publishing through the bridge (`bridged`: its rounds) and through foxglove_bridge
    in the same run: CPU per message delivered to the rospy subscriber against `limit`, and the share delivered."""
    fox_rounds = [r for r in fox_rounds if r]
    if not fox_rounds:
        table.notes.append(f"{label}: {peers.FOXGLOVE_NAME} not measured ({run.foxglove_missing}).")
        return
    mine, fox = medians(bridged), medians(fox_rounds)
    table.row(
        f"{label}: bridge CPU per message",
        mine["server_us"],
        "µs",
        peers.FOXGLOVE_NAME,
        fox["server_us"],
        f"<= {limit}x",
        at_most(mine["server_us"], fox["server_us"], limit),
    )
    table.row(f"{label}: messages delivered", mine["delivered"], "%", peers.FOXGLOVE_NAME, fox["delivered"])


def transport_in(run, count, rate=0, forward=False, client_args=()):
    """The bare server receiving; with `forward`, also writing each message to a plain TCP reader."""
    sink = run.role("tcp_sink.py") if forward else None
    if sink:
        run.ready(sink)
    forwarding = ("--forward", re.search(r"PORT (\d+)", sink.output()).group(1)) if sink else ()
    server, url, stat = run.transport("--no-echo", *forwarding)
    client = run.role("ws_roles.py", "publish", "--url", url, "--count", count, "--publish-rate", rate, *client_args)
    run.ready(client)
    cpu = Cpu(stat)
    run.go(client)
    run.result(client)
    run.go(client)  # closes the socket: the server then reports what it received
    got = run.result(server)
    figures = {"rate": got["rate"], "server_us": cpu.us_per(got["received"])}
    run.stop(client, server, *filter(None, [sink]))
    return figures


def transport_out(run, count, rate=0, kind="twist", cbor=False):
    server, url, stat = run.transport("--count", count, "--rate", rate, "--kind", kind, *(["--cbor"] if cbor else []))
    client = run.role("ws_roles.py", "subscribe", "--url", url, "--count", count, "--kind", kind)
    run.ready(client)
    server.wait_output("SUBSCRIBED")
    cpu = Cpu(stat)
    run.go(server)
    got = run.result(client)
    figures = {"rate": got["rate"], "server_us": cpu.us_per(got["received"])}
    run.stop(client, server)
    return figures


def ws_rtt(run, url, ping, pong, count=300):
    """A websocket client's round trips at 100 Hz: it publishes on `ping` and times what comes back on `pong`."""
    client = run.role(
        "ws_roles.py",
        "rtt",
        "--url",
        url,
        "--kind",
        "float",
        "--topic",
        ping,
        "--out",
        pong,
        "--count",
        count,
        "--rate",
        100,
    )
    got = run.result(client)
    run.stop(client)
    return got


def rtt(run, url=None):
    """Round trips at 100 Hz through a rospy echo node: from a websocket client over the bridge (url given), or
    from a plain rospy node (url None)."""
    ping, pong = run.topic("ping"), run.topic("pong")
    echo = run.role("ros_roles.py", "echo", "--kind", "float", "--topic", ping, "--out", pong)
    run.ready(echo)
    if url:
        got = ws_rtt(run, url, ping, pong)
    else:
        client = run.role(
            "ros_roles.py", "rtt", "--kind", "float", "--topic", ping, "--out", pong, "--count", 300, "--rate", 100
        )
        got = run.result(client)
        run.stop(client)
    run.stop(echo)
    return got


def bridge_loop_rtt(run, url):
    """Round trips at 100 Hz through the bridge alone: the client subscribes to the topic it publishes, so each
    message goes into ROS (to the bridge's TCPROS publisher) and comes back out (from its TCPROS subscriber),
    with no other node in the path, as the bare echo has no other process in its."""
    topic = run.topic("loop")
    return ws_rtt(run, url, topic, topic)


def transport_rtt(run):
    server, url, _ = run.transport()
    got = ws_rtt(run, url, "/t", "/t")
    run.stop(server)
    return got


def fanout(run, clients, messages=30):
    """`clients` websocket clients on one 10 Hz topic of a fresh bridge: loss, memory and threads. (They all come from
    127.0.0.1: the bridge is told to take that many from one address, max_connections_per_address.)"""
    bridge, url, server = run.bridge(max_connections_per_address=clients + 16)
    time.sleep(1.0)
    idle_rss, idle_threads = server.rss_mb(), server.threads()
    topic = run.topic("fan")
    procs = max(1, min(2, clients // 300))  # the clients, multiplexed in one or two processes
    groups = [
        run.role(
            "ws_roles.py",
            "fanout",
            "--url",
            url,
            "--topic",
            topic,
            "--count",
            messages,
            "--clients",
            clients // procs + (i < clients % procs),
            "--timeout",
            90,
            name="fanout",
        )
        for i in range(procs)
    ]
    pub = run.role("ros_roles.py", "pub", "--topic", topic, "--count", messages, "--rate", 10, "--warmup")
    for g in groups:
        run.ready(g, timeout=120)
    rss, threads = [server.rss_mb()], [server.threads()]
    cpu = Cpu(server)
    run.go(pub)
    results = []
    for g in groups:
        while not re.search(r"^RESULT", g.output(), re.M) and g.alive():
            rss.append(server.rss_mb()), threads.append(server.threads())
            time.sleep(0.2)
        results.append(run.result(g))
    delivered = sum(r["delivered"] for r in results)
    figures = {
        "delivered": delivered / (messages * clients),
        "complete_clients": sum(r["complete"] for r in results),
        "idle_rss": idle_rss,
        "rss": max(rss),
        "idle_threads": idle_threads,
        "threads": max(threads),
        "server_us": cpu.us_per(delivered),
        "connect_s": max(r["connect_seconds"] for r in results),
    }
    run.stop(pub, *groups, bridge)
    return figures


# ---- the suite -------------------------------------------------------------------------------------------


def medians(rounds):
    keys = [k for k in rounds[0] if isinstance(rounds[0][k], (int, float))]
    return {k: stats.median([r.get(k) for r in rounds]) for k in keys}


def section_throughput(run, table, rounds, count):
    """As fast as each side can: the bridge against the bare transport (the goals), and plain rospy both ways
    (queued and synchronous publisher) for information. ROS -> client at full speed needs a source faster than
    the bridge: a synchronous rospy publisher (a queued one paces itself, its messages come one by one: that case
    is shown too), and a bridge whose max_queue holds the whole burst, so nothing is dropped."""
    queued, sync, ceil_in, ceil_out, into, out, paced = [], [], [], [], [], [], []
    ceil_in_single, into_single, paced_raw, paced_fox = [], [], [], []
    paced_fg, paced_fg_ceiling = [], []  # (issue 36: the bridge's Foxglove protocol, and its bare ceiling)
    for _ in range(rounds):
        queued.append(rospy_pubsub(run, "twist", count))
        sync.append(rospy_pubsub(run, "twist", count, queue_size=0))
        ceil_in.append(transport_in(run, count))
        ceil_in_single.append(transport_in(run, count, client_args=FRAME_BY_FRAME))
        ceil_out.append(transport_out(run, count))
        # (no per-client frame limit: the default, 20,000 frames/s after a burst of as many, would be measured)
        bridge, url, server = run.bridge(max_queue=count, max_frames_per_second=0)
        into.append(bridge_in(run, url, server, "twist", count))
        into_single.append(bridge_in(run, url, server, "twist", count, client_args=FRAME_BY_FRAME))
        out.append(bridge_out(run, url, server, "twist", count, queue_size=0))
        paced.append(bridge_out(run, url, server, "twist", count))
        paced_raw.append(bridge_out(run, url, server, "twist", count, "cbor-raw"))
        paced_fg.append(bridge_out(run, url, server, "twist", count, protocol="foxglove"))
        run.stop(bridge)
        paced_fox.append(on_foxglove(run, bridge_out, "twist", count))
        paced_fg_ceiling.append(foxglove_ceiling_out(run, "twist", count))
    queued, sync, ceil_in, ceil_out, into, out, paced, ceil_in_single, into_single = map(
        medians, (queued, sync, ceil_in, ceil_out, into, out, paced, ceil_in_single, into_single)
    )
    for client, bridged, ceiling in (
        ("batching client", into, ceil_in),
        ("one frame per write", into_single, ceil_in_single),
    ):
        table.row(
            f"client -> ROS ({client}): Twist delivered to a rospy subscriber",
            bridged["rate"],
            "msg/s",
            "bare Tornado+JSON server receiving",
            ceiling["rate"],
            ">= 0.6x",
            bridged["rate"] >= 0.6 * ceiling["rate"],
        )
        table.row(
            f"client -> ROS ({client}): messages delivered",
            bridged["delivered"],
            "%",
            "all sent",
            1.0,
            "100%",
            bridged["delivered"] >= 1.0,
        )
        table.row(
            f"client -> ROS ({client}): bridge CPU per message",
            bridged["server_us"],
            "µs",
            "bare Tornado+JSON server",
            ceiling["server_us"],
            "<= 1.5x",
            bridged["server_us"] <= 1.5 * ceiling["server_us"],
        )
    table.row(
        "client -> ROS: vs plain rospy, queued publisher (queue_size=100)",
        into["rate"],
        "msg/s",
        "rospy pub -> sub",
        queued["rate"],
    )
    table.row(
        "client -> ROS: vs plain rospy, synchronous publisher", into["rate"], "msg/s", "rospy pub -> sub", sync["rate"]
    )
    table.row(
        "ROS -> client: Twist delivered to a websocket client (synchronous rospy publisher)",
        out["rate"],
        "msg/s",
        "bare Tornado+JSON server pushing",
        ceil_out["rate"],
    )
    # (a client that reads slower than the burst comes gets the newest of the topic, the older ones skipped: the
    # freshness every client gets, issue 26, told at status level warning; lossless is the paced rows' goal)
    table.row(
        "ROS -> client: messages delivered (the client reads slower than they come: each topic kept fresh)",
        out["delivered"],
        "%",
        "all sent",
        1.0,
    )
    table.row(
        "ROS -> client: bridge CPU per message",
        out["server_us"],
        "µs",
        "bare Tornado+JSON server",
        ceil_out["server_us"],
        "<= 1.5x",
        out["server_us"] <= 1.5 * ceil_out["server_us"],
    )
    table.row(
        "ROS -> client: vs a rospy subscriber node's CPU per message",
        out["server_us"],
        "µs",
        "rospy subscriber (synchronous publisher)",
        sync["sub_us"],
    )
    # (its messages come one by one, but faster than read_pace.COALESCE_RATE: read once a millisecond, in batches)
    table.row(
        f"ROS -> client from a queued rospy publisher ({paced['rate']:,.0f} msg/s): bridge CPU per message",
        paced["server_us"],
        "µs",
        "bare Tornado+JSON server at full speed",
        ceil_out["server_us"],
        "<= 1.2x",
        paced["server_us"] <= 1.2 * ceil_out["server_us"],
    )
    table.row(
        "ROS -> client from a queued rospy publisher: messages delivered",
        paced["delivered"],
        "%",
        "plain rospy",
        queued["delivered"],
    )
    foxglove_rows(
        run,
        table,
        f"ROS -> client from a queued rospy publisher ({paced['rate']:,.0f} msg/s)",
        {"JSON": paced, "cbor-raw": medians(paced_raw)},
        paced_fox,
        limit=0.8,
        lossless=True,
    )
    foxglove_protocol_rows(
        run,
        table,
        f"ROS -> client from a queued rospy publisher ({paced['rate']:,.0f} msg/s)",
        paced_fg,
        paced_fox,
        (paced_fg, paced_fg_ceiling),
        limit=0.6,
        lossless=True,
    )


RATES = ((100, 10.0), (1000, 5.0))  # Hz, seconds: most robot topics run at 10-1000 Hz, not in floods


def section_rates(run, table, rounds):
    """At a fixed rate each message may wake the loop on its own: bridge CPU per message at 100 Hz and 1 kHz,
    both ways, against the bare transport at the same rates."""
    for hz, seconds in RATES:
        count = int(hz * seconds)
        ceil_in, ceil_out, into, out, forwarding, raw, fox = [], [], [], [], [], [], []
        foxglove, foxglove_in, fox_in, paired = [], [], [], ([], [])  # (issue 36)
        for _ in range(rounds):
            ceil_in.append(transport_in(run, count, rate=hz))
            forwarding.append(transport_in(run, count, rate=hz, forward=True))
            ceil_out.append(transport_out(run, count, rate=hz))
            bridge, url, server = run.bridge()
            into.append(bridge_in(run, url, server, "twist", count, rate=hz))
            out.append(bridge_out(run, url, server, "twist", count, rate=hz))
            if hz >= 1000:  # (issue 25: beside foxglove_bridge, whose clients get the ROS bytes, as cbor-raw's)
                raw.append(bridge_out(run, url, server, "twist", count, "cbor-raw", rate=hz))
                foxglove.append(bridge_out(run, url, server, "twist", count, rate=hz, protocol="foxglove"))
                foxglove_in.append(bridge_in(run, url, server, "twist", count, rate=hz, protocol="foxglove"))
                paired[0].append(ceiling_pair(run, url, server, "twist", hz))
            run.stop(bridge)
            if hz >= 1000:
                paired[1].append(ceiling_pair_end(run, "twist", hz))
                fox.append(on_foxglove(run, bridge_out, "twist", count, rate=hz))
                fox_in.append(on_foxglove(run, bridge_in, "twist", count, rate=hz))
        ceil_in, ceil_out, into, out, forwarding = map(medians, (ceil_in, ceil_out, into, out, forwarding))
        goal, limit = ("<= 1.3x", 1.3) if hz >= 1000 else ("", None)
        for way, bridge_r, ceil in (("client -> ROS", into, ceil_in), ("ROS -> client", out, ceil_out)):
            table.row(
                f"{way} at {hz:,} Hz: bridge CPU per message",
                bridge_r["server_us"],
                "µs",
                f"bare Tornado+JSON server at {hz:,} Hz",
                ceil["server_us"],
                goal,
                None if limit is None else bridge_r["server_us"] <= limit * ceil["server_us"],
            )
            table.row(f"{way} at {hz:,} Hz: messages delivered", bridge_r["delivered"], "%", "all sent", 1.0)
        table.row(
            f"client -> ROS at {hz:,} Hz: vs the bare server that also writes each message to a TCP reader",
            into["server_us"],
            "µs",
            "bare Tornado+JSON server + one send per message",
            forwarding["server_us"],
        )
        if raw:
            foxglove_rows(
                run, table, f"ROS -> client at {hz:,} Hz", {"JSON": out, "cbor-raw": medians(raw)}, fox, limit=0.9
            )
            foxglove_protocol_rows(run, table, f"ROS -> client at {hz:,} Hz", foxglove, fox, paired, limit=0.7)
            foxglove_in_rows(
                run,
                table,
                f"client -> ROS at {hz:,} Hz (Foxglove protocol: a client channel, Twist as ros1)",
                foxglove_in,
                fox_in,
                limit=1.0,
            )


IDLE_SECONDS = 10


def idle_cpu(run, server, url=None):
    """A server's CPU in ms a second over IDLE_SECONDS with nothing to do: no client, or (url) one Foxglove client
    subscribed to a topic published once a second (the graph, parameters and time are the server's to watch)."""
    client = pub = None
    if url is not None:
        topic = run.topic("idle")
        pub = run.role("ros_roles.py", "pub", "--topic", topic, "--kind", "twist", "--count", 1000, "--rate", 1)
        flags = {"url": url, "topic": topic, "count": 10**6, "protocol": "foxglove", "idle": 600, "timeout": 600}
        argv = itertools.chain.from_iterable((f"--{name}", value) for name, value in flags.items())
        client = run.role("ws_roles.py", "subscribe", *argv)
        run.ready(client, timeout=60)
        run.ready(pub)
        run.go(pub)
    time.sleep(2.0)  # (start-up settles)
    cpu = Cpu(server)
    time.sleep(IDLE_SECONDS)
    spent = cpu.window.seconds()
    run.stop(*filter(None, (client, pub)))
    return {"ms_per_s": spent * 1e3 / IDLE_SECONDS}


def section_idle(run, table, rounds):
    """What a bridge left running costs while nothing happens (a rover's runs for days), beside foxglove_bridge
    left the same way: no client, then one idle Foxglove client."""
    mine, theirs = {"none": [], "foxglove": []}, {"none": [], "foxglove": []}
    for _ in range(rounds):
        bridge, url, server = run.bridge()
        mine["none"].append(idle_cpu(run, server))
        mine["foxglove"].append(idle_cpu(run, server, url))
        run.stop(bridge)
        if not run.foxglove_missing:
            proc, url, stat = run.foxglove()
            theirs["none"].append(idle_cpu(run, stat))
            theirs["foxglove"].append(idle_cpu(run, stat, url))
            run.stop(proc)
    for case, label in (("none", "no client"), ("foxglove", "one Foxglove client, its topic at 1 Hz")):
        fox = medians(theirs[case])["ms_per_s"] if theirs[case] else None
        table.row(
            f"idle bridge, {label}: CPU per second",
            medians(mine[case])["ms_per_s"],
            "ms",
            f"{peers.FOXGLOVE_NAME}, the same",
            fox,
        )


def section_latency(run, table, rounds):
    plain, ceil, bridge_rtts, loop_rtts = [], [], [], []
    for _ in range(rounds):
        plain.append(rtt(run))
        ceil.append(transport_rtt(run))
        bridge, url, _ = run.bridge()
        loop_rtts.append(bridge_loop_rtt(run, url))
        bridge_rtts.append(rtt(run, url))
        run.stop(bridge)
    plain, ceil, bridge_rtts, loop_rtts = map(medians, (plain, ceil, bridge_rtts, loop_rtts))
    table.row(
        "round trip p50 at 100 Hz through the bridge alone (client -> bridge -> ROS topic -> bridge -> client)",
        loop_rtts["p50_ms"],
        "ms",
        "bare Tornado echo",
        ceil["p50_ms"],
        "<= 1.5x",
        loop_rtts["p50_ms"] <= 1.5 * ceil["p50_ms"],
    )
    table.row(
        "round trip p99 at 100 Hz through the bridge alone",
        loop_rtts["p99_ms"],
        "ms",
        "bare Tornado echo",
        ceil["p99_ms"],
    )
    for q in ("p50", "p99"):
        table.row(
            f"round trip {q} at 100 Hz through an echo node (client -> bridge -> echo node -> bridge -> client)",
            bridge_rtts[f"{q}_ms"],
            "ms",
            "plain rospy round trip via the same echo node",
            plain[f"{q}_ms"],
        )
    table.row(
        "round trip p50 through an echo node: vs websocket transport ceiling",
        bridge_rtts["p50_ms"],
        "ms",
        "bare Tornado echo",
        ceil["p50_ms"],
    )
    table.row(
        "round trip p50 through an echo node: vs the two trips it is made of",
        bridge_rtts["p50_ms"],
        "ms",
        "bare Tornado echo + plain rospy round trip",
        ceil["p50_ms"] + plain["p50_ms"],
    )
    table.row(
        "round trips answered",
        min(r["echoed"] / r["sent"] for r in (bridge_rtts, loop_rtts)),
        "%",
        "plain rospy",
        plain["echoed"] / plain["sent"],
    )


def section_fanout(run, table, rounds, sizes):
    results = {n: medians([fanout(run, n) for _ in range(rounds)]) for n in sizes}
    base = results[sizes[0]]
    for n, r in results.items():
        table.row(
            f"fan-out, {n} clients on a 10 Hz topic: messages delivered to every client",
            r["delivered"],
            "%",
            "",
            None,
            "100%",
            r["delivered"] == 1.0,
        )
        table.row(f"fan-out, {n} clients: bridge RSS", r["rss"], "MB", "idle bridge", r["idle_rss"])
        table.row(
            f"fan-out, {n} clients: bridge threads",
            r["threads"],
            "",
            f"{sizes[0]} client(s)",
            base["threads"],
            "constant",
            r["threads"] <= base["threads"],
        )
        if n >= 100:  # (with fewer, the 10 ms CPU clock ticks swamp the few messages)
            table.row(f"fan-out, {n} clients: bridge CPU per delivered message", r["server_us"], "µs", "", None)
    if len(sizes) > 1:
        hi, lo = results[sizes[-1]], results[sizes[0]]
        per_client = (hi["rss"] - lo["rss"]) * 1e3 / (sizes[-1] - sizes[0])
        table.notes.append(
            f"Fan-out memory: {per_client:.0f} kB of bridge RSS per extra client "
            f"({lo['rss']:.1f} MB with {sizes[0]}, {hi['rss']:.1f} MB with {sizes[-1]})."
        )


CAMERA_HZ = 30
TWENTY = 20  # clients on one camera (issue 25)


def section_large(run, table, rounds, count):
    """Client -> ROS as fast as possible; ROS -> client at a camera's 30 Hz (a faster burst of megabyte frames
    only measures how many the bounded client queue drops)."""
    for kind, label in (("image", "640x480 rgb8 sensor_msgs/Image"), ("string", "1 MB std_msgs/String")):
        plain, paced, into, outs = [], [], [], {c: [] for c in ("none", "png", "cbor")}
        ceilings = {"none": [], "cbor": []}
        to_three = {c: [] for c in ceilings} if kind == "image" else {}
        raw, fox, fox_twenty, to_twenty = [], [], [], {"CBOR": [], "cbor-raw": []}
        foxglove, foxglove_twenty, paired = [], [], ([], [])  # (issue 36)
        for _ in range(rounds):
            plain.append(rospy_pubsub(run, kind, count))
            paced.append(rospy_pubsub(run, kind, count, rate=CAMERA_HZ))
            for c in ceilings:
                ceilings[c].append(transport_out(run, count, rate=CAMERA_HZ, kind=kind, cbor=c == "cbor"))
            bridge, url, server = run.bridge()
            into.append(bridge_in(run, url, server, kind, count))
            for c in outs:
                outs[c].append(bridge_out(run, url, server, kind, count, c, rate=CAMERA_HZ))
            for c in to_three:
                to_three[c].append(bridge_out(run, url, server, kind, count, c, rate=CAMERA_HZ, clients=3))
            if kind == "image":  # (issue 25: beside foxglove_bridge, one client and twenty)
                raw.append(bridge_out(run, url, server, kind, count, "cbor-raw", rate=CAMERA_HZ))
                for c in to_twenty:
                    to_twenty[c].append(
                        bridge_out(run, url, server, kind, count, c.lower(), rate=CAMERA_HZ, clients=TWENTY)
                    )
                foxglove.append(bridge_out(run, url, server, kind, count, rate=CAMERA_HZ, protocol="foxglove"))
                foxglove_twenty.append(
                    bridge_out(run, url, server, kind, count, rate=CAMERA_HZ, clients=TWENTY, protocol="foxglove")
                )
                paired[0].append(ceiling_pair(run, url, server, kind, CAMERA_HZ))
            run.stop(bridge)
            if kind == "image":
                paired[1].append(ceiling_pair_end(run, kind, CAMERA_HZ))
                fox.append(on_foxglove(run, bridge_out, kind, count, rate=CAMERA_HZ))
                fox_twenty.append(on_foxglove(run, bridge_out, kind, count, rate=CAMERA_HZ, clients=TWENTY))
        plain, paced, into = medians(plain), medians(paced), medians(into)
        outs = {c: medians(v) for c, v in outs.items()}
        ceilings = {c: medians(v) for c, v in ceilings.items()}
        table.row(
            f"{label}, client -> ROS, as fast as possible",
            into["rate"],
            "msg/s",
            "plain rospy pub -> sub",
            plain["rate"],
        )
        table.row(
            f"{label}, client -> ROS: bridge CPU per message",
            into["server_us"],
            "µs",
            "rospy publisher node",
            plain["pub_us"],
        )
        for c, r in outs.items():
            table.row(
                f"{label}, ROS -> client at {CAMERA_HZ} Hz ({c}): delivered",
                r["delivered"],
                "%",
                "plain rospy",
                paced["delivered"],
            )
            table.row(
                f"{label}, ROS -> client ({c}): bytes on the wire per message",
                r["wire_bytes"],
                "B",
                "JSON (none)",
                outs["none"]["wire_bytes"],
            )
            if c in ceilings:
                ceiling = ceilings[c]["server_us"]
                table.row(
                    f"{label}, ROS -> client ({c}): bridge CPU per message",
                    r["server_us"],
                    "µs",
                    f"bare Tornado server pushing {'CBOR' if c == 'cbor' else 'JSON'}",
                    ceiling,
                    "<= 1.0x" if kind == "image" else "",
                    r["server_us"] <= ceiling if kind == "image" else None,
                )
            else:
                table.row(
                    f"{label}, ROS -> client ({c}): bridge CPU per message",
                    r["server_us"],
                    "µs",
                    "JSON (none)",
                    outs["none"]["server_us"],
                )
        for c, runs in to_three.items():
            r = medians(runs)
            table.row(
                f"{label}, ROS -> 3 clients at {CAMERA_HZ} Hz ({c}): delivered to each",
                r["delivered"],
                "%",
                "plain rospy",
                paced["delivered"],
                "100%",
                r["delivered"] >= 1.0,
            )
            table.row(
                f"{label}, ROS -> 3 clients ({c}): bridge CPU per image published",
                r["server_us"],
                "µs",
                "one client",
                outs[c]["server_us"],
            )
        table.row(
            f"{label}, ROS -> client (none): vs a rospy subscriber node's CPU",
            outs["none"]["server_us"],
            "µs",
            "rospy subscriber node",
            paced["sub_us"],
        )
        if raw:
            foxglove_rows(
                run,
                table,
                f"{label}, ROS -> client at {CAMERA_HZ} Hz",
                {"JSON": outs["none"], "CBOR": outs["cbor"], "cbor-raw": medians(raw)},
                fox,
                limit=1.0,
                age=True,
            )
            foxglove_rows(
                run,
                table,
                f"{label}, ROS -> {TWENTY} clients at {CAMERA_HZ} Hz",
                {c: medians(v) for c, v in to_twenty.items()},
                fox_twenty,
                limit=0.5,
                key="server_us_delivered",
            )
            foxglove_protocol_rows(
                run,
                table,
                f"{label}, ROS -> client at {CAMERA_HZ} Hz",
                foxglove,
                fox,
                paired,
                limit=0.5,
                age=True,
            )
            foxglove_protocol_rows(
                run,
                table,
                f"{label}, ROS -> {TWENTY} clients at {CAMERA_HZ} Hz",
                foxglove_twenty,
                fox_twenty,
                None,
                limit=0.25,
                key="server_us_delivered",
            )


CLOUD_HZ, CLOUD_COUNT = 5, 100  # a 300k-point lidar at 5 Hz, for 20 s (5 ms a cloud: 50 CPU ticks of 10 ms)


def cloud_out(run, url, server, topic):
    """A 300k-point sensor_msgs/PointCloud2 (4.8 MB) from a rospy publisher at 5 Hz -> a server's /cloud at url ->
    one client asking as the page's Cloud viewer does (20,000 points; the next once it has read the last): clouds
    delivered, the server's CPU per cloud delivered, bytes per cloud on the wire."""
    fetch = run.role("cloud_roles.py", "fetch", "--url", url, "--topic", topic, "--count", CLOUD_COUNT)
    run.ready(fetch)
    pub = run.role(
        "ros_roles.py", "pub", "--topic", topic, "--kind", "cloud", "--count", CLOUD_COUNT, "--rate", CLOUD_HZ
    )
    run.ready(pub, timeout=60)  # (once the server subscribed: at the client's first request for the bridge)
    cpu = Cpu(server)
    run.go(pub)
    got = run.result(fetch)
    if got["problems"]:
        raise RuntimeError(f"/cloud answered {got['problems']}")
    figures = {
        "delivered": got["unique"] / CLOUD_COUNT,
        "server_us": cpu.us_per(got["unique"]),
        "wire_bytes": got["bytes"] / got["received"] if got["received"] else None,
    }
    run.stop(fetch, pub)
    return figures


def decimation_ms(reps=20):
    """CPU ms of rosbridge.http.cloud's read_cloud + decimate of the bench's cloud to 20,000 points, in this process."""
    import io

    from rosbridge.http.cloud import decimate, read_cloud

    buffer = io.BytesIO()
    payloads.ros_msg("cloud").serialize(buffer)
    raw = buffer.getvalue()
    started = time.process_time()
    for _ in range(reps):
        decimate(read_cloud(raw), 20000)
    return (time.process_time() - started) * 1e3 / reps


def section_cloud(run, table, rounds):
    """The bridge's /cloud (the Cloud viewer's source) against the least such an endpoint does, in the same run:
    bench/cloud_roles.py's serve (one bare TCPROS connection read into a buffer per message, the same decimation,
    a bare Tornado HTTP server); and, for information, a rospy node that only receives the clouds."""
    plain, ceiling, bridged = [], [], []
    for _ in range(rounds):
        plain.append(rospy_pubsub(run, "cloud", CLOUD_COUNT, rate=CLOUD_HZ))
        topic, port = run.topic("cloud"), harness.free_port()
        server = run.role("cloud_roles.py", "serve", "--topic", topic, "--port", port)
        run.ready(server)
        ceiling.append(cloud_out(run, f"http://127.0.0.1:{port}/", harness.ProcStat(server.pid), topic))
        run.stop(server)
        bridge, url, stat = run.bridge()
        bridged.append(cloud_out(run, url.replace("ws://", "http://") + "/", stat, run.topic("cloud")))
        run.stop(bridge)
    plain, ceiling, bridged = map(medians, (plain, ceiling, bridged))
    decimation = decimation_ms()
    label = f"300k-point PointCloud2 at {CLOUD_HZ} Hz, ROS -> /cloud -> a client asking as the Cloud viewer does"
    ceiling_name = "bare TCPROS read + the same decimation + bare Tornado HTTP"
    table.row(f"{label}: clouds delivered", bridged["delivered"], "%", ceiling_name, ceiling["delivered"])
    table.row(
        "point cloud: bridge CPU per delivered (decimated) cloud",
        bridged["server_us"] / 1e3,
        "ms",
        ceiling_name,
        ceiling["server_us"] / 1e3,
    )
    table.row(
        "point cloud: bridge CPU per delivered cloud, vs a rospy node only receiving the clouds",
        bridged["server_us"] / 1e3,
        "ms",
        "rospy subscriber (PointCloud2)",
        plain["sub_us"] / 1e3,
    )
    table.row(
        "point cloud: of the ceiling's CPU, the decimation alone (read_cloud + decimate, no I/O)",
        decimation,
        "ms",
        ceiling_name,
        ceiling["server_us"] / 1e3,
    )
    table.row(
        "point cloud: bytes on the wire per cloud (20,000 points asked)",
        bridged["wire_bytes"],
        "B",
        "the ceiling's",
        ceiling["wire_bytes"],
    )


def section_isolation(run, table):
    """One hostile client at a time (testkit/hostile.py) against a well-behaved one: the victim's
    largest gap in turtlesim's 62.5 Hz pose, its slowest /rosapi/get_time, the bridge's memory growth."""
    turtle = run.ros.spawn(["rosrun", "turtlesim", "turtlesim_node", "__name:=bench_turtle"], "bench_turtle")
    turtle.wait_output("Spawning turtle [turtle1]", 30)
    try:
        for abuse in hostile.ABUSES:
            if abuse == "auth_flood":  # (needs a bridge with authentication: the tests cover it)
                continue
            bridge, url, server = run.bridge()
            got = hostile.measure(run.ros, url, server, abuse, seconds=6.0)
            run.stop(bridge)
            table.row(
                f"isolation, {abuse}: victim's largest gap in a 62.5 Hz topic",
                got["gap"],
                "s",
                "",
                None,
                "< 0.5 s",
                got["gap"] < 0.5,
            )
            table.row(
                f"isolation, {abuse}: victim's slowest /rosapi/get_time",
                got["slowest_call"],
                "s",
                "",
                None,
                "< 1 s",
                got["slowest_call"] < 1.0,
            )
            table.row(f"isolation, {abuse}: bridge RSS growth", got["rss_growth"], "MB", "", None)
    finally:
        run.stop(turtle)


def other_bench(run, script, title, code_block=False, python=PY, args=()):
    """Runs another part's benchmark (bench/<script> with args, same roscore environment) and returns its table."""
    path = BENCH / script
    if not path.exists():
        return f"### {title}\n\n(bench/{script} is not there yet)"
    res = subprocess.run(
        [python, str(path), *map(str, args)], env=run.ros.env, capture_output=True, text=True, timeout=300
    )
    if res.returncode != 0:
        return f"### {title}\n\n(bench/{script} failed, exit {res.returncode}:\n\n```\n{res.stderr[-1500:]}\n```)"
    out = res.stdout.strip()
    return f"### {title}\n\n" + (f"```\n{out}\n```" if code_block else out)


SECTIONS = (
    "throughput",
    "rates",
    "opcodes",
    "latency",
    "idle",
    "fanout",
    "large",
    "cloud",
    "isolation",
    "turtlesim",
    "convert",
    "page",
)


def main():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--rounds", type=int, default=3, help="runs of each measurement; the table shows medians")
    p.add_argument("--only", nargs="+", choices=SECTIONS, default=list(SECTIONS))
    p.add_argument(
        "--count",
        type=int,
        default=50000,
        help="Twist messages per throughput run (enough CPU ticks: /proc counts in 10 ms)",
    )
    p.add_argument("--fanout", type=int, nargs="+", default=[1, 100, 1000], help="client counts")
    p.add_argument("--no-readme", action="store_true", help="print the table only")
    peers.add_arguments(p)
    a = p.parse_args()
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))  # the bridge inherits it: 1000 clients need fds
    for sig in (signal.SIGINT, signal.SIGTERM):  # (even when started in the background) stop everything
        signal.signal(sig, lambda *_: sys.exit("bench: stopped by signal"))

    started, load_before = time.monotonic(), os.getloadavg()[0]
    table, extras = reporting.Table(), []
    run = Run(tempfile.mkdtemp(prefix="bench-"), a)
    try:
        sections = {
            "throughput": lambda: section_throughput(run, table, a.rounds, a.count),
            "rates": lambda: section_rates(run, table, a.rounds),
            "opcodes": lambda: section_opcodes(run, table),
            "latency": lambda: section_latency(run, table, a.rounds),
            "idle": lambda: section_idle(run, table, a.rounds),
            "isolation": lambda: section_isolation(run, table),
            "fanout": lambda: section_fanout(run, table, a.rounds, a.fanout),
            "large": lambda: section_large(run, table, a.rounds, 120),
            "cloud": lambda: section_cloud(run, table, a.rounds),
            "turtlesim": lambda: other_bench(run, "turtlesim_bench.py", "turtlesim_node (bench/turtlesim_bench.py)"),
            "convert": lambda: other_bench(
                run, "convert_bench.py", "ROS <-> JSON conversion (bench/convert_bench.py)", code_block=True
            ),
            "page": lambda: other_bench(
                run,
                "page_bench.py",
                "The page in Chromium (bench/page_bench.py)",
                python=str(REPO / ".build" / "venv" / "bin" / "python"),
                args=["--screenshot", run.workdir / "page-robot-console.png"],
            ),
        }
        for name in a.only:
            t = time.monotonic()
            extra = sections[name]()
            if extra:
                extras.append(extra)
            print(f"bench: {name} done in {time.monotonic() - t:.0f} s", file=sys.stderr, flush=True)
    finally:
        run.close()
    elapsed = time.monotonic() - started
    results = "\n\n".join(
        filter(
            None,
            [
                table.markdown(),
                "\n".join(f"- {n}" for n in table.notes),
                *extras,
                f"Measured {time.strftime('%Y-%m-%d')} on {os.cpu_count()} CPUs, {a.rounds} rounds (medians), "
                f"suite took {elapsed:.0f} s; load average {load_before:.1f} before, {os.getloadavg()[0]:.1f} after "
                "(other work on the machine slows the baselines and the bridge alike; the ratios are what to "
                "compare). "
                f"Logs: {run.workdir}",
            ],
        )
    )
    print(results)
    if not a.no_readme and set(a.only) == set(SECTIONS):
        template = (BENCH / "README.template.md").read_text()
        (BENCH / "README.md").write_text(template.replace("{{results}}", results))
        print(f"\nwrote {BENCH / 'README.md'}")


if __name__ == "__main__":
    main()
