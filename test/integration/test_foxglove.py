"""The Foxglove WebSocket protocol on the bridge, with a client nobody here wrote: @foxglove/ws-protocol's
FoxgloveClient (npm, pinned by test/js/package.json) run by Node (test/js/foxglove_client.mjs), against a real
bridge on a real roscore with turtlesim, the demo's TF node (which sets /robot_description) and rospy publishers."""

import base64
import json
import shutil
import socket
import struct
import time
import xmlrpc.client

import pytest
import rosgraph.network

from bridge_client import WsClient
from fixtures import bridge_fixture
from harness import REPO, start_bridge, wait_for

CLIENTS = REPO / "test" / "js"
SCRIPT = CLIENTS / "foxglove_client.mjs"

pytestmark = pytest.mark.skipif(
    not shutil.which("node") or not (CLIENTS / "node_modules" / "@foxglove" / "ws-protocol").is_dir(),
    reason="node and test/js/node_modules are installed by tools/setup --test",
)


@pytest.fixture(scope="module")
def world(ros):
    """turtlesim, the demo's TF node, and a rospy publisher of a known message."""
    with (
        ros.spawn(["rosrun", "turtlesim", "turtlesim_node"], "turtlesim_node"),
        ros.spawn(["rosrun", "turtlesim", "turtle_tf"], "turtle_tf"),
        ros.spawn(["rostopic", "pub", "-r", "5", "/fg/point", "geometry_msgs/Point", "{x: 1.5, y: -2, z: 3}"], "pub"),
    ):
        wait_for(lambda: "/fg/point" in dict(ros.master().getTopicTypes()), 30, what="/fg/point")
        wait_for(lambda: ros.master().hasParam("/robot_description"), 30, what="/robot_description")
        yield


bridge = bridge_fixture("foxglove_bridge_test", needs=("world",), yields="bridge")


def run(ros, url, *steps, check=True, env=None):
    """Runs the Node client's steps; {step: result}. A step that fails ends the client (its result holds error)."""
    proc = ros.spawn(["node", str(SCRIPT), url, *map(json.dumps, steps)], "foxglove-client", env=env)
    code = proc.popen.wait(60)
    lines = [json.loads(line) for line in proc.output().splitlines() if line.startswith("{")]
    results = {line["step"]: line for line in lines}
    if check:
        assert code == 0 and not any("error" in line for line in lines), proc.output()
    return results


def ws_url(bridge):
    return f"ws://127.0.0.1:{bridge.port}"


def tcpros_definition(ros, topic):
    """The message_definition a publisher of `topic` sends in its TCPROS header (what a ROS subscriber reads)."""
    master = ros.master()
    node = next(nodes for name, nodes in master.getSystemState()[0] if name == topic)[0]
    _, _, (_, host, port) = xmlrpc.client.ServerProxy(master.lookupNode(node)).requestTopic(
        "/harness", topic, [["TCPROS"]]
    )
    with socket.create_connection((host, port), timeout=10) as sock:
        rosgraph.network.write_ros_handshake_header(
            sock, {"topic": topic, "md5sum": "*", "callerid": "/harness", "type": "*"}
        )
        import io

        return rosgraph.network.read_ros_handshake_header(sock, io.BytesIO(), 65536)["message_definition"]


def test_a_client_gets_the_subprotocol_it_offered_and_the_server_s_capabilities(ros, bridge):
    for subprotocol in ("foxglove.websocket.v1", "foxglove.sdk.v1"):
        info = run(ros, ws_url(bridge), {"do": "info"}, env={"SUBPROTOCOL": subprotocol})["info"]
        assert info["protocol"] == subprotocol
        capabilities = set(info["info"]["capabilities"])
        assert {"clientPublish", "parameters", "parametersSubscribe", "services", "connectionGraph", "assets"} <= (
            capabilities
        )
        assert info["info"]["sessionId"]


