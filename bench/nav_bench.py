"""The rover bench (issue 25): what a navigation rover publishes (bench/nav_robot.py, the messages of
bench/nav_messages.py), each stream measured through this bridge (JSON, CBOR, cbor-raw; the map also in fragments
of 100,000), the reference rosbridge_server 0.11.17, the ceiling (bench/nav_ceiling.py: the same bytes over a bare
Tornado websocket) and foxglove_bridge 0.8.5 (the messages' ROS bytes), in one run and one table; then every stream
at once to one client, as JSON, CBOR and with the map in fragments; then the map ten times after a run of clouds
and maps. The clients (bench/nav_clients.py) check every message they get against what was published.

    bash bench/run --only nav                # everything (about 20 minutes); rewrites its section of the READMEs
    bash bench/run --only nav --streams scan map --servers bridge ceiling --no-readme     # a part

It starts its own roscore on a free port and stops everything it started at the end, even on failure. A peer that
is not there (bench/peers.py) is skipped, with the reason, and the rest runs."""

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BENCH = Path(__file__).resolve().parent
REPO = BENCH.parent
sys.path.insert(0, str(REPO / "testkit"))
import nav_messages  # noqa: E402

import harness  # noqa: E402  (private roscore, process groups, logs, /proc readings)
import peers  # noqa: E402
import reporting  # noqa: E402
import stats  # noqa: E402
from reporting import fmt, markdown  # noqa: E402

PY = "/usr/bin/python3"
MARKERS = ("<!-- nav:start -->", "<!-- nav:end -->")
SERVERS = ("bridge", "reference", "ceiling", "foxglove")
NAMES = {
    "bridge": "this bridge",
    "reference": peers.REFERENCE_NAME,
    "ceiling": "the ceiling",
    "foxglove": peers.FOXGLOVE_NAME,
}
ENCODINGS = ("json", "cbor", "cbor-raw")  # (and, for the map, "fragments"; foxglove: "raw")
FRAGMENT_SIZE = 100_000
WARMUP, GRACE = 1.0, 1.0  # s before a window; after it, for what was stamped in it to arrive
BIG = 1_000_000  # ROS bytes from which a stream's CPU is given per MB, not per message
FRESH = 0.5  # s: the age (p95) of a fresh message (issue 26's goal for a small topic behind a 20 Mbit/s link)


def spec(stream, encoding):
    """A stream as nav_clients.py is told to subscribe to it."""
    if encoding == "raw":
        return stream
    if encoding == "fragments":
        return f"{stream}:json:{FRAGMENT_SIZE}"
    return f"{stream}:{encoding}"


class Server:
    """One running server: its process, ProcStat, websocket URL, the client role that speaks to it and the process
    that counts what was published (the generator, or the ceiling, which is its own source)."""

    def __init__(self, kind, proc, stat, url, source):
        self.kind, self.proc, self.stat, self.url, self.source = kind, proc, stat, url, source
        self.role = "foxglove" if kind == "foxglove" else "rosbridge"
        self.idle_rss = None


