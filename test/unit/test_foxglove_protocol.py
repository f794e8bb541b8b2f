"""The Foxglove WebSocket protocol's pure parts: its binary messages, parameter values, the catalog of channels
and services, and one client's session over a recording backend."""

import json
import struct
import types
import xmlrpc.client

import pytest

from rosbridge.contract import DELETE, GraphState
from rosbridge.errors import RequestError
from rosbridge.foxglove import catalog as catalog_module
from rosbridge.foxglove import parameters as params
from rosbridge.foxglove import wire
from rosbridge.foxglove.catalog import Catalog
from rosbridge.foxglove.session import MAX_PARAMETER_NAMES, MAX_PARAMETER_REQUESTS, FoxgloveSession
from rosbridge.globs import Globs
from rosbridge.protocol import Config
from rosbridge.protocol.encoded import SplicedFrame, TopicRead

from fakes import BackendRecorder, Host, drain


# ---- binary messages -------------------------------------------------------------------------------------
def test_message_data_is_the_head_then_the_bytes_as_they_are():
    assert wire.message_data(7, 1_700_000_000_123_456_789, [b"\x01\x02\x03", b""]) == [
        struct.pack("<BIQ", 1, 7, 1_700_000_000_123_456_789) + b"\x01\x02\x03",
        struct.pack("<BIQ", 1, 7, 1_700_000_000_123_456_789),
    ]


def test_a_big_message_is_not_copied_into_its_frame():
    data = bytes(1 << 20)
    small, frame = wire.message_data(1, 0, [b"x", data])
    assert isinstance(frame, SplicedFrame) and frame.parts[1] is data and len(frame) == 13 + len(data)
    assert small == struct.pack("<BIQ", 1, 1, 0) + b"x"


def test_client_binary_messages_parse_and_bad_ones_are_named():
    assert wire.client_message(b"\x01" + struct.pack("<I", 5) + b"abc")[:2] == ("publish", 5)
    call = wire.client_message(b"\x02" + struct.pack("<III", 3, 9, 4) + b"ros1" + b"\x00\x01")
    assert call[:4] == ("call", 3, 9, "ros1") and bytes(call[4]) == b"\x00\x01"
    for data, words in [
        (b"", "empty"),
        (b"\x01\x00", "shorter than its 5-byte head"),
        (b"\x02" + struct.pack("<III", 3, 9, 400) + b"ros1", "runs past"),
        (b"\x02" + struct.pack("<III", 3, 9, 2) + b"\xff\xfe", "not UTF-8"),
        (b"\x09abc", "unknown binary opcode 9"),
    ]:
        with pytest.raises(RequestError, match=words):
            wire.client_message(data)


def test_responses_carry_their_ids_and_encoding():
    assert wire.service_call_response(2, 3, "ros1", b"xy") == struct.pack("<BIII", 3, 2, 3, 4) + b"ros1xy"
    assert wire.fetch_asset_response(5, b"mesh") == struct.pack("<BIBI", 4, 5, 0, 0) + b"mesh"
    assert wire.fetch_asset_response(5, error="no") == struct.pack("<BIBI", 4, 5, 1, 2) + b"no"


# ---- parameters --------------------------------------------------------------------------------------
def test_parameter_values_keep_their_types_both_ways():
    assert params.to_client("/a", 1.0) == {"name": "/a", "value": 1.0, "type": "float64"}
    assert params.to_client("/b", [1, 2.5]) == {"name": "/b", "value": [1, 2.5], "type": "float64_array"}
    assert params.to_client("/c", [1, 2]) == {"name": "/c", "value": [1, 2]}
    assert params.to_client("/d", xmlrpc.client.Binary(b"AB")) == {"name": "/d", "value": "QUI=", "type": "byte_array"}
    assert params.to_client("/e", {"x": {"y": True}}) == {"name": "/e", "value": {"x": {"y": True}}}
    assert params.to_client("/f", float("nan"))["value"] is None
    assert params.from_client({"name": "/a", "value": 3, "type": "float64"}) == ("/a", 3.0)
    assert params.from_client({"name": "/b", "value": [1, 2], "type": "float64_array"}) == ("/b", [1.0, 2.0])
    assert params.from_client({"name": "/d", "value": "QUI=", "type": "byte_array"})[1].data == b"AB"
    assert params.from_client({"name": "/n", "value": {"k": [1, "s"]}}) == ("/n", {"k": [1, "s"]})
    assert params.from_client({"name": "/gone"}) == ("/gone", DELETE)


