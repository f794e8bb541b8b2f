"""The rosbridge v2 protocol for one websocket client: parse and check every frame, keep the client's state
(subscriptions, fragments, authentication, status level, bounded outgoing queue) and call the ROS side through
the small `backend` interface below. Pure: no rospy, no tornado; the server gives it a clock and a timer.

Backend interface (ros_side.RosBackend implements it; every method runs on the event loop and raises
RequestError / ValueError with a message for the client when it refuses):
    advertise(session, topic, type, latch, queue_size)       unadvertise(session, topic)
    publish(session, topic, msg, latch, queue_size)          subscribe(session, topic, type)
    unsubscribe(session, topic)                              release(session)   (the client left)
    call_service(session, service, args, type, timeout, reply)  reply(ok, values) is called later on the loop
    advertise_service(session, service, type)                unadvertise_service(session, service)
    service_response(session, service, id, result, values)
    resolve_name(name)   a client's (maybe relative) service name as ROS resolves it; the service methods
                         take the client's spelling and resolve it themselves
"""
import base64
import collections
import hashlib
import hmac
import io
import itertools
import json
import logging
import math

from PIL import Image

from rosbridge import encoding
from rosbridge import globs as globs_module
from rosbridge.convert import dumps, to_json

STATUS_LEVELS = ("info", "warning", "error", "none")
COMPRESSIONS = ("none", "png", "cbor", "cbor-raw")


class RequestError(ValueError):
    """A request the bridge refuses; the text goes back to the client in a status frame."""


DEFAULT_MAX_MESSAGE_SIZE = 8_000_000


class Config:
    """The per-server settings the protocol needs (from the launch args). max_message_size 0: no limit."""

    def __init__(self, max_message_size=DEFAULT_MAX_MESSAGE_SIZE, fragment_timeout=600.0, max_queue=1000,
                 globs=None, authenticate=False, auth_secret=None, auth_time_delta=5.0):
        self.max_message_size = max_message_size
        self.fragment_timeout = fragment_timeout
        # what may wait for one slow client before the oldest frames are dropped: frames, and bytes
        self.max_queue = max_queue
        self.max_queue_bytes = max(32_000_000, 2 * max_message_size)
        self.globs = globs or globs_module.Globs()
        self.authenticate = authenticate
        self.auth_secret = auth_secret
        self.auth_time_delta = auth_time_delta


# JSON types of the fields of each op: (python types, name shown to the client)
STRING = ((str,), "a string")
INT = ((int,), "an integer")
NUMBER = ((int, float), "a number")
BOOL = ((bool,), "a boolean")
OBJECT = ((dict,), "an object")
ARGS = ((dict, list), "an object or a list")
ID = ((str, int, float), "a string or a number")
ANY = ((object,), "any value")

