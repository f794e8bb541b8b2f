"""rosbridge.protocol.session without ROS or sockets: a Session fed frames, with a backend that records what the
protocol asks of the ROS side, and a clock and timers the test moves by hand."""

import hashlib
import inspect
import io
import json
import tracemalloc

import pytest
from std_msgs.msg import Int32, String

from rosbridge.contract import Backend
from rosbridge.globs import Globs
from rosbridge.protocol import session as protocol
from rosbridge.protocol.encoded import SplicedFrame, TopicRead, Utf8Text
from rosbridge.settings import Settings

from fakes import Host, OffLoop, drain


class RecordingBackend(Backend):
    """Records every call; `refuse` makes the named method raise like the ROS side does. Its methods are made
    from the Backend contract, so a protocol call outside the contract fails here."""

    def __init__(self):
        self.calls = []
        self.refuse = {}
        self.busy = False  # whether ROS work is under way (after_pending then waits)
        self.waiting = []

    def after_pending(self, session, then):
        if self.busy:
            self.waiting.append(then)
        return self.busy

    def finish_pending(self, busy_again=False):
        """The ROS work is done; busy_again: the requests handled now start more."""
        waiting, self.waiting, self.busy = self.waiting, [], busy_again
        for then in waiting:
            then()

    @staticmethod
    def resolve_name(name):
        return name if name.startswith("/") else "/" + name  # (the bridge's namespace is "/")


def _recorder(name):
    def record(self, session, *args):
        if name in self.refuse:
            raise protocol.RequestError(self.refuse[name])
        self.calls.append((name, *args))

    return record


for _name in Backend.__abstractmethods__ - set(vars(RecordingBackend)):
    setattr(RecordingBackend, _name, _recorder(_name))
RecordingBackend.__abstractmethods__ = frozenset()


def test_the_ros_backend_implements_the_contract_with_its_signatures():
    from rosbridge.ros_side import RosBackend

    for name in Backend.__abstractmethods__:
        contract = inspect.signature(getattr(Backend, name)).parameters
        assert list(inspect.signature(getattr(RosBackend, name)).parameters) == list(contract), name


class Harness:
    def __init__(self, off_loop=None, unfinished=None, writes_now=False, **config):
        self.host = Host(off_loop=off_loop, unfinished=unfinished, writes_now=writes_now)
        self.backend = RecordingBackend()
        self.session = protocol.Session(self.backend, protocol.Config(**config), self.host)

    def send(self, frame):
        self.session.handle_text(frame if isinstance(frame, str) else json.dumps(frame))

    def frames(self):
        return drain(self.session)

    def replies(self):
        return [json.loads(frame) for frame in self.frames()]

    def advance(self, seconds):
        self.host.advance(seconds)


def received(topic, msg, stamp):
    """A read of one message as the bridge makes it from what TCPROS carried: the message's serialized bytes."""
    buffer = io.BytesIO()
    msg.serialize(buffer)
    return TopicRead(topic, type(msg), [buffer.getvalue()], stamp)


def message(topic="/t", data=1, stamp=1.5):
    return received(topic, Int32(data), stamp)


@pytest.fixture
def h():
    return Harness()


def test_the_config_reads_the_one_settings_object_through():
    current = Settings()
    config = protocol.Config(current)
    assert config.settings is current and config.max_queue == current.max_queue == 1000
    current.max_queue = 7
    assert config.max_queue == 7  # (not a copy)
    assert protocol.Config(max_queue=3, authenticate=True).settings.max_queue == 3
    with pytest.raises(TypeError, match="max_queu"):
        protocol.Config(max_queu=3)
    with pytest.raises(AttributeError, match="max_queu"):
        config.max_queu