class Bench:
    def __init__(self, workdir, a):
        self.workdir, self.a = Path(workdir), a
        self.ros = harness.RosMaster(self.workdir).start()
        self.ros.env["PYTHONPATH"] = f"{BENCH}:{REPO / 'testkit'}:{self.ros.env.get('PYTHONPATH', '')}"
        self.spawned = 0
        self.robot = self.start([PY, BENCH / "nav_robot.py"], "nav_robot")
        self.wait_line(self.robot, r"^READY", 60)
        self.ros_bytes = {s.name: len(nav_messages.serialized(s.build())) for s in nav_messages.STREAMS}

    # ---- processes -----------------------------------------------------------------------------------------

    def start(self, args, name):
        self.spawned += 1
        return self.ros.spawn([str(x) for x in args], f"{self.spawned:03d}-{name}", stdin=subprocess.PIPE)

    def stop(self, *procs):
        for p in procs:
            if p is not None:
                p.stop()
                if p in self.ros.procs:
                    self.ros.procs.remove(p)

    def quit(self, *clients):
        """Clients end when told (a signal would wait for their stdin thread)."""
        for client in clients:
            if client is not None and client.alive():
                try:
                    client.popen.stdin.write(b"quit\n")
                    client.popen.stdin.flush()
                    client.popen.wait(3)
                except (OSError, subprocess.TimeoutExpired):
                    pass
        self.stop(*clients)

    @staticmethod
    def wait_line(proc, pattern, timeout, after=0, fail=True):
        """proc.wait_line, or None on timeout when not fail."""
        try:
            return proc.wait_line(pattern, timeout, after)
        except AssertionError:
            if fail:
                raise
            return None

    def ask(self, proc, command):
        before = len(re.findall(r"^RESULT ", proc.output(), re.M))
        proc.popen.stdin.write(f"{command}\n".encode())
        proc.popen.stdin.flush()
        return json.loads(self.wait_line(proc, r"^RESULT (.*)$", 60, after=before))

    def server(self, kind, **params):
        if kind == "bridge":
            proc, port = harness.launch_bridge(self.ros, node_name="nav_bridge")
            server = Server(
                kind,
                proc,
                harness.ProcStat(harness.node_pid(self.ros, "/nav_bridge")),
                f"ws://127.0.0.1:{port}/",
                self.robot,
            )
        elif kind == "reference":
            server = Server(
                kind, *peers.start_reference(self.ros, self.a, name=f"{self.spawned:03d}-reference"), self.robot
            )
        elif kind == "foxglove":
            server = Server(kind, *peers.start_foxglove(self.ros, self.a, name="nav_foxglove", **params), self.robot)
        else:
            port = harness.free_port()
            proc = self.start([PY, BENCH / "nav_ceiling.py", "--port", port, "--streams", *self.a.streams], "ceiling")
            self.wait_line(proc, r"^READY", 120)
            server = Server(kind, proc, harness.ProcStat(proc.pid), f"ws://127.0.0.1:{port}/", proc)
        time.sleep(1.0)
        server.idle_rss = server.stat.rss_mb()
        return server

    def client(self, server, specs):
        proc = self.start(
            [PY, BENCH / "nav_clients.py", server.role, "--url", server.url, *specs], f"client-{server.kind}"
        )
        self.wait_line(proc, r"^READY", 120)
        return proc

    # ---- one stream, alone ---------------------------------------------------------------------------------

    def streaming(self, server, name, encoding):
        """One client subscribed to one stream: after WARMUP, a window of --seconds."""
        client = self.client(server, [spec(name, encoding)])
        try:
            self.wait_line(client, rf"^GOT {name} ", 15, fail=False)  # (a server that fails it: measured anyway)
            time.sleep(WARMUP)
            server.stat.reset_peak_rss()
            cpu, t0 = stats.CpuWindow(server.stat), time.time()
            time.sleep(self.a.seconds)
            cpu_s, t1, peak = cpu.seconds(), time.time(), server.stat.peak_rss_mb()
            time.sleep(GRACE)
            got = self.ask(client, "result")
            published = self.ask(server.source, f"count {t0} {t1}")[name]
        finally:
            self.quit(client)
        time.sleep(0.5)
        figures = window_figures(got["streams"][name], t0, t1, published, self.ros_bytes[name])
        figures.update(cpu_s=cpu_s, peak_rss=peak, rss_after=server.stat.rss_mb(), statuses=got["statuses"][:3])
        figures["cpu"] = per_unit(cpu_s, figures["in_window"], self.ros_bytes[name])
        return figures

    def latched(self, server, name, encoding, timeout=60):
        """A client asks for a latched stream: until it has it (whole), the server's CPU and peak RSS; its RSS
        2 s later."""
        server.stat.reset_peak_rss()
        cpu, before = stats.CpuWindow(server.stat), server.stat.rss_mb()
        client = self.client(server, [spec(name, encoding)])
        try:
            came = self.wait_line(client, rf"^GOT {name} 1$", timeout, fail=False)
            cpu_s, peak = cpu.seconds(), server.stat.peak_rss_mb()
            time.sleep(2.0)
            after = server.stat.rss_mb()
            got = self.ask(client, "result")
        finally:
            self.quit(client)
        record = got["streams"][name]
        arrived = record["arrivals"][0] if came and record["arrivals"] else None
        return {
            "delivered": 1.0 if arrived else 0.0,
            "after_asked": arrived[0] - record["asked"] if arrived else None,
            "wire_bytes": arrived[2] if arrived else None,
            "cpu_s": cpu_s if arrived else None,
            "cpu": per_unit(cpu_s, 1, self.ros_bytes[name]) if arrived else None,
            "rss_before": before,
            "peak_rss": peak,
            "rss_after": after,
            "checked": record["checked"],
            "wrong": record["wrong"],
            "first_wrong": record["first_wrong"],
            "statuses": got["statuses"][:3],
        }

    def fresh_latched(self, kind, name, encoding, **params):
        """The map on a server started for it (so that nothing of an earlier case is held)."""
        server = self.server(kind, **params)
        try:
            figures = self.latched(server, name, encoding, timeout=30 if kind == "foxglove" else 120)
            figures["idle_rss"] = server.idle_rss
            return figures
        finally:
            self.stop(server.proc)

    # ---- all at once -----------------------------------------------------------------------------------------

    def all_at_once(self, kind, encoding, map_encoding):
        """One client subscribed to every stream at once (the map as map_encoding, the others as encoding): whole
        and fresh? The window starts once the map is there."""
        server = self.server(kind)
        client = None
        try:
            server.stat.reset_peak_rss()
            names = [s.name for s in nav_messages.STREAMS if s.name in self.a.streams]
            client = self.client(server, [spec(n, map_encoding if n == "map" else encoding) for n in names])
            if "map" in names:
                self.wait_line(client, r"^GOT map 1$", 30 if kind == "foxglove" else 120, fail=False)
            time.sleep(WARMUP)
            cpu, t0 = stats.CpuWindow(server.stat), time.time()
            time.sleep(self.a.seconds * 2)
            cpu_s, t1 = cpu.seconds(), time.time()
            time.sleep(GRACE)
            got = self.ask(client, "result")
            published = self.ask(server.source, f"count {t0} {t1}")
            peak = server.stat.peak_rss_mb()
        finally:
            self.quit(client)
            self.stop(server.proc)
        figures = {
            "cpu_share": cpu_s / (t1 - t0),
            "peak_rss": peak,
            "idle_rss": server.idle_rss,
            "statuses": got["statuses"][:3],
            "status_count": got["status_count"],
            "streams": {},
        }
        for name, record in got["streams"].items():
            stream = nav_messages.BY_NAME[name]
            if stream.hz:
                f = window_figures(record, t0, t1, published[name], self.ros_bytes[name])
            else:
                first = record["arrivals"][0] if record["arrivals"] else None
                f = {
                    "delivered": 1.0 if first else 0.0,
                    "after_asked": first[0] - record["asked"] if first else None,
                    "checked": record["checked"],
                    "wrong": record["wrong"],
                    "first_wrong": record["first_wrong"],
                }
            figures["streams"][name] = f
        return figures

    # ---- the map again ---------------------------------------------------------------------------------------

    def map_again(self, run_seconds=30, times=10):
        """A fresh bridge sends a client the map (JSON) once (the readers made), then once more (the first,
        measured), then serves clouds (JSON and CBOR) and a map every 2 s (JSON and CBOR) for run_seconds, then the
        map `times` times more, one at a time: the CPU and peak RSS of each."""
        server = self.server("bridge")
        clients = []
        try:
            watcher = self.client(server, [spec("map", "json")])
            clients.append(watcher)
            self.wait_line(watcher, r"^GOT map 1$", 120)
            maps = [self.one_map(server, watcher, 2)]
            clients += [
                self.client(server, [spec("points", "json")]),
                self.client(server, [spec("points", "cbor"), spec("map", "cbor")]),
            ]
            end, n = time.monotonic() + run_seconds, 2
            while time.monotonic() < end:
                self.ask(self.robot, "map")
                n += 1
                self.wait_line(watcher, rf"^GOT map {n}$", 120)
                time.sleep(2.0)
            self.quit(*clients[1:])
            time.sleep(2.0)
            for _ in range(times):
                n += 1
                maps.append(self.one_map(server, watcher, n, publish=True))
        finally:
            self.quit(*clients)
            self.stop(server.proc)
        return {"first": maps[0], "again": maps[1:], "idle_rss": server.idle_rss}

    def one_map(self, server, watcher, n, publish=True):
        time.sleep(1.0)
        server.stat.reset_peak_rss()
        cpu = stats.CpuWindow(server.stat)
        if publish:
            self.ask(self.robot, "map")
        self.wait_line(watcher, rf"^GOT map {n}$", 120)
        cpu_s, peak = cpu.seconds(), server.stat.peak_rss_mb()
        time.sleep(1.0)
        return {"cpu_s": cpu_s, "peak_rss": peak, "rss_after": server.stat.rss_mb()}

    def close(self):
        self.ros.stop()


