"""Fixtures for the integration tests: a fresh `rosrun turtlesim turtlesim_node` per test; a websocket client
per test (ws) of the module's `bridge` (made by fixtures.bridge_fixture)."""

import pytest

from bridge_client import WsClient
from harness import wait_for


@pytest.fixture
def ws(bridge):
    """A websocket client of the module's bridge, closed after the test."""
    client = WsClient(f"ws://127.0.0.1:{bridge}/")
    yield client
    client.close()


def stop_turtlesim(ros, proc):
    """`rosnode kill` (the node unregisters and exits), then whatever is left is killed."""
    if proc.alive():
        ros.run(["rosnode", "kill", "/turtlesim"], check=False)
        try:
            wait_for(lambda: not proc.alive(), 10, what="turtlesim_node to exit")
        except AssertionError:
            pass
    proc.stop()


@pytest.fixture
def start_turtlesim(ros, node):
    """start_turtlesim(params={...}, env={...}) runs turtlesim_node with those (private) parameters preset
    and waits for its first /turtle1/pose. Without params, /turtlesim/* parameters are deleted first."""
    started = []

    def start(params=None, env=None):
        ros.run(["rosparam", "delete", "/turtlesim"], check=False)
        for name, value in (params or {}).items():
            ros.run(["rosparam", "set", f"/turtlesim/{name}", str(value)])
        proc = ros.spawn(["rosrun", "turtlesim", "turtlesim_node"], "turtlesim_node", env=env)
        started.append(proc)
        proc.wait_output("Spawning turtle [turtle1]", timeout=30)
        from turtlesim.msg import Pose

        node.wait_for_message("/turtle1/pose", Pose, timeout=30)
        return proc

    yield start
    for proc in started:
        stop_turtlesim(ros, proc)


@pytest.fixture
def turtlesim(start_turtlesim):
    return start_turtlesim()
