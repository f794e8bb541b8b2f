"""The bad-link benchmark (issue 26): a rover's 50 Hz small topic and 15 Hz 640x480 rgb8 camera, watched from
behind a shaped link, by a roslibjs-style client, a careful client and the console in headless Chromium.

The link: a network namespace joined to this one by a veth pair. The server under test (the bridge, or the plain
baseline) listens on the veth's address here; the clients run inside the namespace (`ip netns exec`). Each side's
egress is shaped with `tc qdisc ... tbf rate <R>mbit burst 32kbit latency 50ms` (netem does not work on these
machines). Every case starts its own server; each server is measured beside the plain baseline
(bench/plain_server.py) with the same client on the same link in the same run. Needs root.

Run it with `bash bench/run --only badlink [options]` (or `/usr/bin/python3 bench/badlink.py` after sourcing
.build/setup.bash). It starts its own roscore on a free port, and stops everything it started (namespace and
veth included) at the end, even on failure. With every case (no --links/--clients/--pictures/--servers given,
no --no-readme) it rewrites its section of bench/README.template.md and bench/README.md."""

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BENCH = Path(__file__).resolve().parent
REPO = BENCH.parent
sys.path.insert(0, str(REPO / "testkit"))
import harness  # noqa: E402  (private roscore, process groups, logs, /proc readings)
import peers  # noqa: E402
import reporting  # noqa: E402
import stats  # noqa: E402
from reporting import fmt  # noqa: E402

PY = "/usr/bin/python3"
VENV_PY = str(REPO / ".build" / "venv" / "bin" / "python")  # (Selenium)
TBF = "burst 32kbit latency 50ms"
LINKS = (20, 5)  # Mbit/s
CLIENTS = ("roslibjs", "careful", "console", "driver")
DRIVER_CUTS = ("kill", "cut")  # how a driver goes away: its process killed, its link cut
PICTURES = ("camera-like", "busy")
SERVERS = ("bridge", "plain", "reference")
SMALL, CAMERA = "/rover/stamp", "/rover/camera"
CAMERA_HZ, SMALL_HZ = 15, 50
GRACE = 1.0  # s after the window: a small message stamped in the window counts as delivered if it came by then
MARKERS = ("<!-- badlink:start -->", "<!-- badlink:end -->")


def sh(*args, check=True):
    res = subprocess.run(list(args), capture_output=True, text=True)
    if check and res.returncode != 0:
        raise RuntimeError(f"{' '.join(args)}: {res.stderr.strip()}")
    return res


class Link:
    """A namespace `ns` joined by a veth pair: `here` (this namespace, address .1) and `there` (.2, inside)."""

    def __init__(self):
        pid = os.getpid()
        self.ns = f"badlink{pid}"
        self.here, self.there = f"bl{pid}a", f"bl{pid}b"
        net = f"10.78.{pid % 250}"
        self.server_addr, self.client_addr = f"{net}.1", f"{net}.2"
        self.rate = None

    def up(self):
        sh("ip", "netns", "add", self.ns)
        sh("ip", "link", "add", self.here, "type", "veth", "peer", "name", self.there, "netns", self.ns)
        sh("ip", "addr", "add", f"{self.server_addr}/24", "dev", self.here)
        sh("ip", "link", "set", self.here, "up")
        sh("ip", "-n", self.ns, "addr", "add", f"{self.client_addr}/24", "dev", self.there)
        sh("ip", "-n", self.ns, "link", "set", self.there, "up")
        sh("ip", "-n", self.ns, "link", "set", "lo", "up")
        return self

    def shape(self, mbit):
        """tbf on both ends' egress: the server -> client direction is the one that matters; the other carries
        the client's requests and TCP's acknowledgements, shaped alike (a Wi-Fi link is one shared medium)."""
        sh("tc", "qdisc", "replace", "dev", self.here, "root", "tbf", "rate", f"{mbit}mbit", *TBF.split())
        sh(
            "ip",
            "netns",
            "exec",
            self.ns,
            "tc",
            "qdisc",
            "replace",
            "dev",
            self.there,
            "root",
            "tbf",
            "rate",
            f"{mbit}mbit",
            *TBF.split(),
        )
        self.rate = mbit

    def qdisc(self):
        """(packets dropped so far, bytes queued now) of the server side's tbf."""
        out = sh("tc", "-s", "qdisc", "show", "dev", self.here).stdout
        dropped = re.search(r"dropped (\d+)", out)
        backlog = re.search(r"backlog (\d+)b", out)
        return int(dropped.group(1)) if dropped else 0, int(backlog.group(1)) if backlog else 0

    def down(self):
        sh("ip", "link", "del", self.here, check=False)  # (deleting the namespace would delete it too)
        sh("ip", "netns", "del", self.ns, check=False)