@pytest.mark.parametrize(
    "entry, words",
    [
        ({"value": 1}, "'name'"),
        ({"name": "/a", "value": "x", "type": "float64"}, "must be a number"),
        ({"name": "/a", "value": "!!", "type": "byte_array"}, "base64"),
        ({"name": "/a", "value": 1, "type": "int"}, "'type'"),
        ({"name": "/a", "value": 2**40}, "32 bits"),
        ({"name": "/a", "value": json.loads("[" * 40 + "]" * 40)}, "deeper"),
    ],
)
def test_bad_parameter_values_are_refused_naming_the_field(entry, words):
    with pytest.raises(RequestError, match=words):
        params.from_client(entry)


# ---- a session over a recording backend ------------------------------------------------------------------
TWIST_DEF = "geometry_msgs/Vector3 linear\n..."
GRAPH = GraphState(
    topics={"/turtle1/cmd_vel": ("geometry_msgs/Twist", TWIST_DEF), "/odd": ("x/Unknown", None)},
    publishers={},
    subscribers={"/turtle1/cmd_vel": frozenset({"/turtlesim"})},
    services={"/clear": ("std_srvs/Empty", "", ""), "/dead": ("", None, None), "/odd": ("x/Unknown", None, None)},
    providers={"/clear": frozenset({"/turtlesim"}), "/dead": frozenset({"/gone"}), "/odd": frozenset({"/x"})},
)


class Client:
    def __init__(self, catalog=None, backend=None, **config):
        self.host, self.backend = Host(), backend or BackendRecorder()
        self.catalog = catalog or Catalog(self.backend, Globs(), self.host.call_later, self.host.cancel_later)
        self.session = FoxgloveSession(self.backend, Config(**config), self.host, self.catalog, session_id="s1")

    def send(self, obj):
        self.session.handle_text(json.dumps(obj))

    def frames(self):
        return [json.loads(frame) if isinstance(frame, str) else bytes(frame) for frame in drain(self.session)]


def test_a_client_gets_server_info_then_a_channel_for_every_topic_it_may_use():
    client = Client()
    info = client.frames()[0]
    assert info["op"] == "serverInfo" and info["sessionId"] == "s1"
    assert {"clientPublish", "parameters", "parametersSubscribe", "services", "connectionGraph", "assets"} <= set(
        info["capabilities"]
    )
    client.backend.watchers[0](GRAPH)
    advertise, services = client.frames()
    assert advertise["op"] == "advertise"
    (channel,) = advertise["channels"]  # (a type not installed here gets no channel)
    assert channel["topic"] == "/turtle1/cmd_vel" and channel["encoding"] == "ros1"
    assert (channel["schemaName"], channel["schema"], channel["schemaEncoding"]) == (
        "geometry_msgs/Twist",
        TWIST_DEF,
        "ros1msg",
    )
    (service,) = services["services"]  # (a service whose type is unknown, or not installed here, is not advertised)
    assert service["name"] == "/clear" and service["request"]["schemaName"] == "std_srvs/Empty_Request"


def test_channels_keep_their_ids_and_go_when_their_topic_goes():
    client = Client()
    client.backend.watchers[0](GRAPH)
    client.frames()
    channel_id = client.catalog.channels and next(iter(client.catalog.channels))
    client.send({"op": "subscribe", "subscriptions": [{"id": 4, "channelId": channel_id}]})
    assert ("subscribe", "/turtle1/cmd_vel", "geometry_msgs/Twist") in client.backend.calls
    client.backend.watchers[0](GraphState({}, {}, {}, GRAPH.services, GRAPH.providers))
    assert {"op": "unadvertise", "channelIds": [channel_id]} in client.frames()
    assert ("unsubscribe", "/turtle1/cmd_vel") in client.backend.calls


