"""Property tests of the pure protocol core (rosbridge.protocol.session.Session) fed random, malformed and hostile
frames: it never raises, answers every refused frame with exactly one `status` error that carries the
request's id, writes only strict JSON, and keeps working afterwards.

The backend is an in-memory implementation of the backend.Backend contract (no ROS
here): it accepts any topic/service whose type looks like "pkg/Name" and answers service calls at once."""

import json
import math

import cbor2
import std_msgs.msg
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_protocol import received

from rosbridge.contract import Backend
from rosbridge.globs import Globs
from rosbridge.protocol import encoded as frames
from rosbridge.protocol import session as protocol

from fakes import Host, drain

SETTINGS = settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large]
)


class MemoryBackend(Backend):
    """Records what the session asked for; refuses like the real one does (RequestError with a message)."""

    def __init__(self):
        self.calls = []

    def _record(self, name, *args):
        self.calls.append((name,) + args)

    @staticmethod
    def resolve_name(name):
        return name if name.startswith("/") else "/" + name  # (the bridge's namespace is "/")

    @staticmethod
    def _check_type(type_name):
        if type_name is not None and (type_name.count("/") != 1 or not all(type_name.split("/"))):
            raise protocol.RequestError(f"unknown type {type_name!r}")

    def advertise(self, session, topic, type_name, latch, queue_size):
        self._check_type(type_name)
        self._record("advertise", topic, type_name)

    def unadvertise(self, session, topic):
        self._record("unadvertise", topic)

    def publish(self, session, topic, msg, latch, queue_size):
        self._record("publish", topic, msg)

    def subscribe(self, session, topic, type_name):
        self._check_type(type_name)
        self._record("subscribe", topic, type_name)

    def unsubscribe(self, session, topic):
        self._record("unsubscribe", topic)

    def latched_messages(self, topic):
        return []

    def after_pending(self, session, then):
        return False  # (the ROS side is done at once here; test_protocol.py holds requests)

    def drives(self, session):
        return False

    def stop_driving(self, session):
        self._record("stop_driving")

    def release(self, session):
        self._record("release")

    def call_service(self, session, service, args, type_name, timeout, reply):
        self._record("call_service", service, args)
        reply(True, {"echo": args})

    def advertise_service(self, session, service, type_name):
        self._check_type(type_name)
        self._record("advertise_service", service, type_name)

    def unadvertise_service(self, session, service):
        self._record("unadvertise_service", service)

    def service_response(self, session, service, call_id, result, values):
        raise protocol.RequestError(f"service_response {service}: no call with id {call_id!r} is waiting")

    # (what only the Foxglove protocol asks: a rosbridge session never calls these)
    def publish_bytes(self, session, topic, data):
        self._record("publish_bytes", topic, data)

    def call_service_bytes(self, session, service, type_name, data, timeout, reply):
        self._record("call_service_bytes", service, data)

    def get_parameters(self, session, names, reply):
        self._record("get_parameters", names)

    def set_parameters(self, session, values, reply):
        self._record("set_parameters", values)

    def fetch_asset(self, session, uri, reply):
        self._record("fetch_asset", uri)

    def watch_graph(self, listener):
        self._record("watch_graph")

    def unwatch_graph(self, listener):
        self._record("unwatch_graph")


