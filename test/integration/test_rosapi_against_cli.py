"""rosbridge.ros_side.rosapi against a real roscore, checked against what the stock CLI tools report."""

import json
import re
import time

import pytest
import yaml

from rosbridge.globs import Globs
from rosbridge.message_types import UnknownType, message_class
from rosbridge.ros_side.rosapi import SERVICES, Rosapi, RosapiError

from harness import wait_for

BRIDGE = "/rosapi_test_bridge"  # the node name the bridge would give rosapi


@pytest.fixture(scope="module")
def graph(ros, node):
    """A small ROS graph under /rosapi_test: a publisher process, an in-process subscriber and service,
    the five topics of an action server, and parameters."""
    from geometry_msgs.msg import Twist
    from std_msgs.msg import Empty as EmptyMsg
    from std_srvs.srv import Empty, EmptyResponse

    chatter = ros.spawn(
        ["rostopic", "pub", "-r", "5", "/rosapi_test/chatter", "std_msgs/String", "data: hi"], "chatter"
    )
    sub = node.Subscriber("/rosapi_test/cmd", Twist, lambda msg: None)
    srv = node.Service("/rosapi_test/reset", Empty, lambda req: EmptyResponse())
    action = [
        node.Publisher(f"/rosapi_test/act/{t}", EmptyMsg, queue_size=1)
        for t in ("goal", "cancel", "result", "feedback", "status")
    ]
    try:
        ros.run(["rosparam", "set", "/rosapi_test/gain", "2.5"])
        ros.run(["rosparam", "set", "/rosapi_test/label", "turtle"])
        ros.run(["rosparam", "set", "/rosapi_test/nested", "{a: 1, b: [1, 2], c: {d: true}}"])
        wait_for(lambda: "/rosapi_test/chatter" in ros.run(["rostopic", "list"]).stdout, 20, what="chatter")
        yield node.get_name()
    finally:
        for handle in [sub, srv, *action]:
            handle.unregister() if hasattr(handle, "unregister") else handle.shutdown()
        chatter.stop()


@pytest.fixture
def rosapi(ros, node):
    return Rosapi(ros.uri, BRIDGE, Globs(), node.get_rostime)


def settle(ours, theirs, timeout=20):
    """Both answers once they agree (the graph may still be changing); else fails showing the difference."""
    try:
        return wait_for(lambda: (lambda a, b: a == b and (a,))(ours(), theirs()), timeout, interval=0.3)[0]
    except AssertionError:
        assert ours() == theirs()


def cli_items(text):
    """The names in ` * name ...` lines."""
    return [line.split()[1] for line in text.splitlines() if line.startswith(" * ")]


def cli_topics(ros):
    """{topic: type} from `rostopic list -v`."""
    return {
        m[1]: m[2] for m in re.finditer(r"^ \* (\S+) \[([^\]]*)\]", ros.run(["rostopic", "list", "-v"]).stdout, re.M)
    }


def cli_node_info(ros, node_name):
    """{section: [names]} of `rosnode info` (Publications, Subscriptions, Services)."""
    text = ros.run(["rosnode", "info", "-q", node_name]).stdout
    sections = {}
    for title in ("Publications", "Subscriptions", "Services"):
        block = re.search(rf"^{title}:(.*?)(?:\n\n|\Z)", text, re.S | re.M).group(1)
        sections[title] = sorted(cli_items(block))
    return sections


# ---- topics


def test_topics_match_rostopic_list(ros, graph, rosapi):
    def ours():
        answer = rosapi.call("/rosapi/topics", {})
        return dict(zip(answer["topics"], answer["types"]))

    topics = settle(ours, lambda: cli_topics(ros))
    assert topics["/rosapi_test/chatter"] == "std_msgs/String"
    assert topics["/rosapi_test/cmd"] == "geometry_msgs/Twist"  # subscribed only
    answer = rosapi.call("/rosapi/topics", {})
    assert answer["topics"] == sorted(answer["topics"])