def test_check_fields_names_the_problem():
    protocol.check_fields("advertise", {"op": "advertise", "topic": "/a", "type": "std_msgs/String"})
    with pytest.raises(protocol.RequestError, match="missing required field 'type'"):
        protocol.check_fields("advertise", {"op": "advertise", "topic": "/a"})
    with pytest.raises(protocol.RequestError, match="'latch' must be a boolean"):
        protocol.check_fields("advertise", {"op": "advertise", "topic": "/a", "type": "x/Y", "latch": 1})
    with pytest.raises(protocol.RequestError, match="'queue_size' must be an integer"):
        protocol.check_fields("advertise", {"op": "advertise", "topic": "/a", "type": "x/Y", "queue_size": True})
    with pytest.raises(protocol.RequestError, match="unknown field 'bogus'"):
        protocol.check_fields("unadvertise", {"op": "unadvertise", "topic": "/a", "bogus": 1})
    # null stands for an absent optional field (roslibpy sends "id": null)
    protocol.check_fields("set_level", {"op": "set_level", "level": "info", "id": None})


def test_ops_reach_the_backend_with_defaults(h):
    h.send({"op": "advertise", "topic": "/a", "type": "std_msgs/String"})
    h.send({"op": "publish", "topic": "/a", "msg": {"data": "x"}, "latch": True})
    h.send({"op": "call_service", "service": "/s", "args": [1, 2], "id": "c"})
    h.send({"op": "advertise_service", "service": "/p", "type": "std_srvs/Empty"})
    h.send({"op": "service_response", "service": "/p", "id": "r", "result": True, "values": {}})
    h.send({"op": "unadvertise", "topic": "/a"})
    names = [call[0] for call in h.backend.calls]
    assert names == ["advertise", "publish", "call_service", "advertise_service", "service_response", "unadvertise"]
    assert h.backend.calls[0] == ("advertise", "/a", "std_msgs/String", False, 100)
    assert h.backend.calls[1] == ("publish", "/a", {"data": "x"}, True, 100)
    assert h.backend.calls[2][1:5] == ("/s", [1, 2], None, None)
    assert h.frames() == []  # success is silent


def test_call_service_reply_is_routed_by_id(h):
    h.send({"op": "call_service", "service": "/s", "id": "call-7"})
    reply = h.backend.calls[0][-1]
    reply(False, "Service /s does not exist")
    assert h.replies() == [
        {
            "op": "service_response",
            "service": "/s",
            "values": "Service /s does not exist",
            "result": False,
            "id": "call-7",
        }
    ]


def test_an_id_that_json_cannot_write_is_left_out_of_every_answer(h):
    # (Python's json reads NaN and Infinity; no JSON writer may send them back: the answer would fail)
    h.session.handle_text('{"op": "call_service", "service": "/s", "id": NaN}')
    reply = h.backend.calls[0][-1]
    reply(True, {})
    h.session.handle_text('{"op": "subscribe", "topic": "/a", "type": "std_msgs/String", "id": Infinity}')
    h.session.handle_text('{"op": "unadvertise", "topic": 5, "id": -Infinity}')
    assert h.replies() == [
        {"op": "service_response", "service": "/s", "values": {}, "result": True},
        {"op": "status", "level": "error", "msg": "unadvertise: field 'topic' must be a string, got 5"},
    ]


def test_backend_refusal_becomes_a_status_error_with_the_id(h):
    h.backend.refuse["advertise"] = "advertise /a: the topic already has type x/Y"
    h.send({"op": "advertise", "topic": "/a", "type": "std_msgs/String", "id": "adv-1"})
    assert h.replies() == [
        {"op": "status", "level": "error", "id": "adv-1", "msg": "advertise /a: the topic already has type x/Y"}
    ]


def test_globs_refuse_names_outside_them():
    h = Harness(globs=Globs.parse(topics_glob="[/turtle1/*]", services_glob="[/spawn]"))
    h.send({"op": "subscribe", "topic": "/secret", "type": "std_msgs/String", "id": "s"})
    h.send({"op": "call_service", "service": "/kill", "id": "k"})
    h.send({"op": "call_service", "service": "/rosapi/topics", "id": "r"})  # always callable
    h.send({"op": "subscribe", "topic": "/turtle1/pose", "type": "turtlesim/Pose"})
    errors = h.replies()
    assert [(e["op"], e["id"]) for e in errors] == [("status", "s"), ("status", "k"), ("service_response", "k")]
    assert "topics_glob" in errors[0]["msg"] and "services_glob" in errors[1]["msg"] == errors[2]["values"]
    assert [c[0] for c in h.backend.calls] == ["call_service", "subscribe"]


