"""The bridge with the client the web page uses: roslibjs 1.x (from npm, in web/node_modules) run by Node."""
import json
import math
import shutil

import pytest

from harness import REPO, start_bridge, wait_for

SCRIPT = REPO / "test" / "integration" / "js" / "roslibjs_client.js"
NODE_PATH = REPO / "web" / "node_modules"

pytestmark = pytest.mark.skipif(not shutil.which("node") or not (NODE_PATH / "roslib").is_dir(),
                                reason="node and web/node_modules/roslib are installed by tools/setup")


@pytest.fixture(scope="module")
def url(ros):
    turtle = ros.spawn(["rosrun", "turtlesim", "turtlesim_node"], "turtlesim_node")
    wait_for(lambda: "/turtle1/pose" in dict(ros.master().getTopicTypes()), 30, what="/turtle1/pose")
    proc, port = start_bridge(ros, node_name="roslibjs_bridge")
    yield f"ws://127.0.0.1:{port}"
    proc.stop()
    turtle.stop()


def start_roslibjs(ros, url, *steps):
    return ros.spawn(["node", str(SCRIPT), url, *steps], "roslibjs", env={"NODE_PATH": str(NODE_PATH)})


def results(proc):
    lines = [line for line in proc.output().splitlines() if line.startswith("{")]
    return {entry["step"]: entry for entry in map(json.loads, lines)}


def run_roslibjs(ros, url, *steps):
    proc = start_roslibjs(ros, url, *steps)
    assert proc.popen.wait(60) == 0, proc.output()
    return results(proc)


def test_roslibjs_subscribes_publishes_and_calls(ros, url, node):
    from turtlesim.msg import Pose
    out = run_roslibjs(ros, url, "pose", "topics", "drive", "spawn", "missing", "params")
    start = out["pose"]["pose"]
    assert set(start) == {"x", "y", "theta", "linear_velocity", "angular_velocity"}
    assert "/turtle1/pose" in out["topics"]["topics"]
    now = node.wait_for_message("/turtle1/pose", Pose, timeout=20)
    assert math.hypot(now.x - start["x"], now.y - start["y"]) > 0.5  # "drive" moved it
    assert out["spawn"]["spawned"] == {"name": "js_turtle"}
    assert out["missing"]["error"] == "Service /no_such_service does not exist"
    assert out["params"]["value"] == {"answer": 42, "list": [1, "two"]}


def test_roslibjs_provides_a_service_to_ros(ros, url):
    proc = start_roslibjs(ros, url, "serve")
    wait_for(lambda: "serve-ready" in results(proc), 30, what="roslibjs to advertise")
    reply = ros.run(["rosservice", "call", "/js_test/flip", "data: true"]).stdout
    assert "success: False" in reply and "flipped by roslibjs" in reply
    assert proc.popen.wait(30) == 0, proc.output()
    assert results(proc)["serve"]["request"] == {"data": True}