def test_every_topic_is_a_channel_with_its_full_ros1_definition(ros, bridge):
    result = run(ros, ws_url(bridge), {"do": "channels", "topics": ["/turtle1/pose", "/turtle1/cmd_vel", "/tf"]})
    channels = {c["topic"]: c for c in result["channels"]["channels"]}
    pose = channels["/turtle1/pose"]
    assert (pose["encoding"], pose["schemaEncoding"], pose["schemaName"]) == ("ros1", "ros1msg", "turtlesim/Pose")
    assert pose["schema"] == tcpros_definition(ros, "/turtle1/pose")
    shown = ros.run(["rosmsg", "show", "turtlesim/Pose"]).stdout.split()
    assert [line.split() for line in pose["schema"].splitlines() if line] == [
        shown[i : i + 2] for i in range(0, len(shown), 2)
    ]
    # a topic only subscribed to (turtlesim listens to cmd_vel) is a channel too, for publishing panels
    assert channels["/turtle1/cmd_vel"]["schemaName"] == "geometry_msgs/Twist"
    tf = channels["/tf"]["schema"]
    assert "MSG: geometry_msgs/TransformStamped" in tf and "MSG: std_msgs/Header" in tf  # (its dependencies)


def test_message_data_is_the_bytes_rospy_serialized(ros, bridge):
    result = run(ros, ws_url(bridge), {"do": "messages", "topic": "/fg/point", "count": 2})
    for message in result["messages"]["messages"]:
        assert base64.b64decode(message["data"]) == struct.pack("<3d", 1.5, -2, 3)
        assert abs(int(message["timestamp"]) / 1e9 - __import__("time").time()) < 30


@pytest.mark.parametrize("length", [108, 109, 70_000])  # frames of 125 and 126 bytes (the two shorter headers' last
# and first), and one long enough to go by reference
def test_message_data_is_whole_whatever_its_frame_header(ros, bridge, length):
    topic, text = f"/fg/text{length}", "t" * length
    with ros.spawn(["rostopic", "pub", "-r", "5", topic, "std_msgs/String", f"data: {text}"], f"text{length}"):
        wait_for(lambda: topic in dict(ros.master().getTopicTypes()), 30, what=topic)
        result = run(ros, ws_url(bridge), {"do": "messages", "topic": topic, "count": 2})
    for message in result["messages"]["messages"]:
        assert base64.b64decode(message["data"]) == struct.pack("<I", length) + text.encode()


def test_channels_come_and_go_with_the_graph(ros, bridge):
    with ros.spawn(["rostopic", "pub", "-r", "2", "/fg/new", "std_msgs/String", "data: hi"], "pub-new") as pub:
        proc = ros.spawn(
            [
                "node",
                str(SCRIPT),
                ws_url(bridge),
                json.dumps({"do": "channels", "topics": ["/fg/new"]}),
                json.dumps({"do": "wait", "seconds": 0.5}),
                json.dumps({"do": "gone", "topic": "/fg/new"}),
            ],
            "foxglove-client",
        )
        wait_for(lambda: '"step":"channels"' in proc.output(), 20, what="the new topic's channel")
        pub.stop()
        state = ros.master().getSystemState()
        assert proc.popen.wait(30) == 0, (proc.output()[-300:], [t for t in state[0] + state[1] if "fg" in t[0]])
    assert '"step":"gone"' in proc.output()


def test_a_twist_published_as_ros1_bytes_drives_the_turtle(ros, bridge):
    before = ros.run(["rostopic", "echo", "-n", "1", "/turtle1/pose/x"]).stdout
    twist = base64.b64encode(struct.pack("<6d", 2.0, 0, 0, 0, 0, 0)).decode()
    run(
        ros,
        ws_url(bridge),
        {"do": "publish", "topic": "/turtle1/cmd_vel", "type": "geometry_msgs/Twist", "data": twist, "count": 10},
    )
    after = ros.run(["rostopic", "echo", "-n", "1", "/turtle1/pose/x"]).stdout
    assert float(after.split()[0]) > float(before.split()[0]) + 0.5