def netns_unavailable():
    if os.geteuid() != 0:
        return "needs root (network namespaces, tc)"
    probe = f"blprobe{os.getpid()}"
    if shutil.which("ip") is None or shutil.which("tc") is None:
        return "needs iproute2 (ip, tc)"
    res = sh("ip", "netns", "add", probe, check=False)
    if res.returncode != 0:
        return f"`ip netns add` fails here: {res.stderr.strip()}"
    try:
        res = subprocess.run(["ip", "netns", "exec", probe, "true"], capture_output=True, text=True, timeout=30)
        return None if res.returncode == 0 else f"`ip netns exec` fails here: {res.stderr.strip()}"
    finally:
        sh("ip", "netns", "del", probe, check=False)


class Bench:
    def __init__(self, workdir, a):
        self.workdir = Path(workdir)
        self.shots = self.workdir / "shots"
        self.shots.mkdir(parents=True, exist_ok=True)
        self.a = a
        self.ros = harness.RosMaster(self.workdir).start()
        self.ros.env["PYTHONPATH"] = f"{BENCH}:{REPO / 'testkit'}:{self.ros.env.get('PYTHONPATH', '')}"
        self.link = Link().up()
        self.rover = None
        self.picture = None
        self.spawned = 0
        self.before_ws = None
        self.sizes = {}  # picture -> its sizes, as the rover printed them

    def spawn(self, args, name, inside=False):
        self.spawned += 1
        if inside:
            args = ["ip", "netns", "exec", self.link.ns, *args]
        return self.ros.spawn([str(x) for x in args], f"{self.spawned:02d}-{name}", stdin=subprocess.PIPE)

    def stop(self, *procs):
        for p in procs:
            if p is None:
                continue
            p.stop()
            if p in self.ros.procs:
                self.ros.procs.remove(p)

    @staticmethod
    def tell(proc, line):
        proc.popen.stdin.write(f"{line}\n".encode())
        proc.popen.stdin.flush()

    @staticmethod
    def wait_line(proc, pattern, timeout, after=0):
        return proc.wait_line(pattern, timeout, after)

    def result(self, proc, timeout=60):
        before = len(re.findall(r"^RESULT (.*)$", proc.output(), re.M))
        self.tell(proc, "result")
        return json.loads(self.wait_line(proc, r"^RESULT (.*)$", timeout, after=before))

    # ---- the rover -----------------------------------------------------------------------------------------

    def show(self, picture):
        """The rover, publishing `picture`."""
        if self.picture == picture:
            return
        self.stop(self.rover)
        self.rover = self.spawn([PY, BENCH / "rover.py", "--picture", picture], f"rover-{picture}")
        self.wait_line(self.rover, r"^READY", 60)
        self.picture = picture
        self.sizes[picture] = json.loads(re.search(r"^PICTURE (.*)$", self.rover.output(), re.M).group(1))

    def published(self, t0, t1):
        before = len(re.findall(r"^RESULT (.*)$", self.rover.output(), re.M))
        self.tell(self.rover, f"count {t0} {t1}")
        return json.loads(self.wait_line(self.rover, r"^RESULT (.*)$", 20, after=before))

    # ---- servers -------------------------------------------------------------------------------------------

    def server(self, kind):
        """(proc, ProcStat of the serving process, websocket URL, page URL)."""
        addr = self.link.server_addr
        if kind == "bridge":
            proc, port = harness.launch_bridge(self.ros, node_name="badlink_bridge", address=addr)
            stat = harness.ProcStat(harness.node_pid(self.ros, "/badlink_bridge"))
            return proc, stat, f"ws://{addr}:{port}/", f"http://{addr}:{port}/"
        if kind == "before":  # the same launch file, from the workspace of the --before commit
            master, param = self.ros.master(), "/badlink_before/actual_port"
            if master.hasParam(param):
                master.deleteParam(param)
            proc = self.spawn(
                [
                    "bash",
                    "-c",
                    f"source {self.before_ws}/devel/setup.bash && exec roslaunch turtlesim "
                    f"rosbridge_websocket.launch port:=0 address:={addr} node_name:=badlink_before",
                ],
                "before",
            )

            def port():
                if not proc.alive():
                    raise RuntimeError(f"the bridge of {self.a.before} ended:\n{proc.output()[-3000:]}")
                return master.getParam(param) if master.hasParam(param) else None

            port = harness.wait_for(port, 60, what=param)
            stat = harness.ProcStat(harness.node_pid(self.ros, "/badlink_before"))
            return proc, stat, f"ws://{addr}:{port}/", f"http://{addr}:{port}/"
        if kind == "reference":  # its own launch file, from its own workspace; it serves no page
            self.spawned += 1
            proc, stat, url = peers.start_reference(self.ros, self.a, addr, f"{self.spawned:02d}-reference")
            return proc, stat, url, None
        port = harness.free_port()
        proc = self.spawn([PY, BENCH / "plain_server.py", "--address", addr, "--port", port], "plain")
        self.wait_line(proc, r"^READY", 30)
        return proc, harness.ProcStat(proc.pid), f"ws://{addr}:{port}/ws", f"http://{addr}:{port}/"

    # ---- one case ------------------------------------------------------------------------------------------

    @property
    def deflate_arg(self):
        """The websocket clients offer permessage-deflate, as browsers and roslibjs in Node do, unless --no-deflate."""
        return ["--no-deflate"] if self.a.no_deflate else []

    def client(self, kind, ws_url, page_url, server):
        if kind == "console":
            proc = self.spawn(
                [
                    VENV_PY,
                    BENCH / "badlink_clients.py",
                    "console",
                    "--url",
                    page_url,
                    "--mode",
                    "plain" if server == "plain" else "bridge",
                    *(["--phone"] if self.a.phone else []),
                ],
                f"console-{server}",
                inside=True,
            )
        else:
            proc = self.spawn(
                [PY, BENCH / "badlink_clients.py", "ws", "--url", ws_url, "--style", kind, *self.deflate_arg],
                f"{kind}-{server}",
                inside=True,
            )
        self.wait_line(proc, r"^READY", 120)
        return proc

    def case(self, mbit, kind, picture, server):
        name = f"{mbit}mbit-{kind}-{picture}-{server}"
        print(f"badlink: {name}", file=sys.stderr, flush=True)
        self.show(picture)
        self.link.shape(mbit)
        code = reporting.code_state() if server == "bridge" else None
        srv, stat, ws_url, page_url = self.server(server)
        client = None
        try:
            time.sleep(1.0)
            rss0 = stat.rss_mb()
            client = self.client(kind, ws_url, page_url, server)
            time.sleep(self.a.warmup)
            drops0 = self.link.qdisc()[0]
            t0, cpu0, rss, backlog = time.time(), stat.cpu_seconds(), [], []
            while time.time() < t0 + self.a.seconds:
                rss.append(stat.rss_mb())
                backlog.append(self.link.qdisc()[1])
                time.sleep(0.5)
            t1, cpu1 = time.time(), stat.cpu_seconds()
            rss.append(stat.rss_mb())
            drops = self.link.qdisc()[0] - drops0
            time.sleep(GRACE)
            got = self.result(client)
            if kind == "console":
                for n in range(2 if server == "bridge" else 1):
                    path = self.shots / f"{name}-{n}.png"
                    self.tell(client, f"shot {path}")
                    self.wait_line(client, r"^SHOT ", 30, after=n)
                    time.sleep(1.5)
            published = self.published(t0, t1)
        finally:
            self.stop(client, srv)
        figures = summarize(got, kind, t0, t1, published)
        figures.update(
            rss_growth=max(rss) - rss0,
            rss_end_growth=rss[-1] - rss0,
            cpu_s=cpu1 - cpu0,
            cpu_ms_per_frame=(cpu1 - cpu0) * 1e3 / figures["camera_frames"] if figures["camera_frames"] else None,
            cpu_share=(cpu1 - cpu0) / (t1 - t0),
            tbf_drops=drops,
            tbf_backlog_max=max(backlog),
            tbf_backlog_p50=stats.percentile(backlog, 0.5),
            code=code,
        )
        (self.workdir / f"{name}.json").write_text(json.dumps({"figures": figures, "raw": got}))
        print(
            f"badlink: {name}: "
            + json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in figures.items()}),
            file=sys.stderr,
            flush=True,
        )
        return figures

    def drive(self, mbit, server, how):
        """A driver (watching the camera) publishes Twist at 20 Hz, then is killed (its connection ends) or its
        link is cut (the namespace's end of the veth goes down: no FIN, as when a phone loses Wi-Fi). Returns
        when the rover got a zero Twist after that, and the ages of the Twists before it."""
        name = f"{mbit}mbit-driver-{how}-{server}"
        print(f"badlink: {name}", file=sys.stderr, flush=True)
        self.show(self.picture or "camera-like")
        self.link.shape(mbit)
        code = reporting.code_state() if server == "bridge" else None
        srv, stat, ws_url, _ = self.server(server)
        client = None
        try:
            client = self.spawn(
                [PY, BENCH / "badlink_clients.py", "driver", "--url", ws_url, *self.deflate_arg],
                f"driver-{server}",
                inside=True,
            )
            self.wait_line(client, r"^READY", 60)
            time.sleep(3.0)
            self.twists()  # (forget the start)
            time.sleep(3.0)
            end = time.time()
            if how == "kill":
                os.kill(client.pid, signal.SIGKILL)  # (ip netns exec execs the driver: this is its pid)
            else:
                sh("ip", "-n", self.link.ns, "link", "set", self.link.there, "down")
            time.sleep(4.0)
            twists = self.twists()
        finally:
            if how == "cut":
                sh("ip", "-n", self.link.ns, "link", "set", self.link.there, "up")
            self.stop(client, srv)
        before = [(t, z) for t, x, z in twists if x != 0 and t < end + 2.0]
        zero = next((t for t, x, z in twists if x == 0 and z == 0 and t >= end - 0.05), None)
        last = max((t for t, _ in before), default=None)
        ages = [t - z for t, z in before if t < end]
        figures = {
            "how": how,
            "zero_after_end": zero - end if zero else None,
            "zero_after_last": zero - last if zero and last else None,
            "zeros": sum(1 for t, x, z in twists if x == 0 and z == 0 and t >= end - 0.05),
            "twist_p50": stats.percentile(ages, 0.5),
            "twist_p95": stats.percentile(ages, 0.95),
            "twist_max": max(ages, default=None),
            "twist_rate": len(ages) / 3.0,
            "code": code,
        }
        (self.workdir / f"{name}.json").write_text(json.dumps({"figures": figures, "raw": twists}))
        print(f"badlink: {name}: " + json.dumps(figures), file=sys.stderr, flush=True)
        return figures

    def twists(self):
        before = len(re.findall(r"^RESULT (.*)$", self.rover.output(), re.M))
        self.tell(self.rover, "twists")
        return json.loads(self.wait_line(self.rover, r"^RESULT (.*)$", 20, after=before))["twists"]

    def raw_capacity(self, mbit, seconds=4.0):
        """TCP goodput through the shaped link: a bulk sender here, the sink inside."""
        self.link.shape(mbit)
        port = harness.free_port()
        sink = self.spawn(
            [PY, BENCH / "badlink_clients.py", "sink", "--listen", f"{self.link.client_addr}:{port}"],
            "sink",
            inside=True,
        )
        try:
            self.wait_line(sink, r"^READY", 30)
            conn = harness.wait_for(lambda: peers.connect(self.link.client_addr, port), 10, what="the sink")
            block, end = b"\0" * 65536, time.monotonic() + seconds
            while time.monotonic() < end:
                conn.sendall(block)
            conn.close()
            return json.loads(self.wait_line(sink, r"^RESULT (.*)$", 30))["mbit"]
        finally:
            self.stop(sink)

    def close(self):
        try:
            self.stop(self.rover)
            self.ros.stop()
        finally:
            self.link.down()