def test_subscriptions_merge_and_unsubscribe(h):
    h.send({"op": "subscribe", "topic": "/t", "id": "a", "throttle_rate": 500, "fragment_size": 100})
    h.send({"op": "subscribe", "topic": "/t", "id": "b", "throttle_rate": 100, "queue_length": 5})
    sub = h.session.subscriptions["/t"]
    assert (sub.throttle_rate, sub.fragment_size, sub.queue_length) == (0.1, 100, 5)
    h.send({"op": "unsubscribe", "topic": "/t", "id": "b"})
    assert (sub.throttle_rate, sub.queue_length) == (0.5, 0)
    assert ("unsubscribe", "/t") not in h.backend.calls
    h.send({"op": "subscribe", "topic": "/t", "id": "c"})
    h.send({"op": "unsubscribe", "topic": "/t"})  # no id: all of them
    assert "/t" not in h.session.subscriptions and ("unsubscribe", "/t") in h.backend.calls


def test_one_encoding_for_every_client():
    sessions = [Harness() for _ in range(3)]
    for s in sessions:
        s.send({"op": "subscribe", "topic": "/t"})
    msg = message(data=42)
    for s in sessions:
        s.session.deliver(msg)
    frames = [s.frames() for s in sessions]
    assert frames[0][0] is frames[1][0] is frames[2][0]  # the same bytes object
    assert isinstance(frames[0][0], Utf8Text)
    assert json.loads(frames[0][0]) == {"op": "publish", "topic": "/t", "msg": {"data": 42}}


def test_fragment_size_and_compressions(h):
    h.send({"op": "subscribe", "topic": "/t", "fragment_size": 10})
    h.session.deliver(message(data=123456))
    parts = h.replies()
    assert {p["op"] for p in parts} == {"fragment"} and len(parts) == parts[0]["total"] > 1
    assert json.loads("".join(p["data"] for p in parts))["msg"] == {"data": 123456}
    h.send({"op": "subscribe", "topic": "/t", "compression": "cbor-raw"})
    h.session.deliver(message(data=1, stamp=12.25))
    import cbor2

    frame = h.frames()
    assert len(frame) == 1 and not isinstance(frame[0], Utf8Text)
    assert cbor2.loads(frame[0])["msg"] == {"bytes": b"\x01\x00\x00\x00", "secs": 12, "nsecs": 250000000}


def test_throttle_keeps_the_latest_and_queue_length_keeps_more(h):
    h.send({"op": "subscribe", "topic": "/t", "throttle_rate": 1000})
    for n in range(5):
        h.session.deliver(message(data=n))
    assert [r["msg"]["data"] for r in h.replies()] == [0]
    h.advance(1.0)
    assert [r["msg"]["data"] for r in h.replies()] == [4]  # the latest, not lost
    h.advance(5.0)
    assert h.replies() == []

    q = Harness()
    q.send({"op": "subscribe", "topic": "/t", "throttle_rate": 1000, "queue_length": 2})
    for n in range(5):
        q.session.deliver(message(data=n))
    received = [r["msg"]["data"] for r in q.replies()]
    for _ in range(2):  # a client that reads what it is sent
        q.advance(1.0)
        received += [r["msg"]["data"] for r in q.replies()]
    assert received == [0, 3, 4]


def test_a_throttled_subscription_waits_for_a_slow_client_and_sends_the_newest():
    """A camera to a client that reads slowly: nothing piles up for it, and when it has read, it gets the newest
    picture, not the ones it missed."""
    h = Harness()
    h.send({"op": "subscribe", "topic": "/camera", "throttle_rate": 10, "queue_length": 1})
    h.session.deliver(message("/camera", data=0))
    for n in range(1, 100):  # the client reads nothing meanwhile
        h.session.deliver(message("/camera", data=n))
        h.advance(0.05)
    assert [r["msg"]["data"] for r in h.replies()] == [0]  # what was queued before it fell behind
    h.advance(0.05)
    assert [r["msg"]["data"] for r in h.replies()] == [99]