def test_a_twist_published_as_json_drives_the_turtle(ros, bridge):
    before = ros.run(["rostopic", "echo", "-n", "1", "/turtle1/pose/theta"]).stdout
    run(
        ros,
        ws_url(bridge),
        {
            "do": "publish",
            "topic": "/turtle1/cmd_vel",
            "type": "geometry_msgs/Twist",
            "encoding": "json",
            "data": {"angular": {"z": 1.0}},
            "count": 10,
        },
    )
    after = ros.run(["rostopic", "echo", "-n", "1", "/turtle1/pose/theta"]).stdout
    assert float(after.split()[0]) != float(before.split()[0])


def test_bad_data_gets_a_status_and_the_connection_goes_on(ros, bridge):
    short = base64.b64encode(bytes(10)).decode()
    results = run(
        ros,
        ws_url(bridge),
        {"do": "publish", "topic": "/turtle1/cmd_vel", "type": "geometry_msgs/Twist", "data": short},
        {"do": "status", "contains": "geometry_msgs/Twist"},
        {"do": "raw", "data": base64.b64encode(b"\x01" + struct.pack("<I", 4242) + b"xx").decode()},
        {"do": "status", "contains": "4242"},
        {"do": "publish", "topic": "/turtle1/cmd_vel", "type": "turtlesim/Pose", "data": short},
        {"do": "status", "contains": "turtlesim/Pose"},
        {"do": "raw", "text": '{"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 99999}]}'},
        {"do": "status", "contains": "no channel 99999"},
        {"do": "messages", "topic": "/fg/point"},  # (still served)
    )
    assert results["status"]["status"]["level"] == 2


def test_parameters_round_trip_and_updates_reach_subscribers(ros, bridge):
    results = run(
        ros,
        ws_url(bridge),
        {
            "do": "set-params",
            "parameters": [
                {"name": "/fg_test/speed", "value": 2, "type": "float64"},
                {"name": "/fg_test/nested", "value": {"a": [1, 2], "b": "text"}},
                {"name": "/fg_test/blob", "value": base64.b64encode(b"\x00\x01").decode(), "type": "byte_array"},
            ],
        },
        {"do": "get-params", "names": ["/fg_test/speed", "/fg_test/nested", "/fg_test/blob"]},
    )
    master = ros.master()
    assert master.getParam("/fg_test/speed") == 2.0 and isinstance(master.getParam("/fg_test/speed"), float)
    assert master.getParam("/fg_test/nested") == {"a": [1, 2], "b": "text"}
    got = {p["name"]: p for p in results["get-params"]["parameters"]}
    assert got["/fg_test/speed"] == {"name": "/fg_test/speed", "value": 2.0, "type": "float64"}
    assert got["/fg_test/nested"]["value"] == {"a": [1, 2], "b": "text"}
    assert got["/fg_test/blob"]["type"] == "byte_array"
    proc = ros.spawn(
        [
            "node",
            str(SCRIPT),
            ws_url(bridge),
            json.dumps({"do": "watch-params", "names": ["/fg_test/speed"]}),
            json.dumps({"do": "param-update", "name": "/fg_test/speed"}),
        ],
        "foxglove-client",
    )
    wait_for(lambda: '"step":"watch-params"' in proc.output(), 20, what="the subscription")
    wait_for(
        lambda: (ros.run(["rosparam", "set", "/fg_test/speed", "3.5"]), '"param-update"' in proc.output())[1],
        20,
        interval=1.5,
        what="the update",
    )
    assert proc.popen.wait(20) == 0
    assert '"value":3.5' in proc.output()