REQUIRED, OPTIONAL = True, False
OPS = {
    "advertise": {"topic": (STRING, REQUIRED), "type": (STRING, REQUIRED), "id": (ID, OPTIONAL),
                  "latch": (BOOL, OPTIONAL), "queue_size": (INT, OPTIONAL)},
    "unadvertise": {"topic": (STRING, REQUIRED), "id": (ID, OPTIONAL)},
    "publish": {"topic": (STRING, REQUIRED), "msg": (OBJECT, REQUIRED), "id": (ID, OPTIONAL),
                "latch": (BOOL, OPTIONAL), "queue_size": (INT, OPTIONAL)},
    "subscribe": {"topic": (STRING, REQUIRED), "id": (ID, OPTIONAL), "type": (STRING, OPTIONAL),
                  "throttle_rate": (NUMBER, OPTIONAL), "queue_length": (INT, OPTIONAL),
                  "fragment_size": (INT, OPTIONAL), "compression": (STRING, OPTIONAL)},
    "unsubscribe": {"topic": (STRING, REQUIRED), "id": (ID, OPTIONAL)},
    "call_service": {"service": (STRING, REQUIRED), "id": (ID, OPTIONAL), "args": (ARGS, OPTIONAL),
                     "type": (STRING, OPTIONAL), "fragment_size": (INT, OPTIONAL),
                     "compression": (STRING, OPTIONAL), "timeout": (NUMBER, OPTIONAL)},
    "advertise_service": {"service": (STRING, REQUIRED), "type": (STRING, REQUIRED), "id": (ID, OPTIONAL)},
    "unadvertise_service": {"service": (STRING, REQUIRED), "id": (ID, OPTIONAL)},
    "service_response": {"service": (STRING, REQUIRED), "result": (BOOL, REQUIRED), "id": (ID, OPTIONAL),
                         "values": (ANY, OPTIONAL)},
    "fragment": {"id": (ID, REQUIRED), "data": (STRING, REQUIRED), "num": (INT, REQUIRED),
                 "total": (INT, REQUIRED)},
    "png": {"data": (STRING, REQUIRED), "id": (ID, OPTIONAL), "num": (INT, OPTIONAL), "total": (INT, OPTIONAL)},
    "auth": {"mac": (STRING, REQUIRED), "client": (STRING, REQUIRED), "dest": (STRING, REQUIRED),
             "rand": (STRING, REQUIRED), "t": (NUMBER, REQUIRED), "level": (STRING, REQUIRED),
             "end": (NUMBER, REQUIRED)},
    "set_level": {"level": (STRING, REQUIRED), "id": (ID, OPTIONAL)},
}


# per op: ({field: (exact JSON-decoded types, type text)}, required field names), for a fast check_fields
_FIELD_CHECKS = {
    op: ({name: (frozenset(types) if types != (object,) else None, text) for name, ((types, text), _) in
          fields.items()}, tuple(name for name, (_, required) in fields.items() if required))
    for op, fields in OPS.items()}


def check_fields(op, request):
    """Raises RequestError naming the first missing, mistyped or unknown field of `request`."""
    fields, required = _FIELD_CHECKS[op]
    for name, value in request.items():
        check = fields.get(name)
        if check is None:
            if name == "op":
                continue
            raise RequestError(f"{op}: unknown field {name!r} (expected: {', '.join(fields)})")
        types, type_text = check
        # json.loads makes exact types (a bool is not an int here); None means absent (roslibpy sends null)
        if value is not None and types is not None and type(value) not in types:
            raise RequestError(f"{op}: field {name!r} must be {type_text}, got {json.dumps(value)[:80]}")
    for name in required:
        if request.get(name) is None:
            raise RequestError(f"{op}: missing required field {name!r}")


def status_frame(level, msg, request_id=None):
    frame = {"op": "status", "level": level, "msg": msg}
    if request_id is not None:
        frame["id"] = request_id
    return dumps(frame)


def mac_is_valid(auth, secret, now, time_delta):
    """rosauth's check: mac == hex(sha512(secret+client+dest+rand+int(t)+level+int(end))), t within
    time_delta seconds of now (a negative delta skips that check) and end still in the future."""
    if secret is None or not (math.isfinite(auth["t"]) and math.isfinite(auth["end"])):
        return False
    if time_delta >= 0 and abs(auth["t"] - now) >= time_delta:
        return False
    if auth["end"] <= now:
        return False
    text = "".join((secret, auth["client"], auth["dest"], auth["rand"], str(int(auth["t"])), auth["level"],
                    str(int(auth["end"]))))
    expected = hashlib.sha512(text.encode()).hexdigest()
    return hmac.compare_digest(expected.encode(), auth["mac"].lower().encode())


class Utf8Text(bytes):
    """A text frame already encoded to UTF-8, so that it is encoded once for all the clients it goes to."""
    __slots__ = ()


