"""roslibjs's actionlib client (ROSLIB.ActionClient and Goal: what the console's Actions tab uses), 1.x and 2.x in
Node, through the bridge to an actionlib server (test/nodes/fibonacci_server.py over actionlib/TestAction)."""

import json
import shutil

import pytest

from fixtures import bridge_fixture
from harness import REPO

CLIENTS = REPO / "test" / "js"

pytestmark = pytest.mark.skipif(
    not shutil.which("node") or not (CLIENTS / "node_modules" / "roslib2").is_dir(),
    reason="node and test/js/node_modules are installed by tools/setup --test",
)


@pytest.fixture(scope="module")
def fibonacci_server(ros):
    with ros.spawn(
        ["/usr/bin/python3", str(REPO / "test" / "nodes" / "fibonacci_server.py"), "_step:=0.05"], "fibonacci_server"
    ) as server:
        server.wait_output("serving /tools_fibonacci", 30)
        yield server


bridge = bridge_fixture("actions_bridge", needs=("fibonacci_server",))


@pytest.fixture(scope="module")
def url(bridge):
    return f"ws://127.0.0.1:{bridge}"


@pytest.mark.parametrize("roslib", ["roslib1", "roslib2"])
def test_roslibjs_sends_a_goal_sees_feedback_and_result_and_cancels(ros, url, roslib):
    proc = ros.spawn(
        ["node", str(CLIENTS / "action_client.mjs"), url, "/tools_fibonacci"],
        f"actions-{roslib}",
        env={"ROSLIB": roslib},
    )
    assert proc.popen.wait(60) == 0, proc.output()
    out = json.loads([line for line in proc.output().splitlines() if line.startswith("{")][-1])
    assert out["done"] == {"feedback": [1, 1, 2, 3, 5, 8, 13, 21], "result": 21, "status": 3}  # SUCCEEDED
    cancelled = out["cancelled"]
    assert cancelled["status"] == 2 and len(cancelled["feedback"]) < 20  # PREEMPTED, early
    assert cancelled["result"] <= cancelled["feedback"][-1]  # the last number reached, or the one before
