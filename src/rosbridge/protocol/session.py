"""The rosbridge v2 protocol for one websocket client: check every frame and dispatch it, keep the client's
state (subscriptions, authentication, status level) and call the ROS side through the `contract.Backend`
contract. Pure: no rospy, no tornado; its connection is its `contract.SessionHost` (a clock, timers, a wake-up).

The jobs around it have rooms of their own: reassembly.py (fragment and png ops), subscription.py (merging and
throttling), outbox.py (the outbox: whole messages, small first, fresh on a slow link), encoded.py (encoding what
goes out), and ../auth.py (rosauth)."""

import collections
import functools
import json
import math
import operator

from rosbridge import globs as globs_module
from rosbridge import settings
from rosbridge.auth import mac_is_valid
from rosbridge.codec.json_values import dumps
from rosbridge.contract import SessionHost
from rosbridge.errors import ClientError, RequestError, log_bug
from rosbridge.protocol.encoded import COMPRESSIONS, service_response_frames, status_frame
from rosbridge.protocol.ops import ID, OPS, check_fields
from rosbridge.protocol.outbox import OutboxSession, QueuePool
from rosbridge.protocol.reassembly import Fragments, unpack_png
from rosbridge.protocol.subscription import MAX_THROTTLE_RATE, Subscription

STATUS_LEVELS = ("info", "warning", "error", "none")
# ops the ROS side may refuse later, off the loop (see Session.ros_refused), and the field naming what they ask
LATER_REFUSALS = {"subscribe": "topic", "advertise": "topic", "publish": "topic", "advertise_service": "service"}
# ops whose ROS side may still be under way (off the loop) when they return: the client's next requests wait for
# it, so that e.g. a call of a service it just advertised finds the service
ORDERED_OPS = frozenset(
    ("advertise", "unadvertise", "subscribe", "unsubscribe", "advertise_service", "unadvertise_service")
)
AUTH_TIMEOUT = 10.0  # s: with authenticate, a client that has not authenticated by then is closed


class Config:
    """What a protocol session needs of the bridge's settings: the one Settings object (`settings`: the server's,
    which every layer reads; settings.py says what each means), whose values it reads through, never copies
    (config.max_queue is config.settings.max_queue), and what is derived from them once for every client.
    Keyword arguments override single settings (the unit tests': Config(max_queue=3))."""

    def __init__(self, current=None, globs=None, auth_secret=None, **overrides):
        unknown = set(overrides) - set(settings.BY_NAME)
        if unknown:
            raise TypeError(f"Config: unknown settings {sorted(unknown)}")
        base = current or settings.Settings()
        self.settings = settings.Settings(lambda name: overrides.get(name, getattr(base, name))) if overrides else base
        # what may wait for one slow client before the oldest whole messages are dropped: frames (max_queue), and
        # bytes: enough for a 16 MB occupancy grid as JSON (about 47 MB)
        self.max_queue_bytes = max(64_000_000, 2 * self.max_message_size)
        # and for all of them together, beyond OWN_QUEUE_BYTES each: two such clients' worth
        self.queue_pool = QueuePool(2 * self.max_queue_bytes)
        self.globs = globs or globs_module.Globs()
        self.auth_secret = auth_secret


# each setting reads through to the one Settings object: config.max_queue is config.settings.max_queue
for _setting in settings.SETTINGS:
    setattr(Config, _setting.name, property(operator.attrgetter("settings." + _setting.name), doc=_setting.meaning))