class TopicMessage:
    """One ROS message from a topic, encoded lazily and at most once per encoding for all its subscribers.
    stamp: its receipt time in seconds (sent with cbor-raw)."""
    __slots__ = ("topic", "msg", "stamp", "_json", "_frames")

    def __init__(self, topic, msg, stamp):
        self.topic, self.msg, self.stamp = topic, msg, stamp
        self._json = None  # the frames of the usual case: plain JSON, not fragmented
        self._frames = None  # (compression, fragment_size) -> frames, for the others

    def frames(self, compression, fragment_size):
        """The frames (Utf8Text for text, bytes for binary) that carry this message with these options."""
        if compression == "none" and fragment_size is None:
            if self._json is None:
                self._json = self._encode(compression, fragment_size)
            return self._json
        if self._frames is None:
            self._frames = {}
        key = (compression, fragment_size)
        frames = self._frames.get(key)
        if frames is None:
            frames = self._frames[key] = self._encode(compression, fragment_size)
        return frames

    def _encode(self, compression, fragment_size):
        if compression == "cbor":
            return (encoding.cbor_frame({"op": "publish", "topic": self.topic,
                                         "msg": encoding.to_cbor_value(self.msg)}),)
        if compression == "cbor-raw":
            secs = int(self.stamp)
            buffer = io.BytesIO()
            self.msg.serialize(buffer)  # the bytes rospy received: genpy serialization is canonical
            raw = {"bytes": buffer.getvalue(), "secs": secs, "nsecs": int((self.stamp - secs) * 1e9)}
            return (encoding.cbor_frame({"op": "publish", "topic": self.topic, "msg": raw}),)
        text = '{"op":"publish","topic":%s,"msg":%s}' % (dumps(self.topic), dumps(to_json(self.msg)))
        if compression == "png":
            text = dumps({"op": "png", "data": encoding.png_frame(text)})
        return tuple(Utf8Text(part.encode()) for part in fragment_text(text, fragment_size))


_fragment_ids = itertools.count(1)


def fragment_text(text, fragment_size):
    if fragment_size is None or len(text) <= fragment_size:
        return (text,)
    return tuple(dumps(f) for f in encoding.fragments(text, fragment_size, f"fragment:{next(_fragment_ids)}"))


class Subscription:
    """All of one client's subscribe requests to one topic, merged: lowest throttle_rate, lowest
    fragment_size, longest queue_length, the latest compression."""
    __slots__ = ("requests", "throttle_rate", "queue_length", "fragment_size", "compression", "last_sent",
                 "pending", "flush_scheduled")

    def __init__(self):
        self.requests = {}  # subscribe id (None when the client gave none) -> its options
        self.last_sent = float("-inf")
        self.pending = collections.deque(maxlen=1)
        self.flush_scheduled = False

    def merge(self):
        options = list(self.requests.values())
        self.throttle_rate = min(o["throttle_rate"] for o in options) / 1000.0
        self.queue_length = max(o["queue_length"] for o in options)
        sizes = [o["fragment_size"] for o in options if o["fragment_size"] is not None]
        self.fragment_size = min(sizes) if sizes else None
        self.compression = options[-1]["compression"]
        if self.pending.maxlen != max(1, self.queue_length):
            self.pending = collections.deque(self.pending, maxlen=max(1, self.queue_length))