# ---- figures -------------------------------------------------------------------------------------------------


def window_figures(record, t0, t1, published, ros_bytes):
    """A stream's figures in the window [t0, t1) from a client's record: delivered (of what was published stamped
    in the window, the share that arrived by GRACE after it), ages (arrival - stamp) of what arrived in it, what
    the client found wrong."""
    arrivals = record["arrivals"]
    inside = [(at, stamp, size) for at, stamp, size in arrivals if t0 <= at < t1]
    on_time = {stamp for at, stamp, _ in arrivals if stamp is not None and t0 <= stamp < t1 and at <= t1 + GRACE}
    ages = sorted(at - stamp for at, stamp, _ in inside if stamp is not None)
    return {
        "delivered": len(on_time) / published if published else None,
        "published": published,
        "in_window": len(inside),
        "age_p50": stats.percentile(ages, 0.5),
        "age_p95": stats.percentile(ages, 0.95),
        "age_max": ages[-1] if ages else None,
        "wire_bytes": sum(size for _, _, size in inside) / len(inside) if inside else None,
        "checked": record["checked"],
        "wrong": record["wrong"],
        "first_wrong": record["first_wrong"],
    }


def per_unit(cpu_s, messages, ros_bytes):
    """CPU per message (µs), or per MB of ROS bytes (ms) for a big stream."""
    if not messages:
        return None
    if ros_bytes >= BIG:
        return cpu_s * 1e3 / (messages * ros_bytes / 1e6)
    return cpu_s * 1e6 / messages