class Harness:
    """A session on the memory backend, with a manual clock and timers."""

    def __init__(self, **config):
        self.backend = MemoryBackend()
        self.host = Host(now=1_700_000_000.0)
        self.session = protocol.Session(self.backend, protocol.Config(**config), self.host)

    def frames(self):
        """Every frame queued since the last call, decoded (strict JSON: NaN/Infinity are refused; binary
        frames are CBOR)."""
        out = []
        for frame in drain(self.session):
            if isinstance(frame, bytes) and not isinstance(frame, frames.Utf8Text):
                out.append(cbor2.loads(frame))
                continue
            text = frame.decode() if isinstance(frame, bytes) else frame
            out.append(json.loads(text, parse_constant=_refuse_constant))
        return out

    def errors(self, frames):
        return [f for f in frames if f.get("op") == "status" and f.get("level") == "error"]

    def deliver_and_run_timers(self, count=3):
        """Delivers `count` messages on /chatter and runs due timers (advancing the clock to each) until none
        is left or a timer storm shows; returns the frames sent."""
        for n in range(count):
            self.session.deliver(received("/chatter", std_msgs.msg.String(f"m{n}"), self.host.now))
        for _ in range(100):
            if not self.host.timers:
                break
            delay = self.host.timers[0][1]
            assert math.isfinite(delay) and delay >= 0, f"timer with delay {delay}"
            self.host.run_next()
        assert not self.host.timers, f"still rescheduling after 100 timers: {self.host.timers[:3]}"
        return self.frames()

    def works(self):
        """A valid call_service round trip still gets its answer."""
        self.session.handle_text('{"op":"call_service","service":"/still_alive","args":{"n":1},"id":"alive"}')
        frames = self.frames()
        assert frames == [
            {
                "op": "service_response",
                "service": "/still_alive",
                "values": {"echo": {"n": 1}},
                "result": True,
                "id": "alive",
            }
        ], frames
        return True


def _refuse_constant(name):
    raise AssertionError(f"the bridge wrote {name}, which is not JSON")


def reported_id(request):
    """The id an error about `request` must carry, or None when it has no usable one."""
    if not isinstance(request, dict):
        return None
    value = request.get("id")
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        return None
    if isinstance(value, float) and not math.isfinite(value):
        return None  # JSON cannot carry it back
    return value


# ---- strategies -----------------------------------------------------------------------------------------
json_scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(),
    st.integers(min_value=-(10**40), max_value=10**40),
    st.floats(),
    st.text(max_size=20),
)
json_values = st.recursive(
    json_scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)),
    max_leaves=20,
)
ids = st.one_of(
    st.text(max_size=10), st.integers(), st.floats(), st.none(), st.booleans(), st.lists(st.integers(), max_size=2)
)


@st.composite
def requests_for_known_ops(draw):
    """A dict with a known op: each field of the op present or not, with a value of the right type or not,
    sometimes an unknown field."""
    op = draw(st.sampled_from(sorted(protocol.OPS)))
    request = {"op": op}
    for name, ((types, _), _required) in protocol.OPS[op].items():
        if draw(st.integers(0, 4)) == 0:
            continue  # missing (required ones too)
        if draw(st.booleans()):
            request[name] = draw(right_typed(types, name))
        else:
            request[name] = draw(json_values)
    if draw(st.integers(0, 6)) == 0:
        request[draw(st.text(min_size=1, max_size=8))] = draw(json_scalars)
    return request


def right_typed(types, name):
    if name in ("topic", "service"):
        return st.one_of(st.sampled_from(["/chatter", "/a/b", "", "/", "~x", "/rosapi/topics"]), st.text(max_size=12))
    if name == "type":
        return st.sampled_from(["std_msgs/String", "std_msgs/Int32", "nonsense", "a/b/c", ""])
    if name == "compression":
        return st.sampled_from(list(protocol.COMPRESSIONS) + ["gzip", ""])
    if name == "level":
        return st.sampled_from(list(protocol.STATUS_LEVELS) + ["debug", ""])
    if name == "data":
        return st.sampled_from(["", "iVBORw0KGgo=", '{"op":"set_level","level":"info"}', "@@@"])
    if name in ("msg", "args"):
        return st.one_of(st.dictionaries(st.text(max_size=6), json_scalars, max_size=3), st.lists(json_scalars))
    strategies = {
        str: st.text(max_size=12),
        bool: st.booleans(),
        int: st.integers(-(10**20), 10**20),
        float: st.floats(),
        dict: st.dictionaries(st.text(max_size=6), json_scalars, max_size=3),
        list: st.lists(json_scalars, max_size=3),
        object: json_values,
    }
    return st.one_of(*(strategies[t] for t in types))


def text_of(value):
    """JSON text as a client could send it (Python's json writes NaN/Infinity, which the bridge must survive)."""
    return json.dumps(value)


