"""Real processes for the tests and the benches (bench/ imports testkit/ too): a private roscore per session,
nodes started with rosrun/roslaunch, and the stock CLI tools. Every process is started in its own process group
and killed at teardown."""

import contextlib
import os
import random
import re
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import rosgraph

REPO = Path(__file__).resolve().parent.parent
ARTIFACTS = REPO / "test" / "artifacts"


def free_port():
    """A port free now for a server to listen on, chosen below the kernel's range for port 0 (ip_local_port_range), so
    that no other socket is given it before the server binds it (roslaunch's own XML-RPC server, bound to port 0,
    once took the port just chosen for its roscore: that worker's whole session failed)."""
    below = int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    for port in random.sample(range(10000, below), min(500, max(0, below - 10000))):
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    with socket.socket() as s:  # (a port-0 range that leaves no room below it)
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(predicate, timeout=10.0, interval=0.05, what="condition"):
    """Polls predicate() until it returns something truthy; returns it, or raises AssertionError saying `what`
    (a text, or a function giving one: what was seen by then)."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout}s waiting for {what() if callable(what) else what}")
        time.sleep(interval)


def descendants(pid):
    """The pids of every living descendant of pid (from /proc)."""
    children = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    found, todo = set(), [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


class Proc:
    """A process in its own process group; its stdout+stderr go to a log file that tests can read."""

    def __init__(self, args, env, log_path, **popen_kwargs):
        self.args = args
        self.log_path = Path(log_path)
        self._log = open(self.log_path, "wb")
        self.popen = subprocess.Popen(
            args, env=env, stdout=self._log, stderr=subprocess.STDOUT, start_new_session=True, **popen_kwargs
        )

    @property
    def pid(self):
        return self.popen.pid

    def output(self):
        return self.log_path.read_text(errors="replace")

    def wait_output(self, text, timeout=10.0):
        return wait_for(lambda: text in self.output(), timeout, what=f"{text!r} in output of {self.args}")

    def wait_line(self, pattern, timeout=10.0, after=0):
        """The first match of the line regex `pattern` (its group, if it has one) after the first `after` matches;
        raises if the process ends first."""

        def found():
            hits = re.findall(pattern, self.output(), re.M)
            if len(hits) > after:
                return hits[after:]
            if not self.alive():
                raise RuntimeError(f"{self.args[:6]} ended:\n{self.output()[-3000:]}")
            return None

        return wait_for(found, timeout, what=f"{pattern} from {self.args[:6]}")[0]

    def alive(self):
        return self.popen.poll() is None

    def __enter__(self):  # `with ros.spawn(...) as proc:` stops it when the block ends, even by an exception
        return self

    def __exit__(self, *_):
        self.stop()

    def signal(self, sig):
        if self.alive():
            os.killpg(self.popen.pid, sig)

    def stop(self, timeout=5.0):
        """SIGINT, then SIGTERM, then SIGKILL the whole group; returns the exit code. Descendants that left the
        group (roslaunch starts each node in a session of its own) are killed afterwards if still running."""
        tree = descendants(self.popen.pid)
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(self.popen.pid, sig)
            except ProcessLookupError:
                break
            try:
                self.popen.wait(timeout)
                break
            except subprocess.TimeoutExpired:
                continue
        try:  # children that outlived the leader
            os.killpg(self.popen.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        for pid in tree | descendants(self.popen.pid):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self._log.close()
        return self.popen.wait()


class RosMaster:
    """A private roscore on a free port (never 11311), with the environment to reach it."""

    def __init__(self, workdir, host="127.0.0.1"):
        self.workdir = Path(workdir)
        self.port = free_port()
        self.uri = f"http://{host}:{self.port}"
        self.env = dict(os.environ)
        self.env.update(
            ROS_MASTER_URI=self.uri,
            ROS_IP=host,
            ROS_HOME=str(self.workdir / "ros_home"),
            ROS_LOG_DIR=str(self.workdir / "ros_log"),
            PYTHONUNBUFFERED="1",
            PATH="/usr/bin:/bin:" + os.environ.get("PATH", ""),
        )
        self.env.pop("ROS_HOSTNAME", None)
        self.procs = []
        self.core = None

    def start(self):
        self.core = self.spawn(["roscore", "-p", str(self.port)], "roscore")
        wait_for(self.online, 20, what="roscore")
        return self

    def online(self):
        try:
            rosgraph.Master("/harness", master_uri=self.uri).getPid()
            return True
        except Exception:
            return False

    @contextlib.contextmanager
    def unresponsive(self):
        """For the block, the master process is stopped (SIGSTOP): it accepts connections and answers nothing, as
        a master on a machine that hangs does."""
        (pid,) = (
            pid for pid in descendants(self.core.popen.pid) if b"rosmaster" in Path(f"/proc/{pid}/cmdline").read_bytes()
        )
        os.kill(pid, signal.SIGSTOP)
        try:
            yield
        finally:
            os.kill(pid, signal.SIGCONT)

    def spawn(self, args, name=None, env=None, **kwargs):
        """Starts a process with this master's environment; it is stopped at teardown."""
        name = name or Path(str(args[0])).name
        log = self.workdir / f"{name}-{len(self.procs)}.log"
        proc = Proc(args, {**self.env, **(env or {})}, log, **kwargs)
        self.procs.append(proc)
        return proc

    def run(self, args, timeout=20, check=True, env=None, input=None):
        """Runs a CLI command to completion against this master; returns its stdout."""
        res = subprocess.run(
            args, env={**self.env, **(env or {})}, capture_output=True, text=True, timeout=timeout, input=input
        )
        if check and res.returncode != 0:
            raise AssertionError(f"{args} exited {res.returncode}:\n{res.stdout}\n{res.stderr}")
        return res

    def master(self):
        return rosgraph.Master("/harness", master_uri=self.uri)

    def start_xvfb(self):
        """A virtual X server on a free display number; returns (Proc, display name such as ':90')."""
        number = next(
            (
                n
                for n in range(90, 300)
                if not Path(f"/tmp/.X11-unix/X{n}").exists() and not Path(f"/tmp/.X{n}-lock").exists()
            ),
            None,
        )
        if number is None:
            raise RuntimeError("no free X display number")
        xvfb = self.spawn(["Xvfb", f":{number}", "-screen", "0", "1024x768x24", "-nolisten", "tcp"], "xvfb")
        wait_for(Path(f"/tmp/.X11-unix/X{number}").exists, 20, what="Xvfb")
        return xvfb, f":{number}"

    def stop(self):
        for proc in reversed(self.procs):
            proc.stop()
        self.procs.clear()