# ---- the run ---------------------------------------------------------------------------------------------------


def measure(bench, a, remarks, loads):
    """Every case; returns {"streams": {(stream, server, encoding): figures}, "all": {...}, "again": {...}}."""
    results = {"streams": {}, "all": {}, "again": None}

    def attempt(what, run):
        try:
            return run()
        except Exception as error:  # (one broken case ends no run)
            remarks.append(f"{what}: the case failed: {str(error).strip().splitlines()[0][:200]}")
            print(f"nav: {remarks[-1]}", file=sys.stderr, flush=True)
            return None

    streaming = [n for n in a.streams if nav_messages.BY_NAME[n].hz]
    latched = [n for n in a.streams if not nav_messages.BY_NAME[n].hz]
    loads.append(("start", os.getloadavg()[0]))
    servers = {kind: attempt(f"{kind} start", lambda kind=kind: bench.server(kind)) for kind in a.servers}
    servers = {k: s for k, s in servers.items() if s}
    try:  # every streaming case, the servers taking turns on each (the machine's moods hit them alike)
        for name in streaming:
            for encoding in ENCODINGS:
                for kind, server in servers.items():
                    if kind == "foxglove" and encoding != ENCODINGS[0]:
                        continue
                    road = "raw" if kind == "foxglove" else encoding
                    print(f"nav: {name} {kind} {road}", file=sys.stderr, flush=True)
                    results["streams"][(name, kind, road)] = attempt(
                        f"{name}, {kind}, {road}", lambda: bench.streaming(server, name, road)
                    )
            loads.append((name, os.getloadavg()[0]))
        for name in [n for n in latched if n != "map"]:  # (tf_static: small, on the running servers)
            for kind, server in servers.items():
                for road in ["raw"] if kind == "foxglove" else ENCODINGS:
                    results["streams"][(name, kind, road)] = attempt(
                        f"{name}, {kind}, {road}", lambda: bench.latched(server, name, road)
                    )
    finally:
        bench.stop(*(s.proc for s in servers.values()))
    if "map" in latched:  # (each on a server of its own; rounds alternate the servers)
        runs = {}
        for _ in range(a.map_repeats):
            for kind in servers:
                for road in ["raw"] if kind == "foxglove" else [*ENCODINGS, "fragments"]:
                    print(f"nav: map {kind} {road}", file=sys.stderr, flush=True)
                    got = attempt(f"map, {kind}, {road}", lambda: bench.fresh_latched(kind, "map", road))
                    runs.setdefault((kind, road), []).append(got)
        for (kind, road), got in runs.items():
            results["streams"][("map", kind, road)] = median_figures([g for g in got if g])
        loads.append(("map", os.getloadavg()[0]))
        if "foxglove" in servers:  # (at its defaults its 10 MB send buffer limit drops the map: one with room)
            got = attempt(
                "map, foxglove, 100 MB",
                lambda: bench.fresh_latched("foxglove", "map", "raw", send_buffer_limit=100_000_000),
            )
            results["streams"][("map", "foxglove", "raw, send_buffer_limit 100 MB")] = got
    for kind, encoding, map_encoding in (
        ("bridge", "json", "json"),
        ("bridge", "cbor", "cbor"),
        ("bridge", "json", "fragments"),
        ("reference", "json", "json"),
        ("reference", "json", "fragments"),
        ("foxglove", "raw", "raw"),
    ):
        if kind in servers:
            print(f"nav: all at once {kind} {encoding} {map_encoding}", file=sys.stderr, flush=True)
            results["all"][(kind, encoding, map_encoding)] = attempt(
                f"all at once, {kind}, {map_encoding}", lambda: bench.all_at_once(kind, encoding, map_encoding)
            )
    loads.append(("all at once", os.getloadavg()[0]))
    if "map" in a.streams and "points" in a.streams and "bridge" in servers:
        print("nav: the map again", file=sys.stderr, flush=True)
        results["again"] = attempt("the map again", bench.map_again)
    loads.append(("end", os.getloadavg()[0]))
    return results