def test_topic_type_and_topics_for_type(ros, graph, rosapi):
    for topic, topic_type in cli_topics(ros).items():
        assert rosapi.call("/rosapi/topic_type", {"topic": topic}) == {"type": topic_type}
    assert rosapi.call("/rosapi/topic_type", {"topic": "/no/such/topic"}) == {"type": ""}
    assert rosapi.call("/rosapi/topic_type", ["/rosapi_test/chatter"]) == {"type": "std_msgs/String"}

    logs = rosapi.call("/rosapi/topics_for_type", {"type": "rosgraph_msgs/Log"})["topics"]
    assert logs == sorted(t for t, ty in cli_topics(ros).items() if ty == "rosgraph_msgs/Log")
    assert "/rosout" in logs
    assert rosapi.call("/rosapi/topics_for_type", {"type": "nobody/Uses"}) == {"topics": []}


def test_topics_and_raw_types_carry_full_definitions(ros, graph, rosapi):
    answer = rosapi.call("/rosapi/topics_and_raw_types")
    assert len(answer["topics"]) == len(answer["types"]) == len(answer["typedefs_full_text"])
    full = dict(zip(answer["topics"], answer["typedefs_full_text"]))
    raw = ros.run(["rosmsg", "show", "-r", "geometry_msgs/Twist"]).stdout
    assert raw.strip().splitlines()[0] in full["/rosapi_test/cmd"]
    assert "MSG: geometry_msgs/Vector3" in full["/rosapi_test/cmd"]
    assert full["/rosapi_test/chatter"].strip() == "string data"


def test_publishers_and_subscribers_match_rostopic_info(ros, graph, rosapi):
    for topic in ("/rosapi_test/chatter", "/rosapi_test/cmd", "/rosout"):
        info = ros.run(["rostopic", "info", topic]).stdout
        pubs_text, _, subs_text = info.partition("Subscribers:")
        assert rosapi.call("/rosapi/publishers", {"topic": topic}) == {"publishers": sorted(cli_items(pubs_text))}
        assert rosapi.call("/rosapi/subscribers", {"topic": topic}) == {"subscribers": sorted(cli_items(subs_text))}
    assert rosapi.call("/rosapi/subscribers", {"topic": "/rosapi_test/cmd"}) == {"subscribers": [graph]}
    assert rosapi.call("/rosapi/publishers", {"topic": "/nothing"}) == {"publishers": []}


def test_action_servers_are_namespaces_with_the_five_action_topics(graph, rosapi):
    assert "/rosapi_test/act" in rosapi.call("/rosapi/action_servers")["action_servers"]
    assert "/rosapi_test" not in rosapi.call("/rosapi/action_servers")["action_servers"]


# ---- services


def test_services_match_rosservice_list_plus_rosapi(ros, graph, rosapi):
    services = settle(
        lambda: rosapi.call("/rosapi/services")["services"],
        lambda: sorted(set(ros.run(["rosservice", "list"]).stdout.split()) | set(SERVICES)),
    )
    assert "/rosapi_test/reset" in services and "/rosapi/get_param" in services


def test_service_type_node_host_match_rosservice(ros, graph, rosapi):
    for service in ("/rosapi_test/reset", "/rosout/get_loggers"):
        cli = lambda *args: ros.run(["rosservice", *args, service]).stdout.strip()
        assert rosapi.call("/rosapi/service_type", {"service": service}) == {"type": cli("type")}
        assert rosapi.call("/rosapi/service_node", {"service": service}) == {"node": cli("node")}
        host = re.match(r"rosrpc://([^:/]+)", cli("uri")).group(1)
        assert rosapi.call("/rosapi/service_host", {"service": service}) == {"host": host}
    for query in ("/rosapi/service_type", "/rosapi/service_node", "/rosapi/service_host"):
        assert list(rosapi.call(query, {"service": "/no/such/service"}).values()) == [""]
    assert rosapi.call("/rosapi/service_type", {"service": "/rosapi/topics"}) == {"type": "rosapi/Topics"}
    assert rosapi.call("/rosapi/service_node", {"service": "/rosapi/topics"}) == {"node": BRIDGE}


