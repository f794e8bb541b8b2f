"""One ROS system spread over four machines, as a user deploys it: roscore on one, turtlesim_node on another
(the robot), the bridge on a third and a roslibpy client on a fourth. The machines are Linux network
namespaces on a private virtual switch (10.77.0.1-4/24, reachable from nothing else); every process gets
ROS_MASTER_URI and ROS_IP as a user would set them. Needs root and iproute2; skipped (saying why) otherwise.
`drive` below is the roslibpy client that runs on machine 4."""

import json
import logging
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from harness import Proc, make_workdir, wait_for

pytestmark = pytest.mark.slow  # (deselect with -m 'not slow' for a quick run)

SUBNET = "10.77.0"
HOSTS = {"master": 1, "robot": 2, "bridge": 3, "client": 4}
MASTER_URI = f"http://{SUBNET}.1:11311"  # the default port: each machine has its own network stack
BRIDGE_PORT = 9090


def ip(*args, check=True):
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check)


def netns_unavailable():
    """Why network namespaces cannot be used here (None when they can). Tries what the test does: make a
    namespace, run a command in it with `ip netns exec` (which makes / a slave mount and remounts /sys: in a
    chroot or a container without the right to mount that fails), and delete it."""
    if os.geteuid() != 0:
        return "needs root to create network namespaces"
    probe = f"tsim-probe-{os.getpid()}"
    try:
        res = ip("netns", "add", probe, check=False)
    except FileNotFoundError:
        return "iproute2 (`ip`) is not installed"
    if res.returncode != 0:
        return f"`ip netns add` fails here: {res.stderr.strip()}"
    try:
        res = subprocess.run(["ip", "netns", "exec", probe, "true"], capture_output=True, text=True, timeout=30)
        reason = (
            None
            if res.returncode == 0
            else f"`ip netns exec` fails here: {res.stderr.strip() or f'exit status {res.returncode}'}"
        )
    except subprocess.TimeoutExpired:
        reason = "`ip netns exec NAME true` did not finish within 30 s"
    res = ip("netns", "del", probe, check=False)
    if not reason and res.returncode != 0:
        reason = f"`ip netns del` fails here: {res.stderr.strip()}"
    return reason


class Lan:
    """Four namespaces ("machines") cabled to a bridge device that lives in a fifth one (the "switch"), so
    nothing of it touches this machine's own network."""

    def __init__(self, workdir):
        self.workdir = workdir
        prefix = f"tsim{os.getpid()}"
        self.switch = f"{prefix}-switch"
        self.ns = {host: f"{prefix}-{host}" for host in HOSTS}
        self.procs = []

    def up(self):
        ip("netns", "add", self.switch)
        ip("-n", self.switch, "link", "add", "br0", "type", "bridge")
        ip("-n", self.switch, "link", "set", "br0", "up")
        for host, n in HOSTS.items():
            ns = self.ns[host]
            ip("netns", "add", ns)
            ip("-n", self.switch, "link", "add", f"port{n}", "type", "veth", "peer", "name", "eth0", "netns", ns)
            ip("-n", self.switch, "link", "set", f"port{n}", "master", "br0", "up")
            ip("-n", ns, "addr", "add", f"{SUBNET}.{n}/24", "dev", "eth0")
            ip("-n", ns, "link", "set", "eth0", "up")
            ip("-n", ns, "link", "set", "lo", "up")
        return self

    def down(self):
        for proc in reversed(self.procs):
            proc.stop()
        for ns in [*self.ns.values(), self.switch]:  # deleting a namespace deletes its end of the cables
            ip("netns", "del", ns, check=False)

    def env(self, host):
        env = {
            k: v
            for k, v in os.environ.items()
            if not k.startswith("ROS_")
            or k in ("ROS_PACKAGE_PATH", "ROS_ROOT", "ROS_DISTRO", "ROS_ETC_DIR", "ROS_VERSION", "ROS_PYTHON_VERSION")
        }
        env.update(
            ROS_MASTER_URI=MASTER_URI,
            ROS_IP=f"{SUBNET}.{HOSTS[host]}",
            PYTHONUNBUFFERED="1",
            ROS_HOME=str(self.workdir / host),
            ROS_LOG_DIR=str(self.workdir / host / "log"),
            PATH="/usr/bin:/bin:/usr/sbin:/sbin:" + os.environ.get("PATH", ""),
        )
        env.pop("DISPLAY", None)
        return env

    def spawn(self, host, args, name):
        proc = Proc(["ip", "netns", "exec", self.ns[host], *args], self.env(host), self.workdir / f"{host}-{name}.log")
        self.procs.append(proc)
        return proc

    def run(self, host, args, timeout=30, env=None):
        return subprocess.run(
            ["ip", "netns", "exec", self.ns[host], *args],
            env={**self.env(host), **(env or {})},
            capture_output=True,
            text=True,
            timeout=timeout,
        )


@pytest.fixture
def lan():
    reason = netns_unavailable()
    if reason:
        pytest.skip(reason)
    lan = Lan(make_workdir("multihost-"))
    try:
        yield lan.up()
    finally:
        lan.down()