def median_figures(runs):
    if not runs:
        return None
    out = dict(runs[0])
    for key, value in runs[0].items():
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            values = [r[key] for r in runs if r.get(key) is not None]
            out[key] = statistics.median(values) if values else None
    out["repeats"] = len(runs)
    return out


# ---- the report ------------------------------------------------------------------------------------------------


def ratio(a, b):
    return a / b if a is not None and b else None


def right(f):
    """What the client found: every message whole and right, or how many were not."""
    if not f:
        return "n/a"
    if not f.get("checked"):
        return "none came"
    return "all" if not f.get("wrong") else f"{f['wrong']} of {f['checked']} wrong: {f['first_wrong'][:60]}"


def streams_table(results, ros_bytes):
    head = [
        "Stream",
        "Encoding",
        "Bridge CPU",
        f"{peers.REFERENCE_NAME} (same encoding)",
        "Ratio",
        "Ceiling (same bytes)",
        "Ratio",
        f"{peers.FOXGLOVE_NAME} (ROS bytes)",
        "Ratio",
        "Delivered: bridge / reference / ceiling / foxglove",
        "Age p95 (latched: arrived after being asked): bridge / reference / ceiling / foxglove",
        "Peak RSS: bridge / reference / foxglove",
        "RSS after: bridge / reference / foxglove",
        "Whole and right: bridge; reference; foxglove",
    ]
    rows, s = [], results["streams"]
    for stream in nav_messages.STREAMS:
        unit = "ms/MB" if ros_bytes[stream.name] >= BIG else "µs/msg"
        fox = s.get((stream.name, "foxglove", "raw")) or {}
        for road in [*ENCODINGS, "fragments"]:
            ours = s.get((stream.name, "bridge", road))
            if ours is None:
                continue
            ref = s.get((stream.name, "reference", road)) or {}
            ceiling = s.get((stream.name, "ceiling", road)) or {}
            age = "after_asked" if not stream.hz else "age_p95"
            rows.append(
                [
                    f"{stream.name} ({_rate(stream)}, {ros_bytes[stream.name]:,} B)",
                    road,
                    fmt(ours.get("cpu"), unit),
                    fmt(_cpu(ref), unit),
                    fmt(ratio(ours.get("cpu"), _cpu(ref)), "x"),
                    fmt(ceiling.get("cpu"), unit),
                    fmt(ratio(ours.get("cpu"), ceiling.get("cpu")), "x"),
                    fmt(_cpu(fox), unit),
                    fmt(ratio(ours.get("cpu"), _cpu(fox)), "x"),
                    " / ".join(fmt(f.get("delivered"), "%") for f in (ours, ref, ceiling, fox)),
                    " / ".join(fmt(f.get(age), "s") for f in (ours, ref, ceiling, fox)),
                    " / ".join(fmt(f.get("peak_rss"), "MB") for f in (ours, ref, fox)),
                    " / ".join(fmt(f.get("rss_after"), "MB") for f in (ours, ref, fox)),
                    f"{right(ours)}; {right(ref)}; {right(fox)}",
                ]
            )
    return markdown(head, ["---"] * 2 + ["---:"] * 11 + ["---"], rows)