class Session:
    """One websocket client. The server feeds it frames (handle_text / handle_binary), drains its outgoing
    queue (take_frame) when `wake` is called, and calls `closed` when the connection is gone.

    clock() -> seconds since the epoch; call_later(delay, fn) runs fn on the loop later; wake() says frames
    are waiting; close(reason) asks the server to close the connection after the queued frames."""
    MAX_FRAGMENT_SETS = 100

    def __init__(self, backend, config, clock, call_later, wake, close, name="client"):
        self.backend, self.config, self.name = backend, config, name
        self._clock, self._call_later, self._wake, self._close = clock, call_later, wake, close
        self.subscriptions = {}
        self.level = STATUS_LEVELS.index("error")
        self.authenticated = not config.authenticate
        self.is_closed = False
        self._queue = collections.deque()
        self._queued_bytes = 0
        self._dropped = 0
        self._woken = False
        self._fragments = {}  # fragment id -> [total, {num: data}, bytes so far, deadline]
        self._fragment_bytes = 0

    # ---- incoming -------------------------------------------------------------------------------
    def handle_text(self, text, depth=0):
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
        self.status("error", f"binary frame of {len(data)} bytes refused: rosbridge v2 clients send JSON text "
                             "frames (binary frames are only sent by the server, for CBOR)")

    def handle_request(self, request, depth=0):
        request_id = request.get("id") if isinstance(request, dict) else None
        if not isinstance(request_id, ID[0]) or isinstance(request_id, bool) or (
                isinstance(request_id, float) and not math.isfinite(request_id)):  # NaN/Infinity: not JSON
            request_id = None
        op = request.get("op") if isinstance(request, dict) else None
        try:
            if not isinstance(request, dict):
                raise RequestError(f"a message must be a JSON object with an 'op' field, got {json.dumps(request)[:60]}")
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
        except ValueError as error:  # RequestError, types.UnknownType, convert.ConversionError
            self.status("error", str(error), request_id)
            if op == "call_service" and isinstance(request.get("service"), str) and self.authenticated:
                # client libraries wait for the service_response of their call: fail it at once too
                self._service_response(request["service"], request_id, False, str(error))
            if op == "auth" and not self.authenticated:
                self.close("authentication failed")
        except Exception as error:  # a bug: tell the client, keep serving
            logging.getLogger("rosbridge").exception("%s: %s failed", self.name, op)
            self.status("error", f"{op}: internal error: {error!r}", request_id)

    def _check_topic(self, topic):
        if not globs_module.allowed(topic, self.config.globs.topics):
            raise RequestError(f"topic {topic!r} is not allowed by topics_glob {self.config.globs.topics}")

    def _check_service(self, service):
        service = self.backend.resolve_name(service)  # the globs name ROS names: "clear" is checked as "/clear"
        if not service.startswith("/rosapi/") and not globs_module.allowed(service, self.config.globs.services):
            raise RequestError(f"service {service!r} is not allowed by services_glob {self.config.globs.services}")

    def _op_advertise(self, req, depth):
        self._check_topic(req["topic"])
        self.backend.advertise(self, req["topic"], req["type"], bool(req.get("latch")),
                               _positive(req, "queue_size", 100))

    def _op_unadvertise(self, req, depth):
        self.backend.unadvertise(self, req["topic"])

    def _op_publish(self, req, depth):
        self._check_topic(req["topic"])
        self.backend.publish(self, req["topic"], req["msg"], bool(req.get("latch")),
                             _positive(req, "queue_size", 100))

    def _op_subscribe(self, req, depth):
        topic = req["topic"]
        self._check_topic(topic)
        compression = _compression(req)
        throttle_rate = req.get("throttle_rate") or 0
        queue_length = min(req.get("queue_length") or 0, self.config.max_queue)  # a deque needs a C-sized maxlen
        if not 0 <= throttle_rate < math.inf or queue_length < 0:  # NaN/Infinity would spin or stall the timer
            raise RequestError("subscribe: throttle_rate must be finite and queue_length must not be negative")
        fragment_size = _positive(req, "fragment_size", None)
        self.backend.subscribe(self, topic, req.get("type"))
        subscription = self.subscriptions.get(topic) or self.subscriptions.setdefault(topic, Subscription())
        subscription.requests.pop(req.get("id"), None)  # a repeated id moves to the end (latest compression)
        subscription.requests[req.get("id")] = {"throttle_rate": throttle_rate, "queue_length": queue_length,
                                               "fragment_size": fragment_size, "compression": compression}
        subscription.merge()

    def _op_unsubscribe(self, req, depth):
        topic, sub_id = req["topic"], req.get("id")
        subscription = self.subscriptions.get(topic)
        if subscription is None:
            self.status("warning", f"unsubscribe: not subscribed to {topic}", sub_id)
            return
        if sub_id is None:
            subscription.requests.clear()
        elif subscription.requests.pop(sub_id, False) is False:
            self.status("warning", f"unsubscribe: no subscription to {topic} with id {sub_id!r}", sub_id)
            return
        if subscription.requests:
            subscription.merge()
        else:
            del self.subscriptions[topic]
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
            self._service_response(service, call_id, ok, values, compression, fragment_size)

        args = req.get("args")
        self.backend.call_service(self, service, {} if args is None else args, req.get("type"), timeout, reply)

    def _service_response(self, service, call_id, ok, values, compression="none", fragment_size=None):
        if self.is_closed:
            return
        frame = {"op": "service_response", "service": service, "values": values, "result": ok}
        if call_id is not None:
            frame["id"] = call_id
        if compression in ("cbor", "cbor-raw"):
            self.send(encoding.cbor_frame(frame))
            return
        text = dumps(frame)
        if compression == "png":
            text = dumps({"op": "png", "data": encoding.png_frame(text)})
        for part in fragment_text(text, fragment_size):
            self.send(part)

    def _op_advertise_service(self, req, depth):
        self._check_service(req["service"])
        self.backend.advertise_service(self, req["service"], req["type"])

    def _op_unadvertise_service(self, req, depth):
        self.backend.unadvertise_service(self, req["service"])

    def _op_service_response(self, req, depth):
        self.backend.service_response(self, req["service"], req.get("id"), req["result"], req.get("values"))

    def _op_fragment(self, req, depth):
        frag_id, num, total, data = req["id"], req["num"], req["total"], req["data"]
        limit = self.config.max_message_size
        if total < 1 or not 0 <= num < total or (limit and total > limit):
            raise RequestError(f"fragment: num {num} / total {total} out of range")
        now = self._clock()
        self._expire_fragments(now)
        entry = self._fragments.get(frag_id)
        if entry is None:
            if len(self._fragments) >= self.MAX_FRAGMENT_SETS:
                raise RequestError(f"fragment: too many unfinished fragmented messages ({self.MAX_FRAGMENT_SETS})")
            entry = self._fragments[frag_id] = [total, {}, now + self.config.fragment_timeout]
        if entry[0] != total:
            raise RequestError(f"fragment {frag_id!r}: total changed from {entry[0]} to {total}")
        if limit and self._fragment_bytes + len(data) > limit:
            self._drop_fragments(frag_id)
            raise RequestError(f"fragment {frag_id!r}: reassembled message over max_message_size ({limit} bytes)")
        previous = entry[1].get(num)
        self._fragment_bytes += len(data) - (len(previous) if previous else 0)
        entry[1][num] = data
        if len(entry[1]) == total:
            parts = entry[1]
            self._drop_fragments(frag_id)
            self.handle_text("".join(parts[i] for i in range(total)), depth + 1)

    def _drop_fragments(self, frag_id):
        entry = self._fragments.pop(frag_id)
        self._fragment_bytes -= sum(len(part) for part in entry[1].values())

    def _expire_fragments(self, now):
        for frag_id, entry in list(self._fragments.items()):
            if entry[2] < now:
                self._drop_fragments(frag_id)
                self.status("warning", f"fragment {frag_id!r}: dropped after fragment_timeout "
                                       f"({self.config.fragment_timeout} s) with {len(entry[1])} of {entry[0]} parts")

    def _op_png(self, req, depth):
        if (req.get("total") or 1) != 1:
            raise RequestError("png: split png messages are not supported; send fragment ops instead")
        try:
            with Image.open(io.BytesIO(base64.b64decode(req["data"]))) as image:  # reads the header only
                size = image.width * image.height * 3
            limit = self.config.max_message_size
            if limit and size > limit:  # a small PNG can unpack to gigabytes
                raise RequestError(f"png: image holds {size} bytes, over max_message_size ({limit} bytes)")
            text = encoding.png_unframe(req["data"])
        except (ValueError, OSError) as error:  # bad base64, not a PNG, not UTF-8
            raise RequestError(f"png: cannot read the image: {error}") from None
        self.handle_text(text, depth + 1)

    def _op_auth(self, req, depth):
        if self.authenticated:
            return  # authentication is off, or done: the reference ignores auth then
        if not mac_is_valid(req, self.config.auth_secret, self._clock(), self.config.auth_time_delta):
            raise RequestError("auth: authentication failed (bad MAC, or t/end out of time)")
        self.authenticated = True
        self.status("info", "authenticated")

    def _op_set_level(self, req, depth):
        if req["level"] not in STATUS_LEVELS:
            raise RequestError(f"set_level: level must be one of {', '.join(STATUS_LEVELS)}, got {req['level']!r}")
        self.level = STATUS_LEVELS.index(req["level"])

    # ---- from the ROS side ----------------------------------------------------------------------
    def deliver(self, message):
        """A TopicMessage for a topic this client subscribes to."""
        subscription = self.subscriptions.get(message.topic)
        if subscription is None:
            return
        if not subscription.throttle_rate:
            self._send_frames(message.frames(subscription.compression, subscription.fragment_size))
            return
        subscription.pending.append(message)
        if not subscription.flush_scheduled:
            self._flush_throttled(subscription)

    def _flush_throttled(self, subscription):
        """Sends the oldest pending message if throttle_rate allows; otherwise comes back when it does. The
        latest message is kept (not dropped as the reference does), so a throttled stream ends on the last value."""
        subscription.flush_scheduled = False
        if self.is_closed or not subscription.pending or self.subscriptions.get(
                subscription.pending[0].topic) is not subscription:
            return
        wait = subscription.last_sent + subscription.throttle_rate - self._clock()
        if wait <= 0:
            message = subscription.pending.popleft()
            self._send_frames(message.frames(subscription.compression, subscription.fragment_size))
            subscription.last_sent = self._clock()
            wait = subscription.throttle_rate
            if not subscription.pending:
                return
        subscription.flush_scheduled = True
        self._call_later(wait, lambda: self._flush_throttled(subscription))

    def request_service(self, call_id, service, args):
        """The ROS side forwards a call of a service this client advertised."""
        self.send(dumps({"op": "call_service", "id": call_id, "service": service, "args": args}))

    # ---- outgoing -------------------------------------------------------------------------------
    def status(self, level, msg, request_id=None):
        if STATUS_LEVELS.index(level) >= self.level:
            self.send(status_frame(level, msg, request_id))

    def _send_frames(self, frames):
        for frame in frames:
            self.send(frame)

    def send(self, frame):
        """Queues a frame (str: text, bytes: binary); the oldest are dropped when the client is too slow."""
        if self.is_closed:
            return
        queue = self._queue
        queue.append(frame)
        self._queued_bytes += len(frame)
        while len(queue) > 1 and (len(queue) > self.config.max_queue
                                   or self._queued_bytes > self.config.max_queue_bytes):
            self._queued_bytes -= len(queue.popleft())
            self._dropped += 1
        if not self._woken:
            self._woken = True
            self._wake()

    def take_frame(self):
        """The next frame to write, or None when the queue is empty (the next send wakes the server again)."""
        if self._dropped:
            dropped, self._dropped = self._dropped, 0
            if STATUS_LEVELS.index("warning") >= self.level:
                return status_frame("warning", f"client too slow: dropped {dropped} oldest outgoing frame(s) "
                                               f"(queue bound: {self.config.max_queue} frames)")
        if not self._queue:
            self._woken = False
            return None
        frame = self._queue.popleft()
        self._queued_bytes -= len(frame)
        return frame

    def close(self, reason):
        self._close(reason)

    def closed(self):
        """The connection is gone: release everything this client held on the ROS side."""
        if self.is_closed:
            return
        self.is_closed = True
        self.subscriptions.clear()
        self._queue.clear()
        self._fragments.clear()
        self.backend.release(self)


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
