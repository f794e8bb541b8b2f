"""Hostile input on the Foxglove WebSocket protocol: whatever a Foxglove client sends, the other clients (rosbridge
and Foxglove) keep being served, and what it causes is bounded and released when it leaves; and a hostile
rosbridge client does not hurt a Foxglove client either. The abuses are foxglove_hostile.py's (a process of their
own), measured beside victims as test_isolation.py does (hostile.measure)."""

import shutil
import struct
from pathlib import Path

import pytest

import foxglove_hostile
from bridge_client import WsClient
from fixtures import bridge_fixture
from harness import REPO, node_pid, wait_for

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def world(ros):
    """turtlesim, the demo camera, a service that never answers, and a 30 MB mesh in the package."""
    foxglove_hostile.BIG_ASSET.parent.mkdir(parents=True, exist_ok=True)
    foxglove_hostile.BIG_ASSET.write_bytes(bytes(range(256)) * (30_000_000 // 256))
    silent = REPO / "test" / "nodes" / "silent_service.py"
    with (
        ros.spawn(["rosrun", "turtlesim", "turtlesim_node", "__name:=hostile_turtle"], "hostile_turtle") as turtle,
        ros.spawn(["rosrun", "turtlesim", "turtle_camera"], "hostile_camera"),
        ros.spawn(["/usr/bin/python3", str(silent)], "silent_service"),
    ):
        turtle.wait_output("Spawning turtle [turtle1]", timeout=30)
        wait_for(lambda: ros.run(["rosservice", "list"]).stdout.count(foxglove_hostile.SLOW_SERVICE), 30)
        yield
    shutil.rmtree(foxglove_hostile.BIG_ASSET.parent)


@pytest.fixture
def parameters(ros):
    """The abuses' parameters are deleted after the test."""
    yield
    if ros.master().hasParam(foxglove_hostile.PARAMETERS):
        ros.master().deleteParam(foxglove_hostile.PARAMETERS)


hostile_bridge = bridge_fixture("foxglove_hostile", scope="function", yields="bridge", unregister_timeout=1)


def blocked_in_reads(pid):
    """How many of the process's threads wait in a socket read (a call to a service that does not answer)."""
    tasks = Path(f"/proc/{pid}/task")
    return sum((task / "wchan").read_text() in ("wait_woken", "sk_wait_data") for task in tasks.iterdir())


def test_calls_to_a_silent_service_end_when_their_client_leaves_and_leave_others_a_call(ros, world, hostile_bridge):
    """Eight clients call a service that never answers 20 times each and leave: their calls end (no thread of the
    bridge stays blocked in them). Nine more do the same and stay: a rosbridge client's /rosapi/get_time is still
    answered. Before, the calls of the first eight held every turn of the bridge's calls (128) and a thread each
    for good: no client's call, parameter or asset was served again, by either protocol."""
    url = f"ws://127.0.0.1:{hostile_bridge.port}/"
    pid = node_pid(ros, "/foxglove_hostile")
    service = foxglove_hostile.Scout(url).services[foxglove_hostile.SLOW_SERVICE]
    calls = b"".join(foxglove_hostile.binary(b"\x02" + struct.pack("<III", service, i, 4) + b"ros1") for i in range(20))
    for _ in range(8):
        with foxglove_hostile.connect(url) as sock:
            sock.sendall(calls)
            wait_for(lambda: blocked_in_reads(pid) >= 16, 10, what="the client's calls running")
    wait_for(lambda: blocked_in_reads(pid) == 0, 10, what=lambda: f"{blocked_in_reads(pid)} calls still blocked")
    staying = [foxglove_hostile.connect(url) for _ in range(9)]
    for sock in staying:
        sock.sendall(calls)
    wait_for(lambda: blocked_in_reads(pid) >= 128, 10, what="the staying clients' calls running")
    victim = WsClient(url)
    reply = victim.request({"op": "call_service", "service": "/rosapi/get_time", "id": "beside"}, timeout=5)
    assert reply["result"], reply
    victim.close()
    for sock in staying:
        sock.close()
    wait_for(lambda: blocked_in_reads(pid) == 0, 10, what=lambda: f"{blocked_in_reads(pid)} calls still blocked")