def _cpu(f):
    """A server's CPU figure, if what it spent it on arrived."""
    return f.get("cpu") if f and f.get("delivered") else None


def _rate(stream):
    return f"{stream.hz} Hz" if stream.hz else "latched"


ALL_CASES = {
    ("bridge", "json", "json"): "bridge, JSON",
    ("bridge", "cbor", "cbor"): "bridge, CBOR",
    ("bridge", "json", "fragments"): "bridge, JSON, the map in fragments",
    ("reference", "json", "json"): "reference, JSON",
    ("reference", "json", "fragments"): "reference, JSON, the map in fragments",
    ("foxglove", "raw", "raw"): "foxglove_bridge",
}


def all_table(results):
    cases = [(key, name) for key, name in ALL_CASES.items() if results["all"].get(key)]
    head = ["Stream"] + [name for _, name in cases]
    rows = []
    for stream in nav_messages.STREAMS:
        if not any(stream.name in results["all"][key]["streams"] for key, _ in cases):
            continue
        cells = [stream.name]
        for key, _ in cases:
            f = results["all"][key]["streams"].get(stream.name)
            if f is None:
                cells.append("")
            elif stream.hz:
                cells.append(f"{fmt(f['delivered'], '%')}, p95 {fmt(f['age_p95'], 's')}, right: {right(f)}")
            else:
                cells.append(f"after {fmt(f['after_asked'], 's')}, right: {right(f)}")
        rows.append(cells)
    for label, key, unit in (("server CPU (share of a core)", "cpu_share", "%"), ("server peak RSS", "peak_rss", "MB")):
        rows.append([label] + [fmt(results["all"][k][key], unit) for k, _ in cases])
    return markdown(head, ["---"] + ["---:"] * len(cases), rows)