def test_services_for_type_and_providers_match_rosservice_find(ros, graph, rosapi):
    empties = ros.run(["rosservice", "find", "std_srvs/Empty"]).stdout.split()
    assert rosapi.call("/rosapi/services_for_type", {"type": "std_srvs/Empty"}) == {"services": sorted(empties)}
    assert rosapi.call("/rosapi/services_for_type", {"type": "rosapi/GetParam"}) == {"services": ["/rosapi/get_param"]}
    providers = sorted({ros.run(["rosservice", "node", s]).stdout.strip() for s in empties})
    assert rosapi.call("/rosapi/service_providers", {"service": "std_srvs/Empty"}) == {"providers": providers}
    assert rosapi.call("/rosapi/service_providers", {"service": "/rosapi_test/reset"}) == {"providers": [graph]}


# ---- nodes


def test_nodes_match_rosnode_list(ros, graph, rosapi):
    nodes = settle(
        lambda: rosapi.call("/rosapi/nodes")["nodes"],
        lambda: sorted(set(ros.run(["rosnode", "list"]).stdout.split()) | {BRIDGE}),
    )
    assert graph in nodes and "/rosout" in nodes


def test_node_details_match_rosnode_info(ros, graph, rosapi):
    for node_name in (graph, "/rosout"):
        info = cli_node_info(ros, node_name)
        assert rosapi.call("/rosapi/node_details", {"node": node_name}) == {
            "publishing": info["Publications"],
            "subscribing": info["Subscriptions"],
            "services": info["Services"],
        }
    details = rosapi.call("/rosapi/node_details", {"node": BRIDGE})
    assert details["services"] == sorted(SERVICES)
    assert rosapi.call("/rosapi/node_details", {"node": "/nobody"}) == {
        "publishing": [],
        "subscribing": [],
        "services": [],
    }


# ---- types


def cli_fields(ros, command, type_name):
    """Top-level (fields, constants) of `rosmsg show` / `rossrv show` text."""
    fields, constants = [], []
    for line in ros.run([command, "show", type_name]).stdout.splitlines():
        if line and not line.startswith(" ") and line != "---":
            field_type, name = line.split(" ", 1)
            (constants if "=" in name else fields).append((field_type, name))
    return fields, constants


def cli_typedef_fields(typedef):
    """A typedef's fields written back as `rosmsg show` writes them, e.g. ("float64[9]", "K")."""
    suffix = {-1: "", 0: "[]"}
    return [
        (t + suffix.get(n, f"[{n}]"), name)
        for t, n, name in zip(typedef["fieldtypes"], typedef["fieldarraylen"], typedef["fieldnames"])
    ]


@pytest.mark.parametrize(
    "type_name",
    [
        "geometry_msgs/Twist",
        "geometry_msgs/PoseWithCovarianceStamped",
        "geometry_msgs/PoseArray",
        "turtlesim/Pose",
        "std_msgs/Empty",
    ],
)
def test_message_details_match_rosmsg_show(ros, rosapi, type_name):
    typedefs = rosapi.call("/rosapi/message_details", {"type": type_name})["typedefs"]
    assert typedefs[0]["type"] == type_name
    fields, constants = cli_fields(ros, "rosmsg", type_name)
    assert cli_typedef_fields(typedefs[0]) == fields
    assert sorted(zip(typedefs[0]["constnames"], typedefs[0]["constvalues"])) == sorted(
        (name.split("=")[0], name.split("=")[1]) for _, name in constants
    )
    listed = [t["type"] for t in typedefs]
    assert len(listed) == len(set(listed))
    nested = {t for t, n in zip(typedefs[0]["fieldtypes"], typedefs[0]["fieldarraylen"]) if "/" in t or t == "time"}
    assert nested <= set(listed)
    for typedef in typedefs:
        assert len({len(typedef[k]) for k in ("fieldnames", "fieldtypes", "fieldarraylen", "examples")}) == 1