class Session(OutboxSession):
    """One websocket client: a contract.ProtocolSession and a contract.Client. Its connection, `host` (a
    contract.SessionHost), feeds it frames (handle_text / handle_binary), takes its queued frames (take_frame)
    once it is woken (host.wake()), and calls `closed` when the connection is gone.

    A client's requests take effect in the order it sent them: after an ORDERED_OPS request whose ROS side is
    still under way, the next ones are held (`holding` is true: the host stops reading the client meanwhile,
    so what is held stays small) and handled once it is done; then host.resume_reading() is called."""

    def __init__(self, backend, config, host: SessionHost, name="client"):
        super().__init__(config, host)
        self.backend, self.name = backend, name
        self._held = None  # frames received while an earlier request's ROS side is under way, in order
        self.subscriptions: dict[str, Subscription] = {}
        self.advertised: set[str] = set()
        # (op, name) -> the id of the latest such request, for refusals that come later
        self._ids: dict[tuple[str, str], object] = {}
        self.level = STATUS_LEVELS.index("error")
        self.authenticated = not config.authenticate
        self._auth_timer = None if self.authenticated else host.call_later(AUTH_TIMEOUT, self._auth_deadline)
        # its fragment ops' unfinished messages count with every client's
        self._fragments = Fragments(
            config.max_message_size, config.fragment_timeout, host.unfinished, self._fragments_made_way
        )
        self._fragments_timer = None  # when the next unfinished fragmented message expires

    # ---- incoming -------------------------------------------------------------------------------
    @property
    def holding(self):
        return self._held is not None

    def handle_text(self, text, depth=0):
        if self._held is not None and depth == 0:
            self._held.append((self.handle_text, text))
            return
        limit = self.config.max_message_size
        if limit and len(text) > limit:
            self.status("error", f"message of {len(text)} bytes refused: over max_message_size ({limit} bytes)")
            return
        try:
            request = json.loads(text)
        except (ValueError, RecursionError) as error:  # RecursionError: nested deeper than Python can parse
            self.status("error", f"message is not valid JSON ({error}): {text[:60]!r}")
            return
        self.handle_request(request, depth)

    def handle_binary(self, data):
        if self._held is not None:
            self._held.append((self.handle_binary, data))
            return
        self.status(
            "error",
            f"binary frame of {len(data)} bytes refused: rosbridge v2 clients send JSON text "
            "frames (binary frames are only sent by the server, for CBOR)",
        )

    def handle_request(self, request, depth=0):
        request_id = request.get("id") if isinstance(request, dict) else None
        if isinstance(request_id, float) and not math.isfinite(request_id):
            # NaN/Infinity, which Python's json reads but no JSON writer may send back: left out of every answer
            # (the ops echo the request's id), as an absent id is
            del request["id"]
            request_id = None
        elif not isinstance(request_id, ID[0]) or isinstance(request_id, bool):
            request_id = None
        op = request.get("op") if isinstance(request, dict) else None
        try:
            if not isinstance(request, dict):
                raise RequestError(
                    f"a message must be a JSON object with an 'op' field, got {json.dumps(request)[:60]}"
                )
            if op is None:
                raise RequestError("missing field 'op'")
            if not isinstance(op, str):
                raise RequestError(f"field 'op' must be a string, got {json.dumps(op)[:60]}")
            if op not in OPS:
                raise RequestError(f"unknown op {op[:60]!r}")
            check_fields(op, request)
            if not self.authenticated and op != "auth":
                raise RequestError(f"{op} refused: not authenticated (the first message must be a valid 'auth')")
            if depth > 2 and op in ("fragment", "png"):
                raise RequestError(f"{op} nested too deeply")
            getattr(self, "_op_" + op)(request, depth)
            if op in LATER_REFUSALS and request_id is not None:
                self._remember_id(op, request[LATER_REFUSALS[op]], request_id)
            if op in ORDERED_OPS and self._held is None and self.backend.after_pending(self, self._settled):
                self._held = collections.deque()
        except ClientError as error:
            self.status("error", str(error), request_id)
            if op == "call_service" and isinstance(request.get("service"), str) and self.authenticated:
                # client libraries wait for the service_response of their call: fail it at once too
                self._queue(None, service_response_frames(request["service"], request_id, False, str(error)))
            if op == "auth" and not self.authenticated:
                self.close("authentication failed")
        except Exception:  # a bug: logged (once a minute per kind), the client told, the connection kept
            log_bug(f"{op} failed")
            self.status("error", f"{op}: internal error (logged by the bridge)", request_id)
            if op == "auth" and not self.authenticated:
                self.close("authentication failed")

    def _settled(self):
        """The ROS side of the request that held the next ones is done: handle those, in order, until one of
        them holds the rest again."""
        held, self._held = self._held, None
        while held and not self.is_closed:
            handle, frame = held.popleft()
            handle(frame)
            if self._held is not None:
                held.extend(self._held)  # (nothing arrives meanwhile: this is one turn of the loop)
                self._held = held
                return
        if not self.is_closed:
            self._host.resume_reading()

    def _remember_id(self, op, name, request_id):
        ids = self._ids
        ids.pop((op, name), None)
        ids[(op, name)] = request_id
        if len(ids) > 2 * self.config.max_topics_per_client:  # (a client's names are bounded; keep it so)
            del ids[next(iter(ids))]

    def _check_topic(self, topic):
        if not globs_module.allowed(topic, self.config.globs.topics):
            raise RequestError(f"topic {topic!r} is not allowed by topics_glob {self.config.globs.topics}")

    def _check_service(self, service):
        service = self.backend.resolve_name(service)  # the globs name ROS names: "clear" is checked as "/clear"
        if not service.startswith("/rosapi/") and not globs_module.allowed(service, self.config.globs.services):
            raise RequestError(f"service {service!r} is not allowed by services_glob {self.config.globs.services}")

    def _check_topic_count(self, topics, topic, what):
        limit = self.config.max_topics_per_client
        if topic not in topics and len(topics) >= limit:
            raise RequestError(
                f"{what} {topic}: refused, this client already has {len(topics)} topics (max_topics_per_client {limit})"
            )

    def _op_advertise(self, req, depth):
        topic = req["topic"]
        self._check_topic(topic)
        self._check_topic_count(self.advertised, topic, "advertise")
        self.backend.advertise(self, topic, req["type"], bool(req.get("latch")), _positive(req, "queue_size", 100))
        self.advertised.add(topic)

    def _op_unadvertise(self, req, depth):
        self.backend.unadvertise(self, req["topic"])
        self.advertised.discard(req["topic"])

    def _op_publish(self, req, depth):
        topic = req["topic"]
        self._check_topic(topic)
        self._check_topic_count(self.advertised, topic, "publish")
        self.backend.publish(self, topic, req["msg"], bool(req.get("latch")), _positive(req, "queue_size", 100))
        self.advertised.add(topic)

    def _op_subscribe(self, req, depth):
        topic = req["topic"]
        self._check_topic(topic)
        compression = _compression(req)
        throttle_rate = req.get("throttle_rate") or 0
        queue_length = min(req.get("queue_length") or 0, self.config.max_queue)
        if not 0 <= throttle_rate <= MAX_THROTTLE_RATE:  # also NaN, which would spin or stall the timer
            raise RequestError(f"subscribe: throttle_rate must be 0..{MAX_THROTTLE_RATE} ms, got {throttle_rate}")
        if queue_length < 0:
            raise RequestError(f"subscribe: queue_length must not be negative, got {queue_length}")
        fragment_size = _positive(req, "fragment_size", None)
        self._check_topic_count(self.subscriptions, topic, "subscribe")
        self.backend.subscribe(self, topic, req.get("type"))
        subscription = self.subscriptions.get(topic)
        if subscription is None:
            subscription = self.subscriptions[topic] = Subscription(
                functools.partial(self._queue, topic),
                self._host.clock,
                self._host.call_later,
                self.config.max_queue_bytes,
                backlogged=lambda: len(self._outbox) > 0,
                off_loop=self._host.off_loop,
            )
        subscription.add(
            req.get("id"),
            {
                "throttle_rate": throttle_rate,
                "queue_length": queue_length,
                "fragment_size": fragment_size,
                "compression": compression,
            },
        )

    def _op_unsubscribe(self, req, depth):
        topic, sub_id = req["topic"], req.get("id")
        subscription = self.subscriptions.get(topic)
        if subscription is None:
            self.status("warning", f"unsubscribe: not subscribed to {topic}", sub_id)
            return
        if not subscription.remove(sub_id):
            self.status("warning", f"unsubscribe: no subscription to {topic} with id {sub_id!r}", sub_id)
            return
        if not subscription.requests:
            del self.subscriptions[topic]
            subscription.close()
            self.backend.unsubscribe(self, topic)

    def _op_call_service(self, req, depth):
        service, call_id = req["service"], req.get("id")
        self._check_service(service)
        compression = _compression(req)
        fragment_size = _positive(req, "fragment_size", None)
        timeout = req.get("timeout")
        if timeout is not None and not timeout > 0:  # also NaN
            raise RequestError("call_service: timeout must be positive (seconds)")

        def reply(ok, values):
            if not self.is_closed:
                self._queue(None, service_response_frames(service, call_id, ok, values, compression, fragment_size))

        args = req.get("args")
        self.backend.call_service(self, service, {} if args is None else args, req.get("type"), timeout, reply)

    def _op_advertise_service(self, req, depth):
        self._check_service(req["service"])
        self.backend.advertise_service(self, req["service"], req["type"])

    def _op_unadvertise_service(self, req, depth):
        self.backend.unadvertise_service(self, req["service"])

    def _op_service_response(self, req, depth):
        self.backend.service_response(self, req["service"], req.get("id"), req["result"], req.get("values"))

    def _op_fragment(self, req, depth):
        text = self._fragments.add(req["id"], req["num"], req["total"], req["data"], self._host.clock())
        if text is not None:
            self.handle_text(text, depth + 1)
        elif self._fragments_timer is None:
            self._expire_fragments()

    def _expire_fragments(self):
        """Drops the fragmented messages that were not whole within fragment_timeout (telling the client), and
        comes back when the next one is due: a client that stops sending holds nothing past it."""
        self._fragments_timer = None
        if self.is_closed:
            return
        now = self._host.clock()
        for frag_id, received, total in self._fragments.expire(now):
            self.status(
                "warning",
                f"fragment {frag_id!r}: dropped after fragment_timeout "
                f"({self.config.fragment_timeout} s) with {received} of {total} parts",
            )
        deadline = self._fragments.next_deadline()
        if deadline is not None:
            self._fragments_timer = self._host.call_later(max(0.0, deadline - now), self._expire_fragments)

    def _fragments_made_way(self, count):
        self.status(
            "error",
            f"{count} unfinished fragmented message(s) dropped: the unfinished messages of all "
            "clients were at their bound, and another client's came faster: send again",
        )

    def _op_png(self, req, depth):
        if (req.get("total") or 1) != 1:
            raise RequestError("png: split png messages are not supported; send fragment ops instead")
        self.handle_text(unpack_png(req["data"], self.config.max_message_size), depth + 1)

    def _op_auth(self, req, depth):
        if self.authenticated:
            return  # authentication is off, or done: the reference ignores auth then
        if not mac_is_valid(req, self.config.auth_secret, self._host.clock(), self.config.auth_time_delta):
            raise RequestError("auth: authentication failed (bad MAC, or t/end out of time)")
        self.authenticated = True
        self._cancel(self._auth_timer)
        self._auth_timer = None
        self.status("info", "authenticated")

    def _auth_deadline(self):
        """An idle socket that never authenticates must not keep a place that max_clients counts."""
        self._auth_timer = None
        if not self.authenticated and not self.is_closed:
            self.close(f"not authenticated within {AUTH_TIMEOUT:g} s")

    def _op_set_level(self, req, depth):
        if req["level"] not in STATUS_LEVELS:
            raise RequestError(f"set_level: level must be one of {', '.join(STATUS_LEVELS)}, got {req['level']!r}")
        self.level = STATUS_LEVELS.index(req["level"])

    # ---- from the ROS side ----------------------------------------------------------------------
    def deliver(self, read):
        """Messages of a topic this client subscribes to (contract.Client.deliver)."""
        subscription = self.subscriptions.get(read.topic)
        if subscription is not None:
            for message in read.messages:
                subscription.deliver(message)

    def ros_refused(self, op, name, text):
        """The ROS side could not do what an earlier `op` on `name` asked; it found out later, off the loop."""
        request_id = self._ids.pop((op, name), None)
        if op == "subscribe":
            subscription = self.subscriptions.pop(name, None)
            if subscription is not None:
                subscription.close()
        elif op in ("advertise", "publish"):
            self.advertised.discard(name)
        self.status("error", text, request_id)

    def request_service(self, call_id, service, args):
        """The ROS side forwards a call of a service this client advertised."""
        self.send(dumps({"op": "call_service", "id": call_id, "service": service, "args": args}))

    # ---- outgoing -------------------------------------------------------------------------------
    def status(self, level, msg, request_id=None):
        if STATUS_LEVELS.index(level) >= self.level:
            self.send(status_frame(level, msg, request_id))

    def send(self, frame):
        """Queues a frame that belongs to no topic (str: text, bytes: binary)."""
        self._queue(None, (frame,))

    def report_frame(self, level, text):
        return status_frame(level, text) if STATUS_LEVELS.index(level) >= self.level else None

    def closed(self):
        """The connection is gone: release everything this client held on the ROS side."""
        if self.is_closed:
            return
        self.is_closed = True
        self._held = None
        for subscription in self.subscriptions.values():
            subscription.close()
        self.subscriptions.clear()
        self._outbox.clear()
        self._fragments.clear()
        self._cancel(self._fragments_timer)
        self._cancel(self._auth_timer)
        self.backend.release(self)

    def _cancel(self, timer):
        if timer is not None:
            self._host.cancel_later(timer)


def _positive(req, name, default):
    value = req.get(name)
    if value is None:
        return default
    if value <= 0:
        raise RequestError(f"{req['op']}: {name} must be positive, got {value}")
    return value


def _compression(req):
    compression = req.get("compression") or "none"
    if compression not in COMPRESSIONS:
        raise RequestError(f"{req['op']}: compression must be one of {', '.join(COMPRESSIONS)}, got {compression!r}")
    return compression