# ---- properties -----------------------------------------------------------------------------------------
def check_one_frame(text, request=None):
    """Feeds one frame to a fresh session; returns (harness, frames). Checks: no exception, strict JSON out,
    at most one error, and the error carries the request's id."""
    harness = Harness()
    harness.session.handle_text(text)
    frames = harness.frames()
    errors = harness.errors(frames)
    assert len(errors) <= 1, frames
    if errors:
        expected_id = reported_id(request)
        if expected_id is not None:
            assert errors[0].get("id") == expected_id, (text[:200], errors)
        assert isinstance(errors[0]["msg"], str) and errors[0]["msg"]
    return harness, frames


@SETTINGS
@given(json_values)
def test_any_json_value_that_is_not_a_request_gets_one_error(value):
    harness, frames = check_one_frame(text_of(value), value)
    if not isinstance(value, dict) or "op" not in value:
        assert len(harness.errors(frames)) == 1 and not harness.backend.calls, frames
    assert harness.works()


@SETTINGS
@given(requests_for_known_ops())
def test_known_ops_with_random_fields_are_done_or_refused_once(request):
    harness, frames = check_one_frame(text_of(request), request)
    errors = harness.errors(frames)
    try:
        protocol.check_fields(request["op"], request)
        well_formed = True
    except protocol.RequestError:
        well_formed = False
    if not well_formed:
        assert len(errors) == 1 and not harness.backend.calls, (request, frames)
    if errors:  # a refused request leaves nothing behind
        assert not harness.session.subscriptions and not harness.backend.calls, (request, harness.backend.calls)
    if harness.session.level != protocol.STATUS_LEVELS.index("none"):
        assert harness.works()


@SETTINGS
@given(
    st.sampled_from(sorted(protocol.OPS)),
    st.sampled_from(["topic", "service", "msg", "args", "id", "type", "num", "level", "result", "mac"]),
    st.one_of(
        st.lists(st.integers(), max_size=2),
        st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
        st.booleans(),
        st.floats(allow_nan=False),
        st.text(max_size=5),
    ),
    ids,
)
def test_a_wrong_typed_field_is_refused_with_the_id(op, field, value, request_id):
    fields = protocol.OPS[op]
    if field not in fields:
        value_ok = False  # an unknown field
    else:
        (types, _), _ = fields[field]
        value_ok = isinstance(value, types) and (not isinstance(value, bool) or bool in types)
    if value_ok or field == "id":
        return
    request = {"op": op, field: value}
    if request_id is not None and "id" in fields:
        request["id"] = request_id
    harness, frames = check_one_frame(text_of(request), request)
    errors = harness.errors(frames)
    assert len(errors) == 1 and not harness.backend.calls, frames
    assert repr(field) in errors[0]["msg"] or "missing" in errors[0]["msg"] or "unknown" in errors[0]["msg"]
    assert harness.works()


@SETTINGS
@given(st.text(max_size=200), st.integers(0, 199))
def test_random_and_truncated_text_never_raises(text, cut):
    valid = '{"op":"subscribe","topic":"/chatter","type":"std_msgs/String","id":"sub:1"}'
    for frame in (text, valid[: cut % len(valid)], valid + text):
        try:
            request = json.loads(frame)
        except ValueError:
            request = None
        harness, frames = check_one_frame(frame, request)
        if request is None:
            assert len(harness.errors(frames)) == 1
        assert harness.works()


@SETTINGS
@given(st.binary(max_size=100))
def test_binary_frames_are_refused_and_the_session_goes_on(data):
    harness = Harness()
    harness.session.handle_binary(data)
    assert len(harness.errors(harness.frames())) == 1
    assert harness.works()


@SETTINGS
@given(st.sampled_from(["[", '{"a":', '{"op":[', '[{"x":']), st.integers(10, 200_000))
def test_deep_nesting_gets_an_error_not_an_exception(opening, depth):
    text = opening * depth
    harness, frames = check_one_frame(text)
    assert len(harness.errors(frames)) == 1
    assert harness.works()