def test_services_are_called_with_ros1_bytes_and_failures_carry_ros_s_message(ros, bridge):
    name = b"fg_turtle"
    request = struct.pack("<3fI", 3.0, 3.0, 0.0, len(name)) + name
    results = run(
        ros,
        ws_url(bridge),
        {"do": "call", "service": "/spawn", "data": base64.b64encode(request).decode()},
        {"do": "call", "service": "/clear"},
    )
    assert "response" in results["call"], results
    response = base64.b64decode(results["call"]["response"])  # (the last call's: /clear's empty response)
    assert response == b""
    assert "/fg_turtle/pose" in dict(ros.master().getTopicTypes())
    bad = struct.pack("<I", 7) + b"nobody!"
    failed = run(
        ros, ws_url(bridge), {"do": "call", "service": "/kill", "data": base64.b64encode(bad).decode()}, check=False
    )
    assert "nobody!" in failed["call"]["failure"] or "kill" in failed["call"]["failure"]
    json_call = run(
        ros,
        ws_url(bridge),
        {
            "do": "call",
            "service": "/spawn",
            "encoding": "json",
            "data": {"x": 5, "y": 5, "theta": 0, "name": "fg_json"},
        },
    )
    assert json.loads(base64.b64decode(json_call["call"]["response"])) == {"name": "fg_json"}


def test_the_connection_graph_lists_who_publishes_what(ros, bridge):
    graph = run(ros, ws_url(bridge), {"do": "graph", "topic": "/turtle1/pose"})["graph"]["graph"]
    published = {t["name"]: t["publisherIds"] for t in graph["publishedTopics"]}
    assert "/turtlesim" in published["/turtle1/pose"]
    subscribed = {t["name"]: t["subscriberIds"] for t in graph["subscribedTopics"]}
    assert "/turtlesim" in subscribed["/turtle1/cmd_vel"]
    services = {s["name"]: s["providerIds"] for s in graph["advertisedServices"]}
    assert services["/spawn"] == ["/turtlesim"]


def test_assets_are_package_files_and_nothing_else(ros, bridge):
    mesh = (REPO / "meshes" / "turtle_shell.stl").read_bytes()
    results = run(ros, ws_url(bridge), {"do": "asset", "uri": "package://turtlesim/meshes/turtle_shell.stl"})
    assert base64.b64decode(results["asset"]["data"]) == mesh
    for uri, words in [
        ("package://turtlesim/../../etc/passwd.stl", "'..'"),
        ("package://turtlesim/package.xml", "not a mesh"),
        ("file:///etc/passwd", "only package://"),
        ("package://no_such_package/a.stl", "no ROS package"),
        ("package://turtlesim/meshes/missing.stl", "no such file"),
    ]:
        answer = run(ros, ws_url(bridge), {"do": "asset", "uri": uri}, check=False)["asset"]
        assert words in answer["error"], (uri, answer)


def test_the_robot_description_names_a_mesh_the_bridge_serves(ros, bridge):
    description = ros.master().getParam("/robot_description")
    assert "package://turtlesim/meshes/turtle_shell.stl" in description and "<box" in description


def test_a_rosbridge_client_is_served_beside_foxglove_clients(ros, bridge):
    proc = ros.spawn(
        ["node", str(SCRIPT), ws_url(bridge), json.dumps({"do": "messages", "topic": "/turtle1/pose", "count": 50})],
        "foxglove-client",
    )
    client = WsClient(ws_url(bridge))
    client.send({"op": "subscribe", "topic": "/fg/point"})
    assert client.recv_until(lambda f: f.get("op") == "publish")["msg"] == {"x": 1.5, "y": -2.0, "z": 3.0}
    assert proc.popen.wait(30) == 0, proc.output()


def test_with_use_sim_time_clients_get_the_clock_and_messages_stamped_by_it(ros, world):
    master = ros.master()
    master.setParam("/use_sim_time", True)
    try:
        with ros.spawn(
            ["rostopic", "pub", "-r", "20", "/clock", "rosgraph_msgs/Clock", "{clock: {secs: 42, nsecs: 7}}"]
        ):
            proc, port = start_bridge(ros, node_name="foxglove_sim_time")
            with proc:
                results = run(
                    ros,
                    f"ws://127.0.0.1:{port}",
                    {"do": "info"},
                    {"do": "time"},
                    {"do": "messages", "topic": "/fg/point"},
                )
    finally:
        master.deleteParam("/use_sim_time")
    assert "time" in results["info"]["info"]["capabilities"]
    assert results["time"]["time"] == str(42 * 10**9 + 7)
    assert results["messages"]["messages"][0]["timestamp"] == str(42 * 10**9 + 7)