def targets(results, ros_bytes):
    """Issue 25's goals for the rover's streams, each as (goal, figures, met)."""
    s, out = results["streams"], []

    def versus(stream, road, limit, what):
        ours, ref = s.get((stream, "bridge", road)), s.get((stream, "reference", road))
        r = ratio((ours or {}).get("cpu"), _cpu(ref))
        out.append(
            (
                f"{what}: bridge CPU per MB <= {limit}x the reference's",
                f"{fmt((ours or {}).get('cpu'), 'ms/MB')} against {fmt(_cpu(ref), 'ms/MB')}: {fmt(r, 'x')}",
                r is not None and r <= limit,
            )
        )

    if ("map", "bridge", "json") in s:
        versus("map", "json", 0.5, "map as JSON")
        ours, ref = s[("map", "bridge", "json")] or {}, s.get(("map", "reference", "json")) or {}
        if ours.get("peak_rss") is not None:
            out.append(
                (
                    "map as JSON: peak RSS <= the reference's",
                    f"{fmt(ours['peak_rss'], 'MB')} against {fmt(ref.get('peak_rss'), 'MB')}",
                    ref.get("peak_rss") is not None and ours["peak_rss"] <= ref["peak_rss"],
                )
            )
            above, text = ours["peak_rss"] - ours["idle_rss"], (ours.get("wire_bytes") or 0) / 1e6
            out.append(
                (
                    "map as JSON: peak RSS above idle <= 3x the JSON text",
                    f"{fmt(above, 'MB')} above "
                    f"{fmt(ours['idle_rss'], 'MB')}, the text {text:.1f} MB: {above / text:.2f}x"
                    if text
                    else "n/a",
                    bool(text) and above <= 3 * text,
                )
            )
    if ("map", "bridge", "cbor") in s:
        versus("map", "cbor", 0.25, "map as CBOR")
    if ("points", "bridge", "cbor") in s:
        versus("points", "cbor", 0.3, "cloud as CBOR")
    again = results.get("again")
    if again:
        first = again["first"]
        for key, label in (("cpu_s", "CPU"), ("peak_rss", "peak RSS")):
            values = [m[key] for m in again["again"]]
            mid = statistics.median(values)
            out.append(
                (
                    f"the map (JSON) sent ten times after a run of clouds and maps: its {label} within 10 % of "
                    "the first time (the median of the ten)",
                    f"first {_num(first[key], key)}, then median {_num(mid, key)} (lowest "
                    f"{_num(min(values), key)}, highest {_num(max(values), key)}, 10th {_num(values[-1], key)}): "
                    f"{mid / first[key]:.2f}x",
                    abs(mid / first[key] - 1) <= 0.10,
                )
            )
    for key, name in ALL_CASES.items():
        f = results["all"].get(key)
        if not f or key[0] != "bridge":
            continue
        wrong = [n for n, g in f["streams"].items() if g.get("wrong") or not g.get("delivered")]
        stale = [
            f"{n} {fmt(g['age_p95'], 's')}"
            for n, g in f["streams"].items()
            if nav_messages.BY_NAME[n].hz and (g.get("age_p95") is None or g["age_p95"] > FRESH)
        ]
        tf = f["streams"].get("tf_static", {}).get("after_asked")
        least = min(
            (
                g["delivered"]
                for n, g in f["streams"].items()
                if nav_messages.BY_NAME[n].hz and g.get("delivered") is not None
            ),
            default=None,
        )
        out.append(
            (
                f"every stream at once to one client ({name}): every message whole and right, every stream "
                f"there, fresh (age p95 <= {FRESH * 1e3:.0f} ms), /tf_static within 1 s of being asked",
                f"not right or missing: {', '.join(wrong) or 'none'}; older: {', '.join(stale) or 'none'}; "
                f"/tf_static after {fmt(tf, 's')}; the least delivered {fmt(least, '%')}",
                not wrong and not stale and tf is not None and tf <= 1.0,
            )
        )
    return out


def _num(value, key):
    return fmt(value, "s") if key == "cpu_s" else fmt(value, "MB")