def test_message_details_constants_match_the_definition(rosapi):
    log = rosapi.call("/rosapi/message_details", {"type": "rosgraph_msgs/Log"})["typedefs"][0]
    definition = message_class("rosgraph_msgs/Log")._full_text.split("=" * 80)[0]
    constants = re.findall(r"^byte (\w+)=(\d+)", definition, re.M)
    assert len(constants) == 5
    assert sorted(zip(log["constnames"], log["constvalues"])) == sorted(constants)
    assert log["fieldtypes"][log["fieldnames"].index("level")] == "byte"


def test_message_details_examples_and_array_lengths(rosapi):
    info = rosapi.call("/rosapi/message_details", {"type": "sensor_msgs/CameraInfo"})["typedefs"]
    by_type = {t["type"]: t for t in info}
    camera = dict(
        zip(
            by_type["sensor_msgs/CameraInfo"]["fieldnames"],
            zip(
                by_type["sensor_msgs/CameraInfo"]["fieldtypes"],
                by_type["sensor_msgs/CameraInfo"]["fieldarraylen"],
                by_type["sensor_msgs/CameraInfo"]["examples"],
            ),
        )
    )
    assert camera["header"] == ("std_msgs/Header", -1, "{}")
    assert camera["height"] == ("uint32", -1, "0")
    assert camera["distortion_model"] == ("string", -1, "")
    assert camera["D"] == ("float64", 0, "[]")
    assert camera["K"] == ("float64", 9, "[]")
    assert camera["roi"] == ("sensor_msgs/RegionOfInterest", -1, "{}")
    roi = by_type["sensor_msgs/RegionOfInterest"]
    assert roi["examples"][roi["fieldnames"].index("do_rectify")] == "False"
    assert by_type["time"] == {
        "type": "time",
        "fieldnames": ["secs", "nsecs"],
        "fieldtypes": ["int32", "int32"],
        "fieldarraylen": [-1, -1],
        "examples": ["0", "0"],
        "constnames": [],
        "constvalues": [],
    }
    assert [t["type"] for t in info] == [
        "sensor_msgs/CameraInfo",
        "std_msgs/Header",
        "time",
        "sensor_msgs/RegionOfInterest",
    ]


def test_service_request_and_response_details_match_rossrv_show(ros, rosapi):
    request = rosapi.call("/rosapi/service_request_details", {"type": "turtlesim/Spawn"})["typedefs"]
    response = rosapi.call("/rosapi/service_response_details", {"type": "turtlesim/Spawn"})["typedefs"]
    text = ros.run(["rossrv", "show", "turtlesim/Spawn"]).stdout
    request_text, _, response_text = text.partition("---")
    expected = lambda part: [tuple(line.split()) for line in part.strip().splitlines()]
    assert request[0]["type"] == "turtlesim/SpawnRequest"
    assert cli_typedef_fields(request[0]) == expected(request_text)
    assert request[0]["examples"] == ["0.0", "0.0", "0.0", ""]
    assert response[0]["type"] == "turtlesim/SpawnResponse"
    assert cli_typedef_fields(response[0]) == expected(response_text)


def test_unknown_types_are_errors(rosapi):
    with pytest.raises(UnknownType, match="nope/Nothing"):
        rosapi.call("/rosapi/message_details", {"type": "nope/Nothing"})
    with pytest.raises(UnknownType, match="nope/Nothing"):
        rosapi.call("/rosapi/service_request_details", {"type": "nope/Nothing"})
    with pytest.raises(UnknownType):
        rosapi.call("/rosapi/message_details", {})


# ---- parameters


def rosparam_get(ros, name):
    return yaml.safe_load(ros.run(["rosparam", "get", name]).stdout)


def test_get_param_matches_rosparam_get(ros, graph, rosapi):
    for name in ("/rosapi_test/gain", "/rosapi_test/label", "/rosapi_test/nested", "/rosapi_test"):
        assert json.loads(rosapi.call("/rosapi/get_param", {"name": name})["value"]) == rosparam_get(ros, name)
    assert rosapi.call("/rosapi/get_param", {"name": "rosapi_test/gain"}) == {"value": "2.5"}