def test_slow_client_drops_oldest_whole_messages_and_is_told_at_the_default_level():
    h = Harness(max_queue=3)
    h.send({"op": "subscribe", "topic": "/t"})
    for n in range(10):
        h.session.deliver(message(data=n))
    replies = h.replies()
    assert replies[0]["op"] == "status" and replies[0]["level"] == "error"
    assert "dropped 7 whole message(s)" in replies[0]["msg"] and "/t 7" in replies[0]["msg"]
    assert [r["msg"]["data"] for r in replies[1:]] == [7, 8, 9]


def test_a_big_message_is_encoded_off_the_loop_once_and_the_topic_keeps_its_order():
    off_loop = OffLoop()
    first, second = Harness(off_loop=off_loop), Harness(off_loop=off_loop)
    for h in (first, second):
        h.send({"op": "subscribe", "topic": "/map"})
        h.send({"op": "subscribe", "topic": "/other"})
    big = received("/map", String("m" * (1 << 20)), 0.0)
    for h in (first, second):
        h.session.deliver(big)
        h.session.deliver(received("/map", String("after"), 0.0))
        h.session.deliver(received("/other", String("other"), 0.0))
    for h in (first, second):  # the other topic goes on; the map's next waits behind it
        assert [(r["topic"], r["msg"]["data"]) for r in h.replies()] == [("/other", "other")]
    assert off_loop.count == 1  # one encoding for both clients
    off_loop.run_all()
    for h in (first, second):
        assert [r["msg"]["data"][:5] for r in h.replies()] == ["mmmmm", "after"]


def test_a_failed_encoding_off_the_loop_skips_that_message_only():
    h = Harness(off_loop=lambda fn, then: then(None))
    h.send({"op": "subscribe", "topic": "/map"})
    h.session.deliver(received("/map", String("m" * (1 << 20)), 0.0))
    h.session.deliver(received("/map", String("after"), 0.0))
    assert [r["msg"]["data"] for r in h.replies()] == ["after"]


def test_backed_up_client_gets_the_newest_of_each_topic_and_is_told_once_a_second():
    h = Harness()
    h.send({"op": "set_level", "level": "warning"})
    h.send({"op": "subscribe", "topic": "/t"})
    h.session.backed_up(True)
    for n in range(2000):  # more than a topic's backlog bound: the older are skipped
        h.session.deliver(message(data=n))
    replies = h.replies()
    assert replies[0]["level"] == "warning" and replies[0]["msg"].startswith("skipped ")
    data = [r["msg"]["data"] for r in replies[1:]]
    assert data == list(range(2000 - len(data), 2000)) and len(data) < 2000
    h.session.deliver(message(data=2000))
    h.session.deliver(message(data=2001))
    assert [r["op"] for r in h.replies()] == ["publish", "publish"]  # (no second report within the second)


def test_a_read_of_several_messages_is_queued_to_go_in_one_write_though_the_client_keeps_up():
    """(A Foxglove client's read may go to the socket at once, in one write: test_foxglove_protocol. A rosbridge
    client's messages are queued one by one: written at once, each would be a write of its own.)"""
    h = Harness(writes_now=True)
    h.send({"op": "subscribe", "topic": "/t"})
    datas = [received("/t", Int32(n), 1.5).datas[0] for n in range(3)]
    h.session.deliver(TopicRead("/t", Int32, datas, 1.5))
    assert h.host.written == [] and [r["msg"]["data"] for r in h.replies()] == [0, 1, 2]


def test_status_level_filters(h):
    h.send({"op": "unsubscribe", "topic": "/nothing"})  # a warning: hidden at the default level (error)
    assert h.frames() == []
    h.send({"op": "set_level", "level": "warning"})
    h.send({"op": "unsubscribe", "topic": "/nothing"})
    assert h.replies()[0]["level"] == "warning"
    h.send({"op": "set_level", "level": "none"})
    h.send("garbage")
    assert h.frames() == []


