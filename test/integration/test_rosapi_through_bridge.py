"""The /rosapi services through the running bridge, called by roslibpy as a client would, checked against
the stock CLI tools; and the launch args' globs hiding topics, services and parameters."""

import socket
import time

import pytest
import roslibpy
import yaml
from test_rosapi_against_cli import graph, settle  # noqa: F401  (graph is a fixture)

from rosbridge.ros_side.rosapi import SERVICES

from fixtures import bridge_fixture
from harness import wait_for


def client_of(port):
    """A roslibpy client of the bridge on this port (yielded), closed after."""
    client = roslibpy.Ros(host="127.0.0.1", port=port)
    client.run(timeout=30)
    try:
        yield client
    finally:
        client.close()


rosapi_bridge = bridge_fixture("rosapi_bridge", needs=("graph",))
rosapi_glob_bridge = bridge_fixture(
    "rosapi_glob_bridge",
    needs=("graph",),
    topics_glob="[/rosapi_test/*]",
    services_glob="['/rosapi_test/*']",
    params_glob="[/rosapi_test/gain]",
)


@pytest.fixture(scope="module")
def bridge(rosapi_bridge):
    """A roslibpy client of the bridge."""
    yield from client_of(rosapi_bridge)


@pytest.fixture(scope="module")
def glob_bridge(rosapi_glob_bridge):
    """A roslibpy client of the bridge with globs."""
    yield from client_of(rosapi_glob_bridge)


def cli_list(ros, *args):
    return sorted(ros.run(list(args)).stdout.split())


def test_get_topics_and_types_match_rostopic(ros, bridge):
    topics = settle(lambda: sorted(bridge.get_topics()), lambda: cli_list(ros, "rostopic", "list"))
    assert "/rosapi_test/chatter" in topics and "/client_count" in topics
    assert bridge.get_topic_type("/rosapi_test/chatter") == "std_msgs/String"
    assert bridge.get_topic_type("/no/such/topic") == ""
    assert bridge.get_topics_for_type("std_msgs/Int32") == ["/client_count"]


def test_get_services_match_rosservice_plus_rosapi(ros, bridge):
    services = settle(
        lambda: sorted(bridge.get_services()), lambda: sorted(set(cli_list(ros, "rosservice", "list")) | set(SERVICES))
    )
    assert "/rosapi_test/reset" in services and "/rosapi/get_param" in services
    assert bridge.get_service_type("/rosapi_test/reset") == "std_srvs/Empty"
    assert bridge.get_service_type("/rosapi/topics") == "rosapi/Topics"
    # as `rosservice find` says (other tests' turtlesims may provide std_srvs/Empty services too)
    assert bridge.get_services_for_type("std_srvs/Empty") == cli_list(ros, "rosservice", "find", "std_srvs/Empty")


@pytest.fixture
def stopped_services(ros):
    """Three services whose provider accepts connections and never answers, as a stopped (SIGSTOP) node does."""
    listener = socket.create_server(("127.0.0.1", 0))
    port = listener.getsockname()[1]
    master = ros.master()
    names = [f"/rosapi_test/stopped_{n}" for n in range(3)]
    for name in names:
        master.registerService(name, f"rosrpc://127.0.0.1:{port}", f"http://127.0.0.1:{port}/")
    yield names
    for name in names:
        master.unregisterService(name, f"rosrpc://127.0.0.1:{port}")
    listener.close()


def test_service_listings_by_type_answer_in_time_with_stopped_providers(graph, bridge, stopped_services):
    # roslibpy waits 3 s for a rosapi answer; asking one provider at a time for 5 s each took 15 s here
    found = bridge.get_services_for_type("std_srvs/Empty")
    assert "/rosapi_test/reset" in found and not set(found) & set(stopped_services)
    providers = roslibpy.Service(bridge, "/rosapi/service_providers", "rosapi/ServiceProviders")
    assert graph in providers.call(roslibpy.ServiceRequest({"service": "std_srvs/Empty"}), timeout=3)["providers"]
    assert bridge.get_service_type(stopped_services[0]) == ""


def test_get_nodes_and_node_details_match_rosnode(ros, graph, bridge):
    nodes = settle(lambda: sorted(bridge.get_nodes()), lambda: cli_list(ros, "rosnode", "list"))
    assert "/rosapi_bridge" in nodes and graph in nodes
    details = bridge.get_node_details("/rosapi_bridge")
    assert set(SERVICES) <= set(details["services"])
    assert "/client_count" in details["publishing"]
    assert "/rosapi_test/cmd" in bridge.get_node_details(graph)["subscribing"]


