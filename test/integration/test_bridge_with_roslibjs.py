"""The bridge with roslibjs run by Node: 1.x (the page's version) and 2.x (npm's current), both pinned by
test/js/package.json and installed by tools/setup --test."""

import json
import math
import shutil

import pytest

from fixtures import bridge_fixture
from harness import REPO, wait_for

CLIENTS = REPO / "test" / "js"
SCRIPT = CLIENTS / "roslibjs_client.mjs"
VERSIONS = ["roslib1", "roslib2"]

pytestmark = pytest.mark.skipif(
    not shutil.which("node") or not (CLIENTS / "node_modules" / "roslib2").is_dir(),
    reason="node and test/js/node_modules are installed by tools/setup --test",
)


@pytest.fixture(scope="module")
def module_turtlesim(ros):
    with ros.spawn(["rosrun", "turtlesim", "turtlesim_node"], "turtlesim_node") as proc:
        wait_for(lambda: "/turtle1/pose" in dict(ros.master().getTopicTypes()), 30, what="/turtle1/pose")
        yield proc


bridge = bridge_fixture("roslibjs_bridge", needs=("module_turtlesim",))


@pytest.fixture(scope="module")
def url(bridge):
    return f"ws://127.0.0.1:{bridge}"


@pytest.fixture(params=VERSIONS)
def roslib(request):
    """The npm alias of the roslibjs version a test runs with."""
    return request.param


def start_roslibjs(ros, roslib, url, *steps):
    return ros.spawn(["node", str(SCRIPT), url, *steps], f"roslibjs-{roslib}", env={"ROSLIB": roslib})


def results(proc):
    lines = [line for line in proc.output().splitlines() if line.startswith("{")]
    return {entry["step"]: entry for entry in map(json.loads, lines)}


def run_roslibjs(ros, roslib, url, *steps):
    proc = start_roslibjs(ros, roslib, url, *steps)
    assert proc.popen.wait(60) == 0, proc.output()
    return results(proc)


def test_roslibjs_subscribes_publishes_and_calls(ros, roslib, url, node):
    from turtlesim.msg import Pose

    ros.run(["rosservice", "call", "/kill", "js_turtle"], check=False)  # (spawned by the other version's run)
    out = run_roslibjs(ros, roslib, url, "pose", "topics", "drive", "spawn", "clear", "missing", "params")
    start = out["pose"]["pose"]
    assert set(start) == {"x", "y", "theta", "linear_velocity", "angular_velocity"}
    assert "/turtle1/pose" in out["topics"]["topics"]
    now = node.wait_for_message("/turtle1/pose", Pose, timeout=20)
    assert math.hypot(now.x - start["x"], now.y - start["y"]) > 0.5  # "drive" moved it
    assert out["spawn"]["spawned"] == {"name": "js_turtle"}
    assert out["clear"]["cleared"] == {}
    assert out["missing"]["error"] == "Service /no_such_service does not exist"
    assert out["params"]["value"] == {"answer": 42, "list": [1, "two"]}


@pytest.mark.parametrize("step, service", [("serve", "/js_test/flip"), ("serve-relative", "/js_test/relative_flip")])
def test_roslibjs_provides_a_service_to_ros(ros, roslib, url, step, service):
    proc = start_roslibjs(ros, roslib, url, step)
    wait_for(lambda: "serve-ready" in results(proc), 30, what="roslibjs to advertise")
    reply = ros.run(["rosservice", "call", service, "data: true"]).stdout
    assert "success: False" in reply and "flipped by roslibjs" in reply
    assert proc.popen.wait(30) == 0, proc.output()
    assert results(proc)[step]["request"] == {"data": True}


def test_roslibjs_simple_example(ros, roslib, url, node):
    """roslibjs's examples/simple.html, against rospy stand-ins for `rostopic pub /listener`, `rostopic echo
    /cmd_vel` and the add_two_ints server."""
    from geometry_msgs.msg import Twist
    from std_msgs.msg import String
    from std_srvs.srv import SetBool, SetBoolResponse

    twists = []
    echo = node.Subscriber("/cmd_vel", Twist, twists.append)
    talker = node.Publisher("/listener", String, latch=True, queue_size=1)
    talker.publish(String("Hello, World!"))
    server = node.Service("/add_two_ints", SetBool, lambda request: SetBoolResponse(True, "3"))
    try:
        out = run_roslibjs(ros, roslib, url, "simple-example")["simple-example"]
        assert (out["heard"], out["sum"]) == ("Hello, World!", {"success": True, "message": "3"})
        assert (out["max_vel_y"], out["favorite_color"]) == (0.8, "red")
        assert "/rosdistro" in out["params"] and node.get_param("/favorite_color") == "red"
        wait_for(lambda: twists, 10, what="the Twist on /cmd_vel")
        assert (twists[0].linear.x, twists[0].angular.z) == (0.1, -0.3)
    finally:
        echo.unregister()
        talker.unregister()
        server.shutdown()