def test_fragments_reassemble_in_any_order_and_expire(h):
    text = json.dumps({"op": "advertise", "topic": "/f", "type": "std_msgs/String"})
    parts = [text[i : i + 7] for i in range(0, len(text), 7)]
    for num in reversed(range(1, len(parts))):
        h.send({"op": "fragment", "id": 1, "data": parts[num], "num": num, "total": len(parts)})
    assert h.backend.calls == []
    h.send({"op": "fragment", "id": 1, "data": parts[0], "num": 0, "total": len(parts)})
    assert h.backend.calls == [("advertise", "/f", "std_msgs/String", False, 100)]

    h.send({"op": "set_level", "level": "warning"})
    h.send({"op": "fragment", "id": 2, "data": "{", "num": 0, "total": 2})
    h.advance(300)
    h.send({"op": "fragment", "id": 3, "data": "{", "num": 0, "total": 2})
    h.advance(301)  # (on a timer: the client sends nothing more)
    assert "fragment 2: dropped after fragment_timeout (600.0 s) with 1 of 2 parts" in h.replies()[0]["msg"]
    assert h.session._fragments.ids() == [3]
    h.advance(300)
    assert "fragment 3: dropped" in h.replies()[0]["msg"] and h.session._fragments.ids() == []
    assert h.host.timers == []  # (nothing left to expire: no timer)


def test_a_client_leaving_cancels_its_fragments_timer():
    h = Harness()
    h.send({"op": "fragment", "id": 1, "data": "{", "num": 0, "total": 2})
    [timer] = h.host.timers
    h.session.closed()
    assert h.host.cancelled == [timer] and h.session._fragments.bytes == 0


def test_fragments_count_with_every_clients_unfinished_messages_and_a_stalled_clients_make_way():
    """A client's parked fragments count against the bound shared by every client's unfinished messages (a
    rfc6455.SharedBound): within it they wait; beyond it the part is refused; and a client whose bytes
    came faster takes their room once they have stopped coming, the client told."""
    from rosbridge.transport.rfc6455 import RECENT, SharedBound

    now = [1000.0]
    shared = SharedBound(1_000_000, clock=lambda: now[0])
    parked, refused, sending = (Harness(unfinished=shared) for _ in range(3))
    parked.send({"op": "fragment", "id": "p", "data": "x" * 600_000, "num": 0, "total": 2})
    assert shared.held == parked.session._fragments.bytes > 600_000
    refused.send({"op": "fragment", "id": "r", "data": "x" * 600_000, "num": 0, "total": 2})
    assert "all clients are at their bound" in refused.replies()[0]["msg"]
    assert refused.session._fragments.ids() == [] and shared.held == parked.session._fragments.bytes
    now[0] += 2 * RECENT
    sending.send({"op": "fragment", "id": "s", "data": "x" * 600_000, "num": 0, "total": 2})
    assert parked.session._fragments.ids() == [] and sending.session._fragments.ids() == ["s"]
    assert "1 unfinished fragmented message(s) dropped" in parked.replies()[0]["msg"]
    sending.send({"op": "fragment", "id": "s", "data": '"}', "num": 1, "total": 2})
    assert shared.held == 0
    sending.session.closed()
    parked.session.closed()
    assert shared.held == 0


def test_fragments_cannot_exceed_max_message_size():
    h = Harness(max_message_size=300)
    h.send({"op": "fragment", "id": "big", "data": "x" * 120, "num": 0, "total": 3})
    h.send({"op": "fragment", "id": "big", "data": "x" * 120, "num": 1, "total": 3})
    assert "max_message_size" in h.replies()[0]["msg"]
    assert h.session._fragments.ids() == [] and h.session._fragments.bytes == 0


def test_empty_fragments_count_against_the_budget():
    h = Harness(max_message_size=10_000)
    for num in range(1000):
        h.send({"op": "fragment", "id": "empty", "data": "", "num": num, "total": 5000})
    assert any("max_message_size" in reply["msg"] for reply in h.replies())
    assert h.session._fragments.bytes <= 10_000