def test_missing_param_gives_the_default_or_null(rosapi):
    get = lambda **args: rosapi.call("/rosapi/get_param", {"name": "/rosapi_test/missing", **args})["value"]
    assert get() == "null"
    assert get(default="") == "null"
    assert get(default="[1, 2]") == "[1, 2]"
    assert get(default="plain text") == '"plain text"'


def test_set_has_delete_param_roundtrip_with_rosparam(ros, graph, rosapi):
    name = "/rosapi_test/written"
    rosapi.call("/rosapi/set_param", {"name": name, "value": json.dumps({"x": [1, 2.5], "on": True})})
    assert rosparam_get(ros, name) == {"x": [1, 2.5], "on": True}
    assert rosapi.call("/rosapi/has_param", {"name": name}) == {"exists": True}
    rosapi.call("/rosapi/set_param", {"name": name, "value": '"text"'})
    assert rosparam_get(ros, name) == "text"
    rosapi.call("/rosapi/delete_param", {"name": name})
    assert ros.run(["rosparam", "get", name], check=False).returncode != 0
    assert rosapi.call("/rosapi/has_param", {"name": name}) == {"exists": False}
    rosapi.call("/rosapi/delete_param", {"name": name})  # deleting a missing param is not an error


def test_bad_param_values_are_refused_with_clear_errors(graph, rosapi):
    with pytest.raises(RosapiError, match="must be JSON"):
        rosapi.call("/rosapi/set_param", {"name": "/rosapi_test/bad", "value": "not json"})
    with pytest.raises(RosapiError, match="null"):
        rosapi.call("/rosapi/set_param", {"name": "/rosapi_test/bad", "value": "[1, null]"})
    with pytest.raises(RosapiError, match="cannot store"):
        rosapi.call("/rosapi/set_param", {"name": "/rosapi_test/bad", "value": str(2**40)})
    with pytest.raises(RosapiError, match="invalid parameter name"):
        rosapi.call("/rosapi/get_param", {"name": "bad name!"})
    assert rosapi.call("/rosapi/has_param", {"name": "/rosapi_test/bad"}) == {"exists": False}


def test_get_param_names_and_search_param(ros, graph, rosapi):
    settle(
        lambda: rosapi.call("/rosapi/get_param_names")["names"],
        lambda: sorted(ros.run(["rosparam", "list"]).stdout.split()),
    )
    assert rosapi.call("/rosapi/search_param", {"name": "rosapi_test"}) == {"global_name": "/rosapi_test"}
    assert rosapi.call("/rosapi/search_param", {"name": "no_such_param"}) == {"global_name": ""}


def test_get_time_is_the_ros_time(rosapi):
    answer = rosapi.call("/rosapi/get_time")
    assert set(answer["time"]) == {"secs", "nsecs"}
    assert abs(answer["time"]["secs"] + answer["time"]["nsecs"] / 1e9 - time.time()) < 60


# ---- requests


def test_bad_requests_are_clear_errors(rosapi):
    with pytest.raises(RosapiError, match="has no field 'topik'"):
        rosapi.call("/rosapi/topic_type", {"topik": "/x"})
    with pytest.raises(RosapiError, match="must be a string"):
        rosapi.call("/rosapi/topic_type", {"topic": 5})
    with pytest.raises(RosapiError, match="takes 1 argument"):
        rosapi.call("/rosapi/topic_type", ["/a", "/b"])
    with pytest.raises(RosapiError, match="must be an object"):
        rosapi.call("/rosapi/topics", "x")
    with pytest.raises(RosapiError, match="does not exist"):
        rosapi.call("/rosapi/nope", {})