def test_a_second_client_gets_the_channels_already_known():
    first = Client()
    first.backend.watchers[0](GRAPH)
    second = Client(catalog=first.catalog, backend=first.backend)
    ops = [f["op"] for f in second.frames()]
    assert ops == ["serverInfo", "advertise", "advertiseServices"]


def test_bad_requests_get_a_status_error_and_the_session_goes_on():
    client = Client()
    client.backend.watchers[0](GRAPH)
    client.frames()
    for request, words in [
        ("not json", "not valid JSON"),
        ({"op": "nope"}, "unknown op"),
        ({"op": "subscribe", "subscriptions": "x"}, "'subscriptions' must be a list"),
        ({"op": "subscribe", "subscriptions": [{"id": -1, "channelId": 1}]}, "'id' must be an integer"),
        ({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 999}]}, "no channel 999"),
        (
            {"op": "advertise", "channels": [{"id": 1, "topic": "/x", "encoding": "cdr", "schemaName": "a/B"}]},
            "encoding",
        ),
        ({"op": "setParameters", "parameters": [{"name": "/p", "value": 1, "type": "float"}]}, "'type'"),
    ]:
        client.session.handle_text(request if isinstance(request, str) else json.dumps(request))
        (status,) = client.frames()
        assert status["op"] == "status" and status["level"] == 2 and words in status["message"], request
    for data, words in [(b"\x01" + struct.pack("<I", 77) + b"x", "not advertised"), (b"\x07", "opcode")]:
        client.session.handle_binary(data)
        (status,) = client.frames()
        assert words in status["message"]


def test_subscriptions_are_bounded_per_client():
    many = {f"/t{i}": ("std_msgs/Empty", "") for i in range(10)}
    client = Client(max_topics_per_client=3)
    client.backend.watchers[0](GraphState(many, {}, {}, {}, {}))
    client.frames()
    client.send(
        {"op": "subscribe", "subscriptions": [{"id": i, "channelId": c} for i, c in enumerate(client.catalog.channels)]}
    )
    assert sum(call[0] == "subscribe" for call in client.backend.calls) == 3
    assert all("max_topics_per_client" in f["message"] for f in client.frames())


def test_a_service_call_answers_with_the_response_bytes_or_a_failure():
    client = Client()
    client.backend.watchers[0](GRAPH)
    client.frames()
    service_id = next(iter(client.catalog.services))
    client.session.handle_binary(b"\x02" + struct.pack("<III", service_id, 8, 4) + b"ros1" + b"req")
    assert client.backend.calls[-1][:5] == ("call_service_bytes", "/clear", "std_srvs/Empty", b"req", 60.0)
    client.backend.replies.pop()(True, b"resp")
    assert client.frames() == [struct.pack("<BIII", 3, service_id, 8, 4) + b"ros1resp"]
    client.session.handle_binary(b"\x02" + struct.pack("<III", service_id, 9, 4) + b"ros1")
    client.backend.replies.pop()(False, "Service /clear failed: boom")
    assert client.frames() == [
        {"op": "serviceCallFailure", "serviceId": service_id, "callId": 9, "message": "Service /clear failed: boom"}
    ]


def test_parameter_updates_reach_the_clients_that_subscribe_to_them():
    client = Client()
    client.frames()
    client.send({"op": "subscribeParameterUpdates", "parameterNames": ["/speed"]})
    client.host.run_next()
    client.backend.replies.pop()(True, {"/speed": 1.0, "/other": 1})  # (the first poll: what later ones compare to)
    client.host.run_next()
    client.backend.replies.pop()(True, {"/speed": 2.5, "/other": 2})
    assert client.frames() == [
        {"op": "parameterValues", "parameters": [{"name": "/speed", "value": 2.5, "type": "float64"}]}
    ]
    client.send({"op": "unsubscribeParameterUpdates", "parameterNames": []})
    assert client.host.timers == []  # (nobody subscribes: the poll stops)


def test_params_glob_hides_parameters():
    host, backend = Host(), BackendRecorder()
    catalog = Catalog(backend, Globs.parse(params_glob="[/public/*]"), host.call_later, host.cancel_later)
    client = Client(catalog=catalog, backend=backend)
    client.frames()
    client.send({"op": "getParameters", "parameterNames": ["/secret"]})
    assert "params_glob" in client.frames()[0]["message"]
    client.send({"op": "getParameters", "parameterNames": [], "id": "r1"})
    backend.replies.pop()(True, {"/public/a": 1, "/secret": 2})
    assert client.frames() == [{"op": "parameterValues", "parameters": [{"name": "/public/a", "value": 1}], "id": "r1"}]