class ProcStat:
    """CPU time, resident memory and thread count of one running process, read from /proc."""

    CLOCK_TICKS = os.sysconf("SC_CLK_TCK")
    PAGE = os.sysconf("SC_PAGE_SIZE")

    def __init__(self, pid):
        self.pid = pid

    def cpu_seconds(self):
        fields = Path(f"/proc/{self.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / self.CLOCK_TICKS  # utime + stime

    def rss_mb(self):
        return int(Path(f"/proc/{self.pid}/statm").read_text().split()[1]) * self.PAGE / 1e6

    def threads(self):
        return len(os.listdir(f"/proc/{self.pid}/task"))

    def thread_cpu(self):
        """{thread id: CPU seconds} of the living threads, from the scheduler's own count (se.sum_exec_runtime in
        /proc/<pid>/task/*/sched, to the microsecond), where cpu_seconds() counts 10 ms ticks: for windows too
        short or too idle for ticks. A thread that ends takes its share with it (compare the ids)."""
        found = {}
        for tid in os.listdir(f"/proc/{self.pid}/task"):
            try:
                text = Path(f"/proc/{self.pid}/task/{tid}/sched").read_text()
            except OSError:  # (it ended meanwhile)
                continue
            line = next(line for line in text.splitlines() if line.startswith("se.sum_exec_runtime"))
            found[int(tid)] = float(line.split(":")[1]) / 1e3  # (ms)
        return found

    def peak_rss_mb(self):
        """The largest RSS since the process started, or since reset_peak_rss() (VmHWM)."""
        status = Path(f"/proc/{self.pid}/status").read_text()
        return int(next(line for line in status.splitlines() if line.startswith("VmHWM")).split()[1]) / 1e3

    def reset_peak_rss(self):
        Path(f"/proc/{self.pid}/clear_refs").write_text("5")  # (Linux: VmHWM starts again from VmRSS)


def make_workdir(prefix):
    return Path(tempfile.mkdtemp(prefix=prefix))


def start_bridge(ros, node_name="rosbridge_websocket", timeout=30.0, max_fds=None, **settings):
    """Runs the bridge node (`rosrun turtlesim rosbridge_websocket`, its settings set as private parameters,
    as the launch file sets them: text) on a free port of 127.0.0.1 (settings may override, e.g.
    authenticate="true"); returns (Proc, port) once the server listens. Give each bridge that runs at the same
    time its own node_name. max_fds: run it under `ulimit -n max_fds`. The launch file itself is run by
    launch_bridge."""
    master = ros.master()
    if master.hasParam(f"/{node_name}"):  # (what an earlier bridge of this name was given)
        master.deleteParam(f"/{node_name}")
    for name, value in {"port": 0, "foxglove_port": -1, "address": "127.0.0.1", **settings}.items():
        master.setParam(f"/{node_name}/{name}", str(value))
    command = ["rosrun", "turtlesim", "rosbridge_websocket", f"__name:={node_name}"]
    if max_fds is not None:
        command = ["bash", "-c", f'ulimit -n {int(max_fds)} && exec "$@"', "bash", *command]
    proc = ros.spawn(command, node_name)
    return proc, _listening_port(ros, proc, node_name, timeout)


def launch_bridge(ros, node_name="rosbridge_websocket", timeout=30.0, env=None, **launch_args):
    """Runs `roslaunch turtlesim rosbridge_websocket.launch` (launch args may override the free port of
    127.0.0.1), as a user starts it, with `env` added to the master's environment; returns (Proc, port) once the
    server listens."""
    args = {"port": 0, "foxglove_port": -1, "address": "127.0.0.1", "node_name": node_name, **launch_args}
    if ros.master().hasParam(f"/{node_name}/actual_port"):  # (an earlier bridge's)
        ros.master().deleteParam(f"/{node_name}/actual_port")
    proc = ros.spawn(
        ["roslaunch", "turtlesim", "rosbridge_websocket.launch", *(f"{key}:={value}" for key, value in args.items())],
        node_name,
        env=env,
    )
    return proc, _listening_port(ros, proc, node_name, timeout)


def _listening_port(ros, proc, node_name, timeout):
    """The port the bridge node writes to ~actual_port once it listens (the callers clear an earlier one); a bridge
    that never listens is stopped before the error goes up (no caller holds it yet to stop it)."""
    master, param = ros.master(), f"/{node_name}/actual_port"

    def port():
        if not proc.alive():
            raise AssertionError(f"rosbridge exited early:\n{proc.output()}")
        return master.getParam(param) if master.hasParam(param) else None

    try:
        return wait_for(port, timeout, what=f"{param} (bridge log: {proc.log_path})")
    except BaseException:
        proc.stop()
        raise


def wait_publisher_connected(ros, publisher, topic, subscriber, timeout=20):
    """Waits until node `publisher` has `subscriber` among the connections of its `topic`, seen from the
    publisher's side (its XML-RPC getBusInfo). rospy delivers nothing published before that, and the subscriber
    counts its connection a moment earlier (the publisher adds it after sending its header)."""
    import xmlrpc.client

    uri = ros.master().lookupNode(publisher)

    def connected():
        _, _, connections = xmlrpc.client.ServerProxy(uri).getBusInfo("/harness")
        return any(c[1] == subscriber and c[2] == "o" and c[4] == topic for c in connections)

    wait_for(connected, timeout, what=f"{subscriber} connected to {publisher}'s {topic}")


def node_pid(ros, node_name):
    """The process id of a running ROS node, asked from the node itself (its XML-RPC getPid)."""
    import xmlrpc.client

    uri = ros.master().lookupNode(node_name)
    return xmlrpc.client.ServerProxy(uri).getPid("/harness")[2]