def test_handles_and_lists_every_rosapi_service(rosapi):
    assert all(rosapi.handles(name) for name in SERVICES)
    assert not rosapi.handles("/rosapi_test/reset") and not rosapi.handles("/rosapi")
    assert rosapi.services()["/rosapi/topics"] == "rosapi/Topics"
    assert rosapi.services()["/rosapi/get_param"] == "rosapi/GetParam"
    assert len(rosapi.services()) == 25


def test_unreachable_master_is_a_clear_error(node):
    from harness import free_port

    lost = Rosapi(f"http://127.0.0.1:{free_port()}", BRIDGE, None, node.get_rostime)
    with pytest.raises(RosapiError, match="cannot reach the ROS master"):
        lost.call("/rosapi/topics")


# ---- globs


@pytest.fixture
def filtered(ros, node):
    return Rosapi(
        ros.uri,
        BRIDGE,
        Globs.parse(
            topics_glob="[/rosapi_test/*]",
            services_glob="['/rosapi_test/*']",
            params_glob="[/rosapi_test/gain, /rosapi_test/nested]",
        ),
        node.get_rostime,
    )


def test_topics_glob_hides_topics_everywhere(graph, filtered):
    topics = filtered.call("/rosapi/topics")["topics"]
    assert "/rosapi_test/chatter" in topics and "/rosout" not in topics
    assert all(t.startswith("/rosapi_test/") for t in topics)
    assert filtered.call("/rosapi/topic_type", {"topic": "/rosout"}) == {"type": ""}
    assert filtered.call("/rosapi/topics_for_type", {"type": "rosgraph_msgs/Log"}) == {"topics": []}
    assert filtered.call("/rosapi/publishers", {"topic": "/rosout_agg"}) == {"publishers": []}
    details = filtered.call("/rosapi/node_details", {"node": "/rosout"})
    assert details["publishing"] == [] and details["subscribing"] == []


def test_services_glob_hides_services_everywhere(graph, filtered):
    assert filtered.call("/rosapi/services") == {"services": ["/rosapi_test/reset"]}
    assert filtered.call("/rosapi/service_type", {"service": "/rosout/get_loggers"}) == {"type": ""}
    assert filtered.call("/rosapi/service_node", {"service": "/rosout/get_loggers"}) == {"node": ""}
    assert filtered.call("/rosapi/service_host", {"service": "/rosout/get_loggers"}) == {"host": ""}
    assert filtered.call("/rosapi/services_for_type", {"type": "roscpp/GetLoggers"}) == {"services": []}
    assert filtered.call("/rosapi/node_details", {"node": "/rosout"})["services"] == []
    assert filtered.call("/rosapi/topics")["topics"]  # /rosapi/* stay callable whatever the glob


def test_params_glob_hides_and_protects_params(ros, graph, filtered):
    assert filtered.call("/rosapi/get_param_names")["names"] == [
        "/rosapi_test/gain",
        "/rosapi_test/nested/a",
        "/rosapi_test/nested/b",
        "/rosapi_test/nested/c/d",
    ]
    assert filtered.call("/rosapi/get_param", {"name": "/rosapi_test/gain"}) == {"value": "2.5"}
    assert json.loads(filtered.call("/rosapi/get_param", {"name": "/rosapi_test/nested"})["value"])["c"] == {"d": True}
    for service, args in [
        ("/rosapi/get_param", {}),
        ("/rosapi/set_param", {"value": "1"}),
        ("/rosapi/delete_param", {}),
        ("/rosapi/get_param", {"name": "/rosapi_test"}),
    ]:
        with pytest.raises(RosapiError, match="hidden by params_glob"):
            filtered.call(service, {"name": "/rosapi_test/label", **args})
    assert rosparam_get(ros, "/rosapi_test/label") == "turtle"
    assert filtered.call("/rosapi/has_param", {"name": "/rosapi_test/label"}) == {"exists": False}
    assert filtered.call("/rosapi/search_param", {"name": "rosapi_test"}) == {"global_name": ""}
    assert filtered.call("/rosapi/search_param", {"name": "/rosapi_test/gain"}) == {"global_name": "/rosapi_test/gain"}