NUMBER_FIELDS = [
    {"op": "no_such_op", "id": "N"},
    {"op": "subscribe", "topic": "/chatter", "type": "std_msgs/String", "id": "s", "throttle_rate": "N"},
    {"op": "subscribe", "topic": "/chatter", "type": "std_msgs/String", "id": "s", "queue_length": "N"},
    {"op": "subscribe", "topic": "/chatter", "type": "std_msgs/String", "id": "s", "fragment_size": "N"},
    {"op": "call_service", "service": "/svc", "id": "c", "timeout": "N"},
    {"op": "advertise", "topic": "/chatter", "type": "std_msgs/String", "id": "a", "queue_size": "N"},
    {"op": "fragment", "id": "f", "data": "{}", "num": "N", "total": 2},
    {"op": "fragment", "id": "f", "data": "{}", "num": 0, "total": "N"},
    {"op": "auth", "mac": "00", "client": "c", "dest": "d", "rand": "r", "t": "N", "level": "admin", "end": 2},
    {"op": "auth", "mac": "00", "client": "c", "dest": "d", "rand": "r", "t": 1, "level": "admin", "end": "N"},
]


@SETTINGS
@given(
    st.sampled_from(["NaN", "Infinity", "-Infinity", "1e999", "-1e999", "1" * 5000, "123456789" * 3, "-0.0"]),
    st.sampled_from(NUMBER_FIELDS),
)
def test_huge_and_non_finite_numbers_in_every_number_field(number, request):
    text = text_of(request).replace('"N"', number)
    harness, frames = check_one_frame(text)
    if harness.errors(frames):  # refused: nothing left behind
        assert not harness.session.subscriptions and not harness.backend.calls, (text, harness.backend.calls)
    if harness.session.subscriptions:  # accepted: messages still flow, with sane timers
        harness.deliver_and_run_timers()
    for _, delay, _ in harness.host.timers:
        assert math.isfinite(delay) and delay >= 0, (text, delay)
    assert harness.works()


@SETTINGS
@given(
    st.lists(
        st.one_of(requests_for_known_ops().map(text_of), json_values.map(text_of), st.text(max_size=40)),
        min_size=1,
        max_size=12,
    )
)
def test_a_session_survives_any_sequence_of_frames(texts):
    harness = Harness()
    for text in texts:
        harness.session.handle_text(text)
        frames = harness.frames()
        assert len(harness.errors(frames)) <= 1, (text, frames)
    # a client that set its level to "none" hears no errors, but its requests still work
    harness.session.handle_text('{"op":"set_level","level":"error"}')
    harness.frames()
    assert harness.works()


@SETTINGS
@given(st.text(min_size=1, max_size=30), st.text(max_size=30))
def test_unicode_topics_and_ids_come_back_intact(topic, request_id):
    harness = Harness()
    harness.session.handle_text(text_of({"op": "subscribe", "topic": topic, "type": "bad type", "id": request_id}))
    errors = harness.errors(harness.frames())
    assert len(errors) == 1 and errors[0]["id"] == request_id


@SETTINGS
@given(requests_for_known_ops())
def test_before_auth_every_op_but_auth_is_refused(request):
    harness = Harness(authenticate=True, auth_secret="secret")
    harness.session.handle_text(text_of(request))
    frames = harness.frames()
    assert not harness.session.authenticated
    assert not harness.backend.calls, (request, harness.backend.calls)
    assert len(harness.errors(frames)) == 1, frames


@SETTINGS
@given(st.sampled_from(["topics", "services"]), st.text(max_size=20))
def test_globs_refuse_every_name_they_do_not_allow(kind, name):
    harness = Harness(globs=Globs(topics=["/allowed/*"], services=["/allowed/*"]))
    if kind == "topics":
        requests = [
            {"op": op, "topic": name, "type": "std_msgs/String", "msg": {}, "id": "g"}
            for op in ("subscribe", "advertise", "publish")
        ]
    else:
        requests = [
            {"op": "call_service", "service": name, "id": "g"},
            {"op": "advertise_service", "service": name, "type": "std_srvs/Empty", "id": "g"},
        ]
    for request in requests:
        request = {k: v for k, v in request.items() if k == "op" or k in protocol.OPS[request["op"]]}
        harness.session.handle_text(text_of(request))
        errors = harness.errors(harness.frames())
        hidden = not name.startswith("/allowed/") and not (kind == "services" and name.startswith("/rosapi/"))
        if hidden:
            assert len(errors) == 1 and "not allowed" in errors[0]["msg"] and not harness.backend.calls, errors