def test_turtle_driven_from_a_fourth_machine_through_the_bridge(lan):
    core = lan.spawn("master", ["roscore"], "roscore")
    core.wait_output("started core service", timeout=40)
    robot = lan.spawn("robot", ["rosrun", "turtlesim", "turtlesim_node"], "turtlesim")
    robot.wait_output("Spawning turtle [turtle1]", timeout=40)
    bridge = lan.spawn(
        "bridge",
        ["roslaunch", "turtlesim", "rosbridge_websocket.launch", f"address:={SUBNET}.3", f"port:={BRIDGE_PORT}"],
        "bridge",
    )
    wait_for(
        lambda: (
            not bridge.alive()
            or lan.run(
                "client",
                [sys.executable, "-c", f"import socket; socket.create_connection(('{SUBNET}.3', {BRIDGE_PORT}), 1)"],
            ).returncode
            == 0
        ),
        40,
        what="the bridge listening on 10.77.0.3 (seen from machine 4)",
    )
    assert bridge.alive(), bridge.output()

    here = Path(__file__).resolve().parent
    client = lan.run(
        "client",
        [
            sys.executable,
            "-c",
            f"import {Path(__file__).stem}; {Path(__file__).stem}.drive('ws://{SUBNET}.3:{BRIDGE_PORT}')",
        ],
        timeout=90,
        env={"PYTHONPATH": f"{here}:{here.parents[1] / 'testkit'}"},
    )
    assert client.returncode == 0, f"client failed:\n{client.stdout}\n{client.stderr}\nbridge:\n{bridge.output()}"
    seen = json.loads(client.stdout.strip().splitlines()[-1])

    assert seen["start"]["x"] == pytest.approx(5.544445, abs=0.01)
    assert seen["end"]["x"] > seen["start"]["x"] + 1.0  # it drove forward (east) ...
    assert seen["end"]["y"] == pytest.approx(seen["start"]["y"], abs=0.05)  # ... in a straight line
    assert seen["end"]["linear_velocity"] == pytest.approx(2.0)
    assert "/turtlesim" in seen["nodes"] and "/rosbridge_websocket" in seen["nodes"]
    # the robot's publisher was reached at the robot's ROS_IP, the bridge's at the bridge's: ROS_IP was honoured
    info = lan.run("master", ["rosnode", "info", "/turtlesim"])
    assert f"http://{SUBNET}.2:" in info.stdout, info.stdout + info.stderr
    assert f"http://{SUBNET}.3:" in lan.run("master", ["rosnode", "info", "/rosbridge_websocket"]).stdout


def test_bridge_listens_only_on_the_address_it_is_given(lan):
    core = lan.spawn("master", ["roscore"], "roscore")
    core.wait_output("started core service", timeout=40)
    bridge = lan.spawn(
        "bridge",
        ["roslaunch", "turtlesim", "rosbridge_websocket.launch", f"address:={SUBNET}.3", f"port:={BRIDGE_PORT}"],
        "bridge",
    )

    def reachable(target):
        probe = f"import socket; socket.create_connection(('{target}', {BRIDGE_PORT}), 1)"
        return lan.run("bridge", [sys.executable, "-c", probe]).returncode == 0

    wait_for(lambda: not bridge.alive() or reachable(f"{SUBNET}.3"), 40, what="the bridge listening")
    assert bridge.alive(), bridge.output()
    assert not reachable("127.0.0.1")


# ---- machine 4: the roslibpy client ------------------------------------------------------------------------


def drive(url):
    """Drives turtle1 forward at 2 m/s for about 1.5 s; prints the poses before and after, and the node list."""
    import roslibpy

    logging.basicConfig(level=logging.DEBUG, stream=sys.stderr)  # every frame sent, for the failure message
    host, port = url.removeprefix("ws://").split(":")
    ros = roslibpy.Ros(host=host, port=int(port))
    ros.run(timeout=20)
    poses = []
    pose = roslibpy.Topic(ros, "/turtle1/pose", "turtlesim/Pose")
    pose.subscribe(poses.append)
    wait_for(lambda: poses, 20, what="a first pose through the bridge")
    start = poses[-1]
    cmd = roslibpy.Topic(ros, "/turtle1/cmd_vel", "geometry_msgs/Twist")
    cmd.advertise()
    twist = roslibpy.Message({"linear": {"x": 2.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}})
    deadline = time.monotonic() + 20
    while poses[-1]["x"] < start["x"] + 1.0 and time.monotonic() < deadline:
        cmd.publish(twist)
        time.sleep(0.1)
    end = poses[-1]
    nodes = roslibpy.Service(ros, "/rosapi/nodes", "rosapi/Nodes").call(roslibpy.ServiceRequest(), timeout=20)
    print(json.dumps({"start": start, "end": end, "nodes": nodes["nodes"]}), flush=True)
    cmd.unadvertise()
    pose.unsubscribe()
    ros.terminate()
