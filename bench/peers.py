"""The other bridges the benchmarks measure beside this one, each built beforehand outside this repository (it
builds no fetched code): where each is, whether it is there, and how to start it on a bench's private master. A
peer that is not there is skipped, with the reason (`missing()`), and the rest of the bench runs.

- rosbridge_server 0.11.17, the reference (RobotWebTools/rosbridge_suite, tag 0.11.17, with rosauth's service
  definition beside it): a catkin workspace (`--reference-ws`, else $REFERENCE_WS, else
  ~/.cache/turtlesim/rosbridge-0.11.17-venv-ws) built with the Python of a venv holding pymongo's bson, autobahn and
  twisted (`--reference-venv`, else $REFERENCE_VENV, else ~/.cache/turtlesim/reference-venv; Debian's
  python3-twisted would shadow the test venv's zope.interface). Run with its own launch file.
- foxglove_bridge 0.8.5's ROS 1 nodelet (foxglove/ros-foxglove-bridge, tag 0.8.5, with ros_babel_fish): a catkin
  workspace (`--foxglove-ws`, else $FOXGLOVE_WS, else /tmp/foxglove_ws). Run as `nodelet standalone`, at its
  defaults. Its protocol: foxglove_protocol.py."""

import os
import socket
import subprocess
from pathlib import Path

import harness

REFERENCE_TAG = "0.11.17"
FOXGLOVE_TAG = "0.8.5"
REFERENCE_NAME = f"rosbridge_server {REFERENCE_TAG}"
FOXGLOVE_NAME = f"foxglove_bridge {FOXGLOVE_TAG}"
CACHE = Path.home() / ".cache" / "turtlesim"


def add_arguments(parser):
    parser.add_argument(
        "--reference-ws",
        type=Path,
        default=Path(os.environ.get("REFERENCE_WS", CACHE / f"rosbridge-{REFERENCE_TAG}-venv-ws")),
        help=f"the catkin workspace of {REFERENCE_NAME}, built beforehand (default: $REFERENCE_WS, else %(default)s)",
    )
    parser.add_argument(
        "--reference-venv",
        type=Path,
        default=Path(os.environ.get("REFERENCE_VENV", CACHE / "reference-venv")),
        help="the venv whose Python it was built with (default: $REFERENCE_VENV, else %(default)s)",
    )
    parser.add_argument(
        "--foxglove-ws",
        type=Path,
        default=Path(os.environ.get("FOXGLOVE_WS", "/tmp/foxglove_ws")),
        help=f"the catkin workspace of {FOXGLOVE_NAME}'s ROS 1 nodelet, built beforehand "
        "(default: $FOXGLOVE_WS, else %(default)s)",
    )


def reference_missing(a):
    """None if the reference can run, else why not (a sentence)."""
    if not (a.reference_ws / "devel" / "setup.bash").exists():
        return f"{REFERENCE_NAME} is not built in {a.reference_ws} (see bench/README.md: the peers)"
    python = a.reference_venv / "bin" / "python"
    if subprocess.run([str(python), "-c", "import bson, autobahn, twisted"], capture_output=True).returncode:
        return f"{python} cannot import bson, autobahn and twisted, which {REFERENCE_NAME} needs"
    return None


def foxglove_missing(a):
    if not (a.foxglove_ws / "devel" / "setup.bash").exists() or not any(
        (a.foxglove_ws / "devel" / "lib").glob("libfoxglove_bridge_nodelet.so")
    ):
        return f"{FOXGLOVE_NAME} is not built in {a.foxglove_ws} (see bench/README.md: the peers)"
    return None


def start_reference(ros, a, address="127.0.0.1", name="reference"):
    """The reference, with its launch file (its node: /rosbridge_websocket, with /rosapi beside it; so never at
    the same time as another bridge of that name): (Proc, ProcStat of its websocket node, websocket URL)."""
    port = harness.free_port()
    proc = ros.spawn(
        [
            "bash",
            "-c",
            f"source {a.reference_ws}/devel/setup.bash && exec roslaunch rosbridge_server "
            f"rosbridge_websocket.launch port:={port} address:={address}",
        ],
        name,
    )
    harness.wait_for(lambda: listening(address, port, proc), 60, what=f"{REFERENCE_NAME} listening")
    return proc, harness.ProcStat(harness.node_pid(ros, "/rosbridge_websocket")), f"ws://{address}:{port}/"


def start_foxglove(ros, a, address="127.0.0.1", name="foxglove_bridge", **params):
    """foxglove_bridge at its defaults (params: private parameters to change, e.g. send_buffer_limit):
    (Proc, ProcStat, websocket URL)."""
    port = harness.free_port()
    settings = " ".join(f"_{key}:={value}" for key, value in {"port": port, "address": address, **params}.items())
    proc = ros.spawn(
        [
            "bash",
            "-c",
            f"source {a.foxglove_ws}/devel/setup.bash && exec rosrun nodelet nodelet "
            f"standalone foxglove_bridge/foxglove_bridge_nodelet __name:={name} {settings}",
        ],
        name,
    )
    harness.wait_for(lambda: listening(address, port, proc), 60, what=f"{FOXGLOVE_NAME} listening")
    return proc, harness.ProcStat(harness.node_pid(ros, f"/{name}")), f"ws://{address}:{port}/"


def connect(host, port):
    try:
        return socket.create_connection((host, port), 1)
    except OSError:
        return None


def listening(host, port, proc):
    if not proc.alive():
        raise RuntimeError(f"the server ended:\n{proc.output()[-3000:]}")
    conn = connect(host, port)
    if conn:
        conn.close()
    return conn is not None