def test_too_many_asset_fetches_at_once_are_refused():
    client = Client()
    client.frames()
    for request_id in range(6):
        client.send({"op": "fetchAsset", "uri": "package://turtlesim/meshes/turtle.stl", "requestId": request_id})
    refused = client.frames()
    assert len(refused) == 2 and all(frame[:1] == b"\x04" and frame[5] == 1 for frame in refused)


def test_with_sim_time_the_clock_is_sent_and_stamps_the_messages():
    host, backend, ros_now = Host(), BackendRecorder(), [0]
    catalog = Catalog(backend, Globs(), host.call_later, host.cancel_later, sim_now_ns=lambda: ros_now[0])
    client = Client(catalog=catalog, backend=backend)
    assert "time" in client.frames()[0]["capabilities"]
    client.backend.watchers[0](GraphState({"/a": ("std_msgs/Empty", "")}, {}, {}, {}, {}))
    client.frames()
    client.send({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": next(iter(catalog.channels))}]})
    ros_now[0] = 12_000_000_500
    host.run_next()  # (the clock's tick)
    client.session.deliver(TopicRead("/a", None, [b""], 1_700_000_000.0))
    assert client.frames() == [
        struct.pack("<BQ", 2, 12_000_000_500),
        struct.pack("<BIQ", 1, 1, 12_000_000_500),  # (stamped by the simulated clock, not the wall's)
    ]
    host.run_next()  # (the time did not move: nothing sent)
    assert client.frames() == []
    client.session.closed()
    assert host.timers == []  # (the last client left: the tick stops)


def test_a_binary_message_over_max_message_size_is_refused():
    client = Client(max_message_size=150)
    client.frames()
    client.send(
        {"op": "advertise", "channels": [{"id": 1, "topic": "/s", "encoding": "ros1", "schemaName": "std_msgs/String"}]}
    )
    client.session.handle_binary(b"\x01" + struct.pack("<I", 1) + bytes(200))
    (status,) = client.frames()
    assert "binary message of 205 bytes refused: over max_message_size (150 bytes)" == status["message"]
    assert not any(call[0] == "publish_bytes" for call in client.backend.calls)


def test_after_a_subscribe_or_an_advertise_the_client_waits_for_its_ros_side():
    """Its next messages wait in its socket (holding) until the ROS worker, which every client shares, has made
    the publishers and subscribers asked. Before, a client that advertised and unadvertised 200 topics in a loop
    queued 180,000 of them there in 5 s, and another client's subscription waited behind them (no message in
    60 s)."""
    client = Client()
    client.frames()
    pending = []
    client.backend.after_pending = lambda session, then: pending.append(then) or True
    channel = {"id": 1, "topic": "/s", "encoding": "ros1", "schemaName": "std_msgs/String"}
    for request in (
        {"op": "advertise", "channels": [channel]},
        {"op": "unadvertise", "channelIds": [1]},
        {"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 99}]},  # (even one refused in part)
        {"op": "unsubscribe", "subscriptionIds": [1]},
    ):
        client.send(request)
        assert client.session.holding, request
        pending.pop()()
        assert not client.session.holding
    assert client.host.resumes == 4
    client.send({"op": "getParameters", "parameterNames": ["/a"], "id": "x"})
    assert not client.session.holding and not pending


def test_the_parameter_poll_reads_only_what_clients_subscribe_to_and_spaces_itself_by_its_cost(monkeypatch):
    """Before, one client watching one parameter made the bridge read the whole tree every second: with 28 MB of
    parameters on the master, 8% of a core and +152 MB at the peak."""
    now = [0.0]
    monkeypatch.setattr(catalog_module, "time", types.SimpleNamespace(monotonic=lambda: now[0]))
    first = Client()
    first.send({"op": "subscribeParameterUpdates", "parameterNames": ["/b", "/a"]})
    first.host.run_next()
    assert first.backend.calls[-1][:2] == ("get_parameters", ["/a", "/b"])
    now[0] += 0.5  # (the poll took 0.5 s: the next one waits 5 s)
    first.backend.replies.pop()(True, {"/a": 1})
    assert first.host.timers[-1][1] == 0.5 * catalog_module.POLL_SPACING
    second = Client(catalog=first.catalog, backend=first.backend)
    second.send({"op": "subscribeParameterUpdates", "parameterNames": []})  # (every parameter)
    first.host.run_next()
    assert first.backend.calls[-1][:2] == ("get_parameters", None)


def test_parameter_subscriptions_and_requests_are_bounded_per_client():
    """Before, each subscribeParameterUpdates added its names for good: 100 of 10,000 names took +168 MB."""
    client = Client()
    client.frames()
    client.send({"op": "subscribeParameterUpdates", "parameterNames": [f"/p{i}" for i in range(MAX_PARAMETER_NAMES)]})
    client.send({"op": "subscribeParameterUpdates", "parameterNames": ["/one/more"]})
    (status,) = client.frames()
    assert f"at most {MAX_PARAMETER_NAMES} names subscribed" in status["message"]
    assert len(client.session.parameter_subscriptions) == MAX_PARAMETER_NAMES
    for i in range(MAX_PARAMETER_REQUESTS + 1):
        client.send({"op": "getParameters", "parameterNames": [], "id": str(i)})
    (status,) = client.frames()
    assert f"{MAX_PARAMETER_REQUESTS} parameter requests of this client under way" in status["message"]
    client.backend.replies.pop(0)(True, {"/a": 1})  # (one answered: another may go)
    client.send({"op": "setParameters", "parameters": [{"name": "/a", "value": 2}]})
    assert not [frame for frame in client.frames() if frame["op"] == "status"]


def test_a_request_s_refused_entries_are_told_in_one_status():
    """Before, a subscribe of 10,000 channels that do not exist made 10,000 statuses (0.1 s of the loop; the
    client's bound kept 1,000 of them and dropped its other answers with the rest)."""
    client = Client()
    client.frames()
    client.send({"op": "subscribe", "subscriptions": [{"id": i, "channelId": 100_000 + i} for i in range(10_000)]})
    (status,) = client.frames()
    assert status["message"] == (
        "subscribe: no channel 100000; subscribe: no channel 100001; subscribe: no channel 100002; and 9997 more"
    )
    client.send({"op": "unsubscribe", "subscriptionIds": [1, "x", None]})
    (status,) = client.frames()
    assert status["level"] == 1 and "no subscription 1;" in status["message"]
    channels = [{"id": i, "topic": f"/t{i}", "encoding": "ros1", "schemaName": "std_msgs/Empty"} for i in range(3)]
    client.send({"op": "advertise", "channels": [channels[0], {"id": "bad"}, channels[1], channels[0]]})
    (status,) = client.frames()  # (the good ones advertised, each bad one named)
    assert "field 'id' must be an integer" in status["message"] and "1 is already advertised" not in status["message"]
    assert "client channel 0 is already advertised" in status["message"]
    assert [call[1] for call in client.backend.calls if call[0] == "advertise"] == ["/t0", "/t1"]


def test_what_every_client_is_told_is_encoded_once():
    """The channels and services a client is told when it comes, and the graph when it subscribes to it, are the
    same frames for every client until the graph changes. Before, each was encoded for each client: with 308
    channels, a Foxglove connection took 1.5 ms of the loop (a rosbridge one 0.26 ms)."""
    first = Client()
    first.backend.watchers[0](GRAPH)
    later = [Client(catalog=first.catalog, backend=first.backend) for _ in range(2)]
    told = []
    for client in later:
        client.session.take_frames(0)  # (its serverInfo)
        client.send({"op": "subscribeConnectionGraph"})
        told.append([client.session.take_frames(0)[0] for _ in range(3)])
    assert [json.loads(frame)["op"] for frame in told[0]] == ["advertise", "advertiseServices", "connectionGraphUpdate"]
    assert all(a is b for a, b in zip(*told))


@pytest.mark.parametrize("writes_now", [False, True])  # (queued, or written at once to a client that keeps up)
def test_a_reads_messages_share_one_head_and_latched_ones_keep_their_own_receive_times(writes_now):
    client = Client()
    client.backend.watchers[0](GraphState({"/a": ("std_msgs/Empty", "")}, {}, {}, {}, {}))
    client.frames()
    client.send({"op": "subscribe", "subscriptions": [{"id": 3, "channelId": next(iter(client.catalog.channels))}]})
    client.host.writes_now = writes_now
    read = TopicRead("/a", None, [bytes([n]) for n in range(3)], 1_700_000_000.5)
    client.session.deliver(read)
    assert read._messages is None  # (the bytes go as they came: no TopicMessage is made for them)
    for data, stamp in ((b"x", 1_700_000_001.0), (b"y", 1_700_000_002.0)):  # (two publishers' latched ones)
        client.session.deliver(TopicRead("/a", None, [data], stamp))
    head = struct.Struct("<BIQ")
    if writes_now:  # (the first read in one write; each latched one in its own)
        assert [len(frames) for frames in client.host.written] == [3, 1, 1] and client.frames() == []
    assert [frame for frames in client.host.written for frame in frames] + client.frames() == [
        *(head.pack(1, 3, 1_700_000_000_500_000_000) + bytes([n]) for n in range(3)),
        head.pack(1, 3, 1_700_000_001_000_000_000) + b"x",
        head.pack(1, 3, 1_700_000_002_000_000_000) + b"y",
    ]


def test_a_read_is_written_at_once_only_while_nothing_of_the_clients_waits_and_what_waits_keeps_its_order():
    client = Client()
    client.backend.watchers[0](GraphState({"/a": ("std_msgs/Empty", ""), "/b": ("std_msgs/Empty", "")}, {}, {}, {}, {}))
    client.frames()
    channels = iter(client.catalog.channels)
    client.send({"op": "subscribe", "subscriptions": [{"id": n, "channelId": next(channels)} for n in (1, 2)]})
    client.host.writes_now = True

    def deliver(data, topic="/a"):
        client.session.deliver(TopicRead(topic, None, [data], 1_700_000_000.0))

    def data(frames):
        return [frame[13:] for frame in frames]

    deliver(b"0")
    assert data(client.host.written.pop()) == [b"0"] and client.frames() == []
    client.host.writes_now = False  # (its socket is busy)
    deliver(b"1")
    client.host.writes_now = True
    deliver(b"2")  # (behind 1, though the host could write it)
    assert client.host.written == [] and data(client.frames()) == [b"1", b"2"]
    deliver(b"3")  # (all taken: at once again)
    assert data(client.host.written.pop()) == [b"3"]
    picture = b"x" * (1 << 16)
    deliver(picture, topic="/b")  # (big: at once too, its bytes held in the pool until they have left)
    [[frame]] = client.host.written
    assert frame.parts[1] is picture and client.session.config.queue_pool.shared == len(picture)
    client.host.written.clear()
    client.session.backed_up(False)
    assert client.session.config.queue_pool.shared == 0
    client.session.backed_up(True)
    deliver(b"4")  # (backed up: queued, kept fresh)
    assert client.host.written == [] and data(client.frames()) == [b"4"]


def test_a_slow_link_is_told_what_it_skipped_first_as_a_status_a_newer_one_replaces():
    client = Client()
    client.backend.watchers[0](GraphState({"/a": ("std_msgs/Empty", "")}, {}, {}, {}, {}))
    client.frames()
    client.send({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": next(iter(client.catalog.channels))}]})
    client.session.backed_up(True)
    client.session.deliver(TopicRead("/a", None, [b""], 1_700_000_000.0))
    client.host.now += 1.0  # (past the freshness horizon: the older one is skipped)
    client.session.deliver(TopicRead("/a", None, [b""], 1_700_000_001.0))
    client.session.backed_up(False)
    status, data = client.frames()
    assert (status["op"], status["level"], status["id"]) == ("status", 1, "warning")
    assert status["message"].startswith("skipped 1 older message(s)") and "/a 1" in status["message"]
    assert data == struct.pack("<BIQ", 1, 1, 1_700_000_001_000_000_000)