def render(results, ros_bytes, remarks, footer):
    s = results["streams"]
    goals = targets(results, ros_bytes)
    parts = [
        streams_table(results, ros_bytes),
        "Every stream at once, one client (the window starts once the map is there, and lasts twice as long):",
        all_table(results) if results["all"] else "(not measured)",
        "Issue 25's goals, same run:",
        "\n".join(f"- {goal}: {text}: {'met' if ok else '**missed**'}" for goal, text, ok in goals),
    ]
    again = results.get("again")
    if again:
        parts.append(
            "The map again (JSON, one client; clouds and maps between): CPU / peak RSS / RSS after of each, "
            "the first, then the ten: "
            + "; ".join(
                f"{fmt(m['cpu_s'], 's')} / {fmt(m['peak_rss'], 'MB')} / {fmt(m['rss_after'], 'MB')}"
                for m in [again["first"], *again["again"]]
            )
            + f" (idle {fmt(again['idle_rss'], 'MB')})."
        )
    fox = s.get(("map", "foxglove", "raw, send_buffer_limit 100 MB"))
    if fox:
        parts.append(
            f"foxglove_bridge with `send_buffer_limit` 100 MB (its default, 10 MB, drops the 16 MB map): the "
            f"map {fmt(fox.get('cpu'), 'ms/MB')}, after {fmt(fox.get('after_asked'), 's')}, peak RSS "
            f"{fmt(fox.get('peak_rss'), 'MB')}, right: {right(fox)}."
        )
    notes = []
    for (name, kind, road), f in sorted(s.items(), key=lambda kv: str(kv[0])):
        if f and f.get("statuses"):
            notes.append(f"{name}, {kind}, {road}: status `{f['statuses'][0][1][:150]}`")
    for key, f in results["all"].items():
        if f and f.get("status_count"):
            notes.append(
                f"all at once, {ALL_CASES[key]}: {f['status_count']} status op(s), the first "
                f"`{f['statuses'][0][1][:150]}`"
            )
    if notes:
        parts.append("What the servers said (status ops):\n\n" + "\n".join(f"- {n}" for n in notes))
    return "\n\n".join(parts + remarks + [footer])


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--servers", nargs="+", choices=SERVERS, default=list(SERVERS))
    p.add_argument("--streams", nargs="+", choices=list(nav_messages.BY_NAME), default=list(nav_messages.BY_NAME))
    p.add_argument("--seconds", type=float, default=5.0, help="each streaming case's window, after 1 s of warm-up")
    p.add_argument("--map-repeats", type=int, default=2, help="the map's cases, each on a fresh server (medians)")
    p.add_argument("--no-readme", action="store_true")
    p.add_argument(
        "--render",
        metavar="DIR",
        help="print the text of an earlier run from its directory's run.json, measuring nothing",
    )
    peers.add_arguments(p)
    a = p.parse_args()
    if a.render:
        run = json.loads((Path(a.render) / "run.json").read_text())
        results = {
            "streams": {tuple(json.loads(k)): v for k, v in run["streams"].items()},
            "all": {tuple(json.loads(k)): v for k, v in run["all"].items()},
            "again": run["again"],
        }
        ros_bytes = run.get("ros_bytes") or {
            s.name: len(nav_messages.serialized(s.build())) for s in nav_messages.STREAMS
        }
        print(render(results, ros_bytes, run["remarks"], run["footer"]))
        return
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: sys.exit("nav: stopped by signal"))
    remarks = []
    for kind, missing in (("reference", peers.reference_missing), ("foxglove", peers.foxglove_missing)):
        why = missing(a) if kind in a.servers else None
        if why:
            a.servers.remove(kind)
            remarks.append(f"{NAMES[kind]} not measured: {why}.")
            print(f"nav: {remarks[-1]}", file=sys.stderr)
    full = set(a.servers) == set(SERVERS) and set(a.streams) == set(nav_messages.BY_NAME) and not a.no_readme
    started, code, digest, loads = time.monotonic(), reporting.code_state(), reporting.code_digest(), []
    workdir = Path(tempfile.mkdtemp(prefix="nav-"))
    bench = Bench(workdir, a)
    try:
        results = measure(bench, a, remarks, loads)
    finally:
        bench.close()
    if reporting.code_digest() != digest:
        remarks.append(
            f"The bridge's or the page's code (src/, web/) changed during the run ({code} -> {reporting.code_state()})."
        )
    footer = (
        f"Measured {time.strftime('%Y-%m-%d %H:%M')} at {reporting.git_head()} (code {code}) on "
        f"{os.cpu_count()} CPUs, {a.seconds:.0f} s per streaming case after {WARMUP:.0f} s of warm-up, the map "
        f"{a.map_repeats} times on each road (medians); took {time.monotonic() - started:.0f} s; load average "
        + ", ".join(f"{load:.1f} ({when})" for when, load in loads)
        + f". Logs: {workdir}"
    )
    (workdir / "run.json").write_text(
        json.dumps(
            {
                "streams": {json.dumps(k): v for k, v in results["streams"].items()},
                "all": {json.dumps(k): v for k, v in results["all"].items()},
                "again": results["again"],
                "ros_bytes": bench.ros_bytes,
                "remarks": remarks,
                "footer": footer,
            }
        )
    )
    text = render(results, bench.ros_bytes, remarks, footer)
    print(text)
    if full:
        reporting.write_section(MARKERS, text)


if __name__ == "__main__":
    main()