def test_a_foxglove_client_that_drives_and_leaves_is_stopped(ros, bridge):
    twist = base64.b64encode(struct.pack("<6d", 0.7, 0, 0, 0, 0, 0)).decode()
    step = {"do": "publish", "topic": "/fg/drive", "type": "geometry_msgs/Twist", "data": twist, "count": 40}
    client = ros.spawn(["node", str(SCRIPT), ws_url(bridge), json.dumps(step)], "foxglove-client")
    wait_for(lambda: any(name == "/fg/drive" for name, _ in ros.master().getSystemState()[0]), 20, what="/fg/drive")
    with ros.spawn(["rostopic", "echo", "/fg/drive/linear/x"], "echo-drive") as echo:
        wait_for(lambda: "0.7" in echo.output(), 20, what="the client's Twists")
        assert client.popen.wait(30) == 0, client.output()
        # (the client left: the dead-man stop sends one zero Twist on what it drove)
        wait_for(lambda: echo.output().split()[-2:] == ["0.0", "---"], 10, what=lambda: echo.output()[-200:])


def test_clients_coming_and_going_are_logged_with_their_protocol(ros, bridge):
    run(ros, ws_url(bridge), {"do": "info"})
    wait_for(
        lambda: "Client disconnected (foxglove.websocket.v1, 127.0.0.1)" in bridge.proc.output(),
        10,
        what=lambda: bridge.proc.output()[-500:],
    )
    assert "Client connected (foxglove.websocket.v1, 127.0.0.1)" in bridge.proc.output()
    client = WsClient(ws_url(bridge))
    client.send({"op": "subscribe", "topic": "/fg/point"})
    client.recv_until(lambda f: f.get("op") == "publish")
    assert "Client connected (rosbridge, 127.0.0.1)" in bridge.proc.output()


def test_with_authenticate_a_foxglove_client_is_refused_with_a_reason_it_shows(ros):
    proc, port = start_bridge(ros, node_name="foxglove_auth", authenticate="true")
    with proc:
        results = run(ros, f"ws://127.0.0.1:{port}", {"do": "info"}, check=False)
    assert results["closed"]["code"] == 1008 and "rosauth" in results["closed"]["reason"]
    assert "a Foxglove client refused" in proc.output()


def test_providers_that_never_answer_do_not_hold_channel_updates(ros, bridge):
    # three services whose provider takes the connection and never answers the type probe (a stopped node)
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(16)
    master, caller = ros.master(), xmlrpc.client.ServerProxy(ros.uri)
    uri = f"rosrpc://127.0.0.1:{silent.getsockname()[1]}"
    names = [f"/fg/silent_{i}" for i in range(3)]
    try:
        for name in names:
            caller.registerService("/fg_silent", name, uri, "http://127.0.0.1:9/")
        client = WsClient(ws_url(bridge), headers={"Sec-WebSocket-Protocol": "foxglove.websocket.v1"})
        client.recv_until(lambda f: f.get("op") == "advertise", timeout=20)  # (the first poll, which probed them)
        started = time.monotonic()
        with ros.spawn(["rostopic", "pub", "-r", "2", "/fg/late", "std_msgs/String", "data: x"], "pub-late"):
            client.recv_until(lambda f: f.get("op") == "advertise" and "/fg/late" in str(f), timeout=30)
            took = time.monotonic() - started
    finally:
        for name in names:
            caller.unregisterService("/fg_silent", name, uri)
        silent.close()
    assert took < 4.0, f"the new topic's channel came {took:.1f} s after its publisher started"
    assert master.getSystemState()  # (the master still answers)