def before_workspace(commit, log):
    """A catkin workspace of this package as it was at `commit` (git archive; the page's libraries copied from
    web/vendor/, which git does not hold), built once in ~/.cache/turtlesim/: the bridge of that commit, to
    measure beside today's. Returns (workspace, full commit hash)."""
    full = subprocess.run(
        ["git", "-C", str(REPO), "rev-parse", "--verify", f"{commit}^{{commit}}"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    ws = Path.home() / ".cache" / "turtlesim" / f"badlink-before-{full[:12]}"
    if (ws / "devel" / "setup.bash").exists():
        return ws, full
    shutil.rmtree(ws, ignore_errors=True)
    src = ws / "src" / "turtlesim"
    src.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(REPO), "archive", full], capture_output=True, check=True)
    subprocess.run(["tar", "x", "-C", str(src)], input=archive.stdout, check=True)
    shutil.copytree(REPO / "web" / "vendor", src / "web" / "vendor", dirs_exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k not in ("CMAKE_PREFIX_PATH", "ROS_PACKAGE_PATH", "PYTHONPATH")}
    with open(log, "w") as out:
        res = subprocess.run(
            ["catkin_make", "-C", str(ws), f"-DPYTHON_EXECUTABLE={PY}", "-DCMAKE_BUILD_TYPE=Release"],
            cwd=ws,
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    if res.returncode:
        shutil.rmtree(ws / "devel", ignore_errors=True)
        raise SystemExit(f"badlink: the bridge of {commit} did not build (log: {log})")
    return ws, full


def summarize(got, kind, t0, t1, published):
    """Figures of one case from the client's records (wall times) and the rover's counts for [t0, t1)."""
    seconds = t1 - t0
    if kind == "console":  # [[shown at, age]]
        camera = [(t, age) for t, age in got["camera"] if t0 <= t < t1]
        small = [(t, age) for t, age in got["small"] if t0 <= t < t1]
        delivered = None
        frames = [t for t in got["frames"] if t0 <= t < t1]
        seen = [(camera, small) for t, camera, small in got.get("in_view", []) if t0 <= t < t1]
        extra = {
            "page_fps": len(frames) / seconds,
            "element": got.get("element"),
            "readouts": got.get("readouts", [])[-3:],
            "both_on_screen": sum(c and s for c, s in seen) / len(seen) if seen else None,
        }
    else:  # [[arrived, stamp, bytes]]
        camera = [(t, t - stamp) for t, stamp, _ in got["camera"] if t0 <= t < t1]
        small = [(t, t - stamp) for t, stamp, _ in got["small"] if t0 <= t < t1]
        on_time = {stamp for t, stamp, _ in got["small"] if t0 <= stamp < t1 and t <= t1 + GRACE}
        delivered = len(on_time) / published["small"] if published["small"] else None
        wire = sum(size for t, _, size in got["camera"] + got["small"] if t0 <= t < t1)
        extra = {
            "kbyte_s": wire / seconds / 1e3,
            "status_count": got.get("status_count", 0),
            "statuses": got.get("statuses", [])[:2],
            "closed": bool(got.get("closed")),
        }

    def ages(rows, lo=0.0, hi=1.0):
        return [age for t, age in rows if t0 + lo * seconds <= t < t0 + hi * seconds]

    return {
        "small_delivered": delivered,
        "small_rate": len(small) / seconds,
        "small_p50": stats.percentile(ages(small), 0.5),
        "small_p95": stats.percentile(ages(small), 0.95),
        "small_max": max(ages(small), default=None),
        "small_p95_first": stats.percentile(ages(small, 0, 1 / 3), 0.95),
        "small_p95_last": stats.percentile(ages(small, 2 / 3, 1), 0.95),
        "camera_frames": len(camera),
        "camera_fps": len(camera) / seconds,
        "camera_p50": stats.percentile(ages(camera), 0.5),
        "camera_p95": stats.percentile(ages(camera), 0.95),
        "camera_max": max(ages(camera), default=None),
        "camera_p95_first": stats.percentile(ages(camera, 0, 1 / 3), 0.95),
        "camera_p95_last": stats.percentile(ages(camera, 2 / 3, 1), 0.95),
        "published_small": published["small"],
        "published_camera": published["camera"],
        **extra,
    }


# ---- the table ---------------------------------------------------------------------------------------------


PHONE = False  # (--phone: the console cases ran on a phone's screen)
EXTRA = {"reference": peers.REFERENCE_NAME}  # more servers measured: their columns' titles


def goals(mbit, kind, picture):
    """The issue's goals for a case, as {figure: (text, test)}; none for the cases it sets none for."""
    le = lambda x: lambda v: v is not None and v <= x  # noqa: E731
    ge = lambda x: lambda v: v is not None and v >= x  # noqa: E731
    if mbit == 20 and kind in ("roslibjs", "careful"):
        return {
            "small_delivered": (">= 95 %", ge(0.95)),
            "small_p95": ("<= 0.5 s", le(0.5)),
            "small_max": ("<= 1 s", le(1.0)),
            "camera_fps": (">= 1/s", ge(1.0)),
            "camera_p95": ("<= 1.5 s", le(1.5)),
            "rss_growth": ("<= 64 MB", le(64)),
        }
    if mbit == 5 and kind == "console" and picture == "camera-like":
        return {
            "camera_fps": (">= 14/s", ge(14)),
            "camera_p95": ("<= 100 ms", le(0.1)),
            "small_p95": ("<= 100 ms", le(0.1)),
        }
    if mbit == 5 and kind == "console" and picture == "busy":
        return {
            "camera_fps": (">= 10/s", ge(10)),
            "camera_p95": ("<= 250 ms", le(0.25)),
            "small_p95": ("<= 150 ms", le(0.15)),
        }
    return {}


CLIENT_NAMES = {
    "roslibjs": "roslibjs-style (JSON, no throttle, no queue)",
    "careful": "careful (camera CBOR, throttle_rate 66, queue_length 1)",
    "console": "the console in Chromium",
    "phone": "the console in Chromium on a phone's screen",
}


def table(results, capacity):
    primary = "bridge" if any(k[3] == "bridge" for k in results) else "before"
    t = reporting.Table(
        {
            server: EXTRA[server]
            for server in ("before", "reference")
            if server in EXTRA and server != primary and any(k[3] == server for k in results)
        }
    )
    for mbit in sorted({k[0] for k in results}, reverse=True):
        if mbit in capacity:
            t.row(
                f"{mbit} Mbit/s link: raw TCP goodput through it (one bulk sender)", capacity[mbit], "Mbit/s", "", None
            )
        for kind in CLIENTS:
            if kind == "driver":
                continue
            for picture in PICTURES:
                bridge = results.get((mbit, kind, picture, primary))
                if not bridge:
                    continue
                plain = results.get((mbit, kind, picture, "plain")) or {}
                others = {server: results.get((mbit, kind, picture, server)) or {} for server in t.extra}
                g = goals(mbit, kind, picture)
                name = "phone" if kind == "console" and PHONE else kind
                where = f"{mbit} Mbit/s, {CLIENT_NAMES[name]}" + (f", {picture} picture" if kind == "console" else "")
                base = "plain forwarder" if kind != "console" else "JPEG q50 page (rosboard's way)"

                def row(key, label, unit):
                    target, test = g.get(key, ("", None))
                    t.row(
                        f"{where}: {label}",
                        bridge.get(key),
                        unit,
                        base,
                        plain.get(key),
                        target,
                        test(bridge.get(key)) if test else None,
                        {k: v.get(key) for k, v in others.items()},
                    )

                def trend(key, label):
                    def text(f):
                        return f"{fmt(f.get(key + '_first'), 's')} -> {fmt(f.get(key + '_last'), 's')}" if f else ""

                    t.text_row(
                        f"{where}: {label} age p95, first third of the window -> last third",
                        text(bridge),
                        f"{base}: {text(plain)}" if plain else "",
                        {k: text(v) for k, v in others.items()},
                    )

                if kind != "console":
                    row("small_delivered", f"small topic delivered (within {GRACE:.0f} s)", "%")
                else:
                    row("small_rate", "small topic: new values shown", "/s")
                row("small_p50", "small topic age p50", "s")
                row("small_p95", "small topic age p95", "s")
                row("small_max", "small topic age max", "s")
                trend("small_p95", "small topic")
                row("camera_fps", "camera frames/s" + (" on screen" if kind == "console" else ""), "/s")
                row("camera_p50", "camera age p50" + (" (from the pixels)" if kind == "console" else ""), "s")
                row("camera_p95", "camera age p95", "s")
                trend("camera_p95", "camera")
                row("rss_growth", "server RSS growth", "MB")
                row("cpu_ms_per_frame", "server CPU per camera frame delivered", "ms")
        for how in DRIVER_CUTS:
            driven = results.get((mbit, "driver", how, primary))
            if not driven:
                continue
            others = {server: results.get((mbit, "driver", how, server)) or {} for server in t.extra}
            where = f"{mbit} Mbit/s, a driver (Twist at 20 Hz, watching the camera as the careful client)"

            def zero(f, key):
                return f.get(key) if f.get(key) is not None else (None if not f else float("nan"))

            if how == "kill":
                t.row(
                    f"{where}, killed: zero Twist after its connection's end",
                    zero(driven, "zero_after_end"),
                    "s",
                    "",
                    None,
                    "<= 0.5 s",
                    (driven.get("zero_after_end") or 9) <= 0.5,
                    {k: zero(v, "zero_after_end") for k, v in others.items()},
                )
            else:
                t.row(
                    f"{where}, its link cut (no FIN): zero Twist after the last Twist that arrived",
                    zero(driven, "zero_after_last"),
                    "s",
                    "",
                    None,
                    "<= 1 s (the timeout)",
                    (driven.get("zero_after_last") or 9) <= 1.0,
                    {k: zero(v, "zero_after_last") for k, v in others.items()},
                )
                t.text_row(
                    f"{where}: Twist age at the rover p50 / p95 / max (client -> ROS while the camera fills the link)",
                    " / ".join(fmt(driven.get(k), "s") for k in ("twist_p50", "twist_p95", "twist_max")),
                    "",
                    {k: fmt(v.get("twist_p95"), "s") for k, v in others.items() if v.get("twist_p95") is not None},
                )
    return t


def notes(results):
    lines = []
    for (mbit, kind, picture, server), f in sorted(results.items()):
        if kind == "driver":
            lines.append(
                f"- {mbit} Mbit/s, driver {picture}, {server}: {f['zeros']} zero Twist(s) after the end, "
                f"{f['twist_rate']:.1f} Twists/s arrived before it" + (f", code `{f['code']}`" if f.get("code") else "")
            )
            continue
        bits = [
            f"CPU {f['cpu_share'] * 100:.0f} %",
            f"tbf drops {f['tbf_drops']}",
            f"tbf queue p50 {f['tbf_backlog_p50'] / 1e3:.0f} kB, max {f['tbf_backlog_max'] / 1e3:.0f} kB",
        ]
        if kind == "console":
            bits += [f"page {f['page_fps']:.0f} frames/s", f"picture read from `{f.get('element')}`"]
            if f.get("both_on_screen") is not None:
                bits.append(f"camera and small topic both on screen {f['both_on_screen'] * 100:.0f} % of the time")
            readouts = [text for _, text in f.get("readouts") or []]
            if readouts:
                bits.append(f'its own readout at the end: "{readouts[-1].strip()}"')
        else:
            bits += [f"{f['kbyte_s']:.0f} kB/s to the client", f"{f['status_count']} status ops"]
            if f.get("statuses"):
                bits.append(f"first: `{f['statuses'][0][1][:120]}`")
            if f.get("closed"):
                bits.append("**the connection was closed**")
        if f.get("code"):
            bits.append(f"code `{f['code']}`")
        lines.append(
            f"- {mbit} Mbit/s, {kind}"
            + (f", {picture}" if kind == "console" else "")
            + f", {server}: "
            + ", ".join(bits)
        )
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--links", type=int, nargs="+", default=list(LINKS), help="Mbit/s")
    p.add_argument("--clients", nargs="+", choices=CLIENTS, default=list(CLIENTS))
    p.add_argument(
        "--pictures",
        nargs="+",
        choices=PICTURES,
        default=list(PICTURES),
        help="for the console (the websocket clients get the raw rgb8 picture: camera-like only)",
    )
    p.add_argument(
        "--servers",
        nargs="+",
        choices=SERVERS,
        default=list(SERVERS),
        help="reference: rosbridge_server 0.11.17, for the websocket clients (it serves no console)",
    )
    p.add_argument("--seconds", type=float, default=20.0, help="measured per case, after --warmup")
    p.add_argument("--warmup", type=float, default=5.0)
    p.add_argument(
        "--before",
        metavar="COMMIT",
        help="also measure the bridge (and its page) of this commit, built from git in ~/.cache/turtlesim",
    )
    peers.add_arguments(p)
    p.add_argument("--phone", action="store_true", help="the console on a phone's screen (390x844), not a desktop's")
    p.add_argument(
        "--no-deflate",
        action="store_true",
        help="the websocket clients offer no permessage-deflate "
        "(browsers and roslibjs in Node offer it; the console's Chromium always does)",
    )
    p.add_argument("--no-readme", action="store_true")
    p.add_argument(
        "--render",
        metavar="DIR",
        help="print (and with --readme, write) the text of an earlier run "
        "from its directory's run.json, measuring nothing",
    )
    p.add_argument("--readme", action="store_true", help="with --render: write the README sections")
    a = p.parse_args()
    global PHONE
    PHONE = a.phone
    if a.render:
        run = json.loads((Path(a.render) / "run.json").read_text())
        EXTRA.update(run["extra"])
        PHONE = run.get("phone", False)
        results = {tuple(json.loads(k)): v for k, v in run["results"].items()}
        text = render(
            results, {int(k): v for k, v in run["capacity"].items()}, run["sizes"], run["remarks"], run["footer"]
        )
        print(text)
        if a.readme:
            reporting.write_section(MARKERS, text)
        return
    reason = netns_unavailable()
    if reason:
        raise SystemExit(f"badlink: {reason}")
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: sys.exit("badlink: stopped by signal"))
    full = (
        a.links == list(LINKS)
        and a.clients == list(CLIENTS)
        and a.pictures == list(PICTURES)
        and a.servers == list(SERVERS)
        and not a.phone
        and not a.no_deflate
    )
    started, load_before = time.monotonic(), os.getloadavg()[0]
    workdir = Path(tempfile.mkdtemp(prefix="badlink-"))
    remarks = [
        (
            "The roslibjs-style and careful clients and the driver offered no permessage-deflate (--no-deflate)."
            if a.no_deflate
            else "The roslibjs-style and careful clients and the driver offered permessage-deflate "
            "(`permessage-deflate; client_max_window_bits`), as browsers and roslibjs in Node do."
        )
    ]
    if "reference" in a.servers:
        why = peers.reference_missing(a)
        if why:
            a.servers.remove("reference")
            remarks.append(f"{peers.REFERENCE_NAME} not measured: {why}.")
            print(f"badlink: {remarks[-1]}", file=sys.stderr)
    before_ws = None
    if a.before:
        before_ws, commit = before_workspace(a.before, workdir / "before-build.log")
        a.servers.insert(1, "before")
        when = subprocess.run(
            ["git", "-C", str(REPO), "log", "-1", "--format=%cd", "--date=format:%Y-%m-%d %H:%M", commit],
            capture_output=True,
            text=True,
        ).stdout.strip()
        EXTRA["before"] = f"the bridge before: `{commit[:7]}`"
        remarks.append(
            f'"The bridge before": the bridge and its page as of commit `{commit[:7]}` ({when}), '
            "built from git and measured in the same run."
        )
    bench = Bench(workdir, a)
    bench.before_ws = before_ws
    results, capacity, sizes = {}, {}, {}
    try:
        for picture in PICTURES:
            kinds = [k for k in a.clients if k == "console" or picture == "camera-like" and k != "driver"]
            if picture not in a.pictures and "console" in kinds:
                kinds.remove("console")
            if not kinds:
                continue
            bench.show(picture)
            for mbit in a.links:
                if mbit not in capacity:
                    capacity[mbit] = bench.raw_capacity(mbit)
                for kind in kinds:
                    for server in a.servers:
                        if server == "reference" and kind == "console":
                            continue
                        try:
                            results[(mbit, kind, picture, server)] = bench.case(mbit, kind, picture, server)
                        except Exception as error:  # (one broken case, e.g. a bridge mid-edit, ends no run)
                            remarks.append(
                                f"{mbit} Mbit/s, {kind}, {picture}, {server}: the case failed: "
                                f"{str(error).strip().splitlines()[0][:200]} (logs: {workdir})"
                            )
                            print(f"badlink: {remarks[-1]}", file=sys.stderr, flush=True)
        if "driver" in a.clients:  # (the dead-man stop does not depend on the rate: the narrowest link)
            for how in DRIVER_CUTS:
                for server in a.servers:
                    if server == "plain":  # (it takes no publish)
                        continue
                    try:
                        results[(min(a.links), "driver", how, server)] = bench.drive(min(a.links), server, how)
                    except Exception as error:
                        remarks.append(
                            f"driver {how}, {server}: the case failed: "
                            f"{str(error).strip().splitlines()[0][:200]} (logs: {workdir})"
                        )
                        print(f"badlink: {remarks[-1]}", file=sys.stderr, flush=True)
    finally:
        bench.close()
    sizes = {picture: bench.sizes[picture] for picture in PICTURES if picture in bench.sizes}
    elapsed = time.monotonic() - started
    footer = (
        f"Measured {time.strftime('%Y-%m-%d %H:%M')} at {reporting.git_head()} on {os.cpu_count()} CPUs, "
        f"{a.seconds:.0f} s per case after {a.warmup:.0f} s of warm-up; took {elapsed:.0f} s; load average "
        f"{load_before:.1f} before, {os.getloadavg()[0]:.1f} after (the machine's other work shares its 2 "
        f"cores with the rover, the servers, the clients and Chromium). Logs, screenshots and raw records: "
        f"{workdir}"
    )
    (workdir / "run.json").write_text(
        json.dumps(
            {
                "results": {json.dumps(k): v for k, v in results.items()},
                "capacity": capacity,
                "sizes": sizes,
                "remarks": remarks,
                "footer": footer,
                "extra": EXTRA,
                "phone": PHONE,
            }
        )
    )
    text = render(results, capacity, sizes, remarks, footer)
    print(text)
    if full and not a.no_readme:
        reporting.write_section(MARKERS, text)


def render(results, capacity, sizes, remarks, footer):
    return "\n\n".join(
        [
            table(results, capacity).markdown(),
            "Pictures (JPEG q50 with Pillow, mean of the 30 frames; raw rgb8 is 921,600 B): "
            + ", ".join(
                f"{s['picture']} {s['jpeg_q50_bytes'] / 1e3:.1f} kB (deflated raw: {s['deflate_bytes'] / 1e3:.0f} kB)"
                for s in sizes.values()
            )
            + ".",
            *remarks,
            "Per case (server CPU as a share of one core; the server side's tbf queue, sampled every 0.5 s; for the "
            "bridge, the code it ran: HEAD and a digest of uncommitted changes in src/ and web/):\n\n" + notes(results),
            footer,
        ]
    )


if __name__ == "__main__":
    main()