def test_message_and_service_details(bridge):
    typedefs = bridge.get_message_details("geometry_msgs/Twist")["typedefs"]
    assert [t["type"] for t in typedefs] == ["geometry_msgs/Twist", "geometry_msgs/Vector3"]
    assert typedefs[0]["fieldnames"] == ["linear", "angular"]
    assert typedefs[1]["examples"] == ["0.0", "0.0", "0.0"]
    request = bridge.get_service_request_details("std_srvs/SetBool")["typedefs"]
    assert request[0]["fieldnames"] == ["data"] and request[0]["fieldtypes"] == ["bool"]
    response = bridge.get_service_response_details("std_srvs/SetBool")["typedefs"]
    assert response[0]["fieldnames"] == ["success", "message"]
    with pytest.raises(roslibpy.core.ServiceException, match="nope/Nothing"):
        bridge.get_message_details("nope/Nothing")


def test_details_of_this_packages_own_types(bridge):
    pose = bridge.get_message_details("turtlesim/Pose")["typedefs"]
    assert pose[0]["fieldnames"] == ["x", "y", "theta", "linear_velocity", "angular_velocity"]
    spawn = bridge.get_service_request_details("turtlesim/Spawn")["typedefs"]
    assert spawn[0]["fieldnames"] == ["x", "y", "theta", "name"]


def test_params_get_set_delete_agree_with_rosparam(ros, bridge):
    settle(lambda: sorted(bridge.get_params()), lambda: cli_list(ros, "rosparam", "list"))
    assert roslibpy.Param(bridge, "/rosapi_test/gain").get() == 2.5
    assert bridge.get_param("/rosapi_test/nested") == yaml.safe_load(
        ros.run(["rosparam", "get", "/rosapi_test/nested"]).stdout
    )

    param = roslibpy.Param(bridge, "/rosapi_test/from_client")
    param.set({"speed": 1.5, "names": ["a", "b"]}, timeout=30)
    assert yaml.safe_load(ros.run(["rosparam", "get", "/rosapi_test/from_client"]).stdout) == {
        "speed": 1.5,
        "names": ["a", "b"],
    }
    assert "/rosapi_test/from_client/speed" in bridge.get_params()
    param.delete(timeout=30)
    assert ros.run(["rosparam", "get", "/rosapi_test/from_client"], check=False).returncode != 0
    assert param.get(timeout=30) is None  # missing: "null"


def test_bad_param_value_is_a_service_error(bridge):
    set_param = roslibpy.Service(bridge, "/rosapi/set_param", "rosapi/SetParam")
    with pytest.raises(roslibpy.core.ServiceException, match="must be JSON"):
        set_param.call(roslibpy.ServiceRequest({"name": "/rosapi_test/bad", "value": "not json"}), timeout=30)
    assert bridge.get_topics()  # the connection still works


def test_get_time(bridge):
    now = bridge.get_time()
    assert abs(now.secs + now.nsecs / 1e9 - time.time()) < 60


def test_action_servers(bridge):
    found = []
    bridge.get_action_servers(found.append)
    assert "/rosapi_test/act" in wait_for(lambda: found, 30, what="action_servers answer")[0]["action_servers"]


def test_globs_hide_topics_services_and_params(ros, glob_bridge):
    topics = glob_bridge.get_topics()
    assert "/rosapi_test/chatter" in topics
    assert all(t.startswith("/rosapi_test/") for t in topics)
    assert glob_bridge.get_topic_type("/rosout") == ""
    assert glob_bridge.get_services() == ["/rosapi_test/reset"]
    assert glob_bridge.get_params() == ["/rosapi_test/gain"]
    assert glob_bridge.get_param("/rosapi_test/gain") == 2.5
    with pytest.raises(roslibpy.core.ServiceException, match="hidden by params_glob"):
        glob_bridge.get_param("/rosapi_test/label")
    with pytest.raises(roslibpy.core.ServiceException, match="hidden by params_glob"):
        roslibpy.Param(glob_bridge, "/rosapi_test/label").set("changed", timeout=30)
    assert ros.run(["rosparam", "get", "/rosapi_test/label"]).stdout.strip() == "turtle"