def test_what_empty_fragments_hold_in_memory_stays_within_the_budget():
    budget = 1_000_000
    h = Harness(max_message_size=budget)
    tracemalloc.start()
    try:
        for num in range(budget // 50):  # more parts than the budget can count
            h.send({"op": "fragment", "id": "empty", "data": "", "num": num, "total": budget})
        _, held = tracemalloc.get_traced_memory()  # (the peak)
    finally:
        tracemalloc.stop()
    assert held <= budget


def test_nested_fragments_are_refused(h):
    inner = json.dumps({"op": "fragment", "id": "in", "data": "{}", "num": 0, "total": 1})
    frame = {"op": "fragment", "id": "out", "data": inner, "num": 0, "total": 1}
    for _ in range(3):
        frame = {"op": "fragment", "id": "out", "data": json.dumps(frame), "num": 0, "total": 1}
    h.send(frame)
    assert "nested too deeply" in h.replies()[0]["msg"]


def test_png_op_carries_a_request(h):
    from rosbridge.codec.wrapping import png_frame

    h.send({"op": "png", "data": png_frame(json.dumps({"op": "unadvertise", "topic": "/p"}))})
    assert h.backend.calls == [("unadvertise", "/p")]


def secret_mac(fields, secret="s3cret"):
    text = "".join(
        [
            secret,
            fields["client"],
            fields["dest"],
            fields["rand"],
            str(int(fields["t"])),
            fields["level"],
            str(int(fields["end"])),
        ]
    )
    return hashlib.sha512(text.encode()).hexdigest()


def auth(now, **changes):
    fields = {"client": "c", "dest": "d", "rand": "r", "t": now, "level": "admin", "end": now + 100}
    fields["mac"] = secret_mac(fields)
    return {"op": "auth", **fields, **changes}


def test_auth_gate():
    h = Harness(authenticate=True, auth_secret="s3cret")
    h.send({"op": "advertise", "topic": "/a", "type": "std_msgs/String", "id": "early"})
    assert "not authenticated" in h.replies()[0]["msg"] and h.host.close_reasons == []
    h.send(auth(h.host.now))
    h.send({"op": "advertise", "topic": "/a", "type": "std_msgs/String"})
    assert h.backend.calls == [("advertise", "/a", "std_msgs/String", False, 100)]


@pytest.mark.parametrize(
    "changes",
    [
        {"mac": "00"},
        {"rand": "other"},
        {"t": 1000.0 - 10},
        {"end": 999.0},
        {"client": 5},
        {"mac": None},
        {"mac": "é" * 128},
        {"end": float("inf")},
        {"t": float("nan")},
    ],
)
def test_bad_auth_closes(changes):
    h = Harness(authenticate=True, auth_secret="s3cret")
    frame = auth(h.host.now)
    frame.update(changes)
    if changes.get("mac", "") is None:
        del frame["mac"]
    h.send(frame)
    assert h.replies()[0]["level"] == "error" and h.host.close_reasons == ["authentication failed"]


def test_a_client_that_does_not_authenticate_in_time_is_closed():
    idle = Harness(authenticate=True, auth_secret="s3cret")
    idle.advance(protocol.AUTH_TIMEOUT - 0.1)
    assert idle.host.close_reasons == []
    idle.advance(0.1)
    assert idle.host.close_reasons == [f"not authenticated within {protocol.AUTH_TIMEOUT:g} s"]
    prompt = Harness(authenticate=True, auth_secret="s3cret")
    [deadline] = prompt.host.timers
    prompt.send(auth(prompt.host.now))
    assert prompt.host.cancelled == [deadline] and prompt.host.timers == []
    deadline[2]()  # (had it run all the same: the client has authenticated, it stays)
    prompt.advance(protocol.AUTH_TIMEOUT)
    assert prompt.host.close_reasons == []
    assert Harness().host.timers == []  # (without authenticate: no deadline)


def test_auth_without_a_secret_refuses_everyone():
    h = Harness(authenticate=True, auth_secret=None)
    h.send(auth(h.host.now))
    assert h.host.close_reasons == ["authentication failed"]


def test_closed_session_releases_and_stops_sending(h):
    h.send({"op": "subscribe", "topic": "/t"})
    h.session.closed()
    h.session.deliver(message())
    assert h.frames() == [] and h.backend.calls[-1] == ("release",)


def test_a_reads_messages_are_made_once_when_asked_and_its_last_alone_shares_its_own():
    read = TopicRead("/t", Int32, [b"\x01\0\0\0", b"\x02\0\0\0"], 1.5)
    messages = read.messages
    assert [(m.topic, m.msg_class, m.data, m.stamp) for m in messages] == [
        ("/t", Int32, b"\x01\0\0\0", 1.5),
        ("/t", Int32, b"\x02\0\0\0", 1.5),
    ]
    assert read.messages is messages
    last = read.last()
    assert (last.topic, last.datas, last.stamp) == ("/t", [b"\x02\0\0\0"], 1.5) and last.messages == messages[1:]
    assert last.messages[0] is messages[1] and last.last() is last


def test_string_messages_keep_unicode():
    (msg,) = received("/s", String("grüß 🐢"), 0.0).messages
    assert json.loads(msg.frames("none", None)[0])["msg"]["data"] == "grüß 🐢"


def test_a_camera_image_goes_out_with_its_base64_as_a_part_of_its_own():
    from sensor_msgs.msg import Image

    from rosbridge.codec.json_values import dumps, to_json

    image = Image(height=480, width=640, encoding="rgb8", step=1920, data=bytes(range(256)) * 3600)
    (msg,) = received("/camera", image, 0.0).messages
    (frame,) = msg.frames("none", None)
    assert isinstance(frame, SplicedFrame) and frame.text
    assert bytes(frame) == dumps({"op": "publish", "topic": "/camera", "msg": to_json(image)}).encode()
    assert len(frame) == len(bytes(frame)) and max(map(len, frame.parts)) == 4 * 3600 * 256 // 3
    fragments = msg.frames("none", 500_000)  # other options: the whole text, as before
    assert len(fragments) == 3 and all(isinstance(f, Utf8Text) for f in fragments)


def test_png_bomb_is_refused_before_unpacking():
    import base64
    import io

    from PIL import Image

    h = Harness(max_message_size=1000)
    buffer = io.BytesIO()
    Image.new("RGB", (100, 100)).save(buffer, format="PNG")  # 30 kB of pixels in a tiny file
    h.send({"op": "png", "data": base64.b64encode(buffer.getvalue()).decode(), "id": "bomb"})
    reply = h.replies()[0]
    assert reply["id"] == "bomb" and "over max_message_size" in reply["msg"]


def test_refused_call_service_fails_the_call():
    """Client libraries match a call by its service_response: a refusal must be one, or they wait forever."""
    h = Harness(globs=Globs.parse(services_glob="[/open/*]"))
    h.send({"op": "call_service", "service": "/closed/reset", "id": "c1"})
    h.send({"op": "call_service", "service": "/open/x", "id": "c2", "compression": "zip"})
    replies = [r for r in h.replies() if r["op"] == "service_response"]  # each after its status error
    assert [(r["id"], r["result"]) for r in replies] == [("c1", False), ("c2", False)]
    assert "services_glob" in replies[0]["values"] and "compression" in replies[1]["values"]


def test_requests_wait_for_the_ros_side_of_an_earlier_one_and_keep_their_order():
    h = Harness()
    h.backend.busy = True  # the ROS side makes the service off the loop
    h.send({"op": "advertise_service", "service": "/adder", "type": "std_srvs/Trigger"})
    assert h.session.holding
    h.send({"op": "call_service", "service": "/adder", "id": "c1"})
    h.send({"op": "subscribe", "topic": "/a", "type": "std_msgs/String"})
    h.send({"op": "call_service", "service": "/adder", "id": "c2"})
    assert [call[0] for call in h.backend.calls] == ["advertise_service"]
    h.backend.finish_pending(busy_again=True)  # the subscribe starts ROS work too
    assert [call[0] for call in h.backend.calls] == ["advertise_service", "call_service", "subscribe"]
    assert h.session.holding and h.host.resumes == 0
    h.backend.finish_pending()
    assert [call[0] for call in h.backend.calls] == ["advertise_service", "call_service", "subscribe", "call_service"]
    assert not h.session.holding and h.host.resumes == 1


def test_a_request_refused_at_once_holds_nothing():
    h = Harness()
    h.backend.busy = True
    h.backend.refuse["advertise"] = "no"
    h.send({"op": "advertise", "topic": "/a", "type": "std_msgs/String"})
    assert not h.session.holding


def test_a_client_that_leaves_while_held_drops_what_it_sent():
    h = Harness()
    h.backend.busy = True
    h.send({"op": "subscribe", "topic": "/a", "type": "std_msgs/String"})
    h.send({"op": "call_service", "service": "/x", "id": "c1"})
    h.session.closed()
    h.backend.finish_pending()
    assert "call_service" not in [call[0] for call in h.backend.calls]
