"""The Foxglove WebSocket protocol for one client (`foxglove.websocket.v1`, or its other name `foxglove.sdk.v1`),
with ROS 1 data: channels carry each message's TCPROS bytes as they are (encoding `ros1`, schemas `ros1msg`).

What the transport sees is the same as for a rosbridge Session (contract.ProtocolSession): text and binary frames
in, frames out of an Outbox (small before big, each topic fresh on a slow link, bounded per client and for all).
What it asks of ROS goes through contract.Backend, shared with rosbridge clients: one subscription per topic,
one read. What all Foxglove clients are told alike (channels, services, the graph) is kept by the Catalog.
Pure: no rospy, no tornado."""

import json

from rosbridge.codec.json_values import dumps
from rosbridge.contract import DELETE
from rosbridge.errors import ClientError, RequestError, log_bug
from rosbridge.foxglove import parameters as params
from rosbridge.foxglove import wire
from rosbridge.globs import allowed
from rosbridge.protocol.outbox import OutboxSession

LEVELS = {"info": 0, "warning": 1, "error": 2}
ENCODINGS = ("ros1", "json")  # what clients may publish and call services with
CAPABILITIES = ("clientPublish", "parameters", "parametersSubscribe", "services", "connectionGraph", "assets")
# requests whose ROS side (publishers and subscribers made and dropped) is the ROS worker's, shared by every client:
# after one, the client's next messages wait in its socket until that work is done (holding), so that a client
# cannot queue work without bound there (200 topics advertised and unadvertised in a loop queued 180,000)
PACED_OPS = frozenset(("subscribe", "unsubscribe", "advertise", "unadvertise"))
SHOWN_REFUSALS = 3  # entries of one request refused that its status names; it counts the others
MAX_PARAMETER_NAMES = 10_000  # names in one request, and names one client subscribes to
# getParameters and setParameters of one client under way at once; more are refused (each may carry every parameter:
# 100 getParameters of a 28 MB tree at once took the bridge to +615 MB)
MAX_PARAMETER_REQUESTS = 4
# s: a service call not answered by then fails (serviceCallFailure); the protocol has no timeout of its own, and a
# call holds one of the client's call slots (ros_side.backend: 16 at once) while it runs
CALL_TIMEOUT = 60.0
MAX_ASSETS_IN_FLIGHT = 4  # fetchAsset requests of one client being read at once; more are refused


class FoxgloveSession(OutboxSession):
    """One Foxglove client. `host` is its connection (contract.SessionHost); `catalog` the bridge's Catalog."""

    authenticated = True  # (the protocol has no authentication: with authenticate on, the handshake refuses it)
    holding = False  # after a PACED_OPS request, while its ROS side is under way (the host then reads nothing)

    def __init__(self, backend, config, host, catalog, name="client", session_id=""):
        super().__init__(config, host)
        self.backend, self.name, self._catalog = backend, name, catalog
        self._subscriptions = {}  # subscription id -> topic
        self._topics = {}  # topic -> subscription id (one per channel)
        self._client_channels = {}  # client channel id -> (topic, encoding, type)
        self.parameter_subscriptions = set()  # names; params.ALL: every parameter
        self.graph_subscribed = False
        self._assets_in_flight = 0
        self._parameter_requests = 0  # getParameters and setParameters under way
        self.send_json(
            {
                "op": "serverInfo",
                "name": "turtlesim rosbridge (ROS 1)",
                "capabilities": list(CAPABILITIES) + (["time"] if catalog.sim_clock is not None else []),
                "supportedEncodings": list(ENCODINGS),
                # (Debian's ROS 1 is noetic's: Lichtblick takes ROS 1's common message definitions by this name,
                # and ROS 2's, whose Header differs, by any other)
                "metadata": {"ROS_DISTRO": "noetic"},
                "sessionId": session_id,
            }
        )
        catalog.join(self)

    # ---- incoming -------------------------------------------------------------------------------
    def handle_text(self, text):
        limit = self.config.max_message_size
        if limit and len(text) > limit:
            self.status("error", f"message of {len(text)} bytes refused: over max_message_size ({limit} bytes)")
            return
        try:
            request = json.loads(text)
        except (ValueError, RecursionError) as error:
            self.status("error", f"message is not valid JSON ({error}): {text[:60]!r}")
            return
        op = request.get("op") if isinstance(request, dict) else None
        self._answering(op, self._dispatch, op, request)
        if isinstance(op, str) and op in PACED_OPS and self.backend.after_pending(self, self._settled):
            self.holding = True

    def _settled(self):
        self.holding = False
        if not self.is_closed:
            self._host.resume_reading()

    def handle_binary(self, data):
        limit = self.config.max_message_size
        if limit and len(data) > limit:
            self.status("error", f"binary message of {len(data)} bytes refused: over max_message_size ({limit} bytes)")
            return
        self._answering("binary message", self._dispatch_binary, data)

    def _dispatch(self, op, request):
        handler = _OPS.get(op) if isinstance(op, str) else None
        if handler is None:
            raise RequestError(f"unknown op {str(op)[:60]!r}" if op is not None else "missing field 'op'")
        handler(self, request)

    def _dispatch_binary(self, data):
        message = wire.client_message(data)
        if message[0] == "publish":
            self._publish(*message[1:])
        else:
            self._call(*message[1:])

    def _answering(self, what, fn, *args):
        """fn(*args): a refusal becomes a status error; a bug is logged and the client told; the session goes on."""
        try:
            fn(*args)
        except ClientError as error:
            self.status("error", str(error))
        except Exception:
            log_bug(f"foxglove {what} failed")
            self.status("error", f"{what}: internal error (logged by the bridge)")

    # ---- subscriptions ----------------------------------------------------------------------------
    def _op_subscribe(self, req):
        self._each(_list(req, "subscriptions"), self._subscribe)

    def _subscribe(self, entry):
        sub_id, channel_id = _u32(entry, "id"), _u32(entry, "channelId")
        channel = self._catalog.channel(channel_id)
        if sub_id in self._subscriptions:
            raise RequestError(f"subscribe: subscription id {sub_id} is already in use")
        if channel is None:
            raise RequestError(f"subscribe: no channel {channel_id}")
        topic = channel["topic"]
        if topic in self._topics:
            raise RequestError(f"subscribe: channel {channel_id} ({topic}) is already subscribed")
        limit = self.config.max_topics_per_client
        if len(self._topics) >= limit:
            raise RequestError(f"subscribe {topic}: refused, {limit} already (max_topics_per_client)")
        self._subscriptions[sub_id] = topic
        self._topics[topic] = sub_id
        self.backend.subscribe(self, topic, channel["schemaName"])

    def _op_unsubscribe(self, req):
        self._each(_list(req, "subscriptionIds"), self._unsubscribe, "warning")

    def _unsubscribe(self, sub_id):
        topic = self._subscriptions.pop(sub_id, None) if type(sub_id) is int else None
        if topic is None:
            raise RequestError(f"unsubscribe: no subscription {str(sub_id)[:20]}")
        del self._topics[topic]
        self.backend.unsubscribe(self, topic)

    def _each(self, entries, handle, level="error"):
        """handle(entry) for each entry of a request; those it refuses (ClientError) are told in one status: a
        subscribe of 10,000 channels that do not exist made 10,000 (0.1 s of the loop), and the client's other
        answers were dropped for them."""
        refused = []
        for entry in entries:
            try:
                handle(entry)
            except ClientError as error:
                refused.append(str(error))
        if refused:
            more = f"; and {len(refused) - SHOWN_REFUSALS} more" if len(refused) > SHOWN_REFUSALS else ""
            self.status(level, "; ".join(refused[:SHOWN_REFUSALS]) + more)

    # ---- client publishing ------------------------------------------------------------------------
    def _op_advertise(self, req):
        self._each(_list(req, "channels"), self._advertise)

    def _advertise(self, entry):
        channel_id = _u32(entry, "id")
        topic, encoding, type_name = (_string(entry, key) for key in ("topic", "encoding", "schemaName"))
        if channel_id in self._client_channels:
            raise RequestError(f"advertise: client channel {channel_id} is already advertised")
        if encoding not in ENCODINGS:
            raise RequestError(f"advertise {topic}: encoding must be one of {', '.join(ENCODINGS)}")
        if not allowed(topic, self.config.globs.topics):
            raise RequestError(f"advertise {topic}: not allowed by topics_glob {self.config.globs.topics}")
        limit = self.config.max_topics_per_client
        if len(self._client_channels) >= limit:
            raise RequestError(f"advertise {topic}: refused, {limit} already (max_topics_per_client)")
        self.backend.advertise(self, topic, type_name, False, 100)
        self._client_channels[channel_id] = (topic, encoding, type_name)

    def _op_unadvertise(self, req):
        self._each(_list(req, "channelIds"), self._unadvertise, "warning")

    def _unadvertise(self, channel_id):
        channel = self._client_channels.pop(channel_id, None) if isinstance(channel_id, int) else None
        if channel is None:
            raise RequestError(f"unadvertise: no client channel {str(channel_id)[:20]}")
        if not any(topic == channel[0] for topic, _, _ in self._client_channels.values()):
            self.backend.unadvertise(self, channel[0])

    def _publish(self, channel_id, payload):
        channel = self._client_channels.get(channel_id)
        if channel is None:
            raise RequestError(f"message data for client channel {channel_id}, which is not advertised")
        topic, encoding, type_name = channel
        if encoding == "ros1":
            self.backend.publish_bytes(self, topic, bytes(payload))
            return
        try:
            msg = json.loads(bytes(payload))
        except (ValueError, RecursionError) as error:
            raise RequestError(f"message data for {topic}: not JSON ({error})") from None
        if not isinstance(msg, dict):
            raise RequestError(f"message data for {topic}: a JSON message must be an object")
        self.backend.publish(self, topic, msg, False, 100)

    # ---- services ---------------------------------------------------------------------------------
    def _call(self, service_id, call_id, encoding, payload):
        service = self._catalog.service(service_id)
        if service is None:
            self._call_failed(service_id, call_id, f"no service {service_id}")
            return
        if encoding not in ENCODINGS:
            self._call_failed(service_id, call_id, f"encoding must be one of {', '.join(ENCODINGS)}")
            return
        name, type_name = service["name"], service["type"]

        def reply(ok, values):
            if self.is_closed:
                return
            if not ok:
                self._call_failed(service_id, call_id, str(values))
                return
            body = dumps(values).encode() if encoding == "json" else values
            self._queue(None, (wire.service_call_response(service_id, call_id, encoding, body),))

        try:
            if encoding == "ros1":
                self.backend.call_service_bytes(self, name, type_name, bytes(payload), CALL_TIMEOUT, reply)
                return
            try:
                args = json.loads(bytes(payload)) if len(payload) else {}
            except (ValueError, RecursionError) as error:
                raise RequestError(f"the request is not JSON ({error})") from None
            self.backend.call_service(self, name, args, type_name, CALL_TIMEOUT, reply)
        except ClientError as error:
            self._call_failed(service_id, call_id, str(error))

    def _call_failed(self, service_id, call_id, text):
        self.send_json({"op": "serviceCallFailure", "serviceId": service_id, "callId": call_id, "message": text})

    # ---- parameters -------------------------------------------------------------------------------
    def _names(self, req):
        names = req.get("parameterNames") or []
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise RequestError(f"{req['op']}: field 'parameterNames' must be a list of strings")
        if len(names) > MAX_PARAMETER_NAMES:
            raise RequestError(f"{req['op']}: at most {MAX_PARAMETER_NAMES} names")
        return names

    def _op_getParameters(self, req):  # noqa: N802 (the op's name)
        names, request_id = self._names(req), _request_id(req)
        for name in names:
            if not self._catalog.parameter_allowed(name):
                raise RequestError(f"getParameters {name}: not allowed by params_glob")
        self._ask_parameters(
            "getParameters",
            lambda reply: self.backend.get_parameters(self, names or None, reply),
            lambda values: self._parameter_values(values, request_id),
        )

    def _op_setParameters(self, req):  # noqa: N802
        request_id, updates = _request_id(req), {}
        for entry in _list(req, "parameters"):
            name, value = params.from_client(entry)
            if not self._catalog.parameter_allowed(name):
                raise RequestError(f"setParameters {name}: not allowed by params_glob")
            updates[name] = value

        def done(values):
            self._catalog.parameters_changed(values)
            if request_id is not None:
                self._parameter_values(values, request_id)

        self._ask_parameters("setParameters", lambda reply: self.backend.set_parameters(self, updates, reply), done)

    def _ask_parameters(self, op, ask, done):
        """ask(reply) of the backend, within MAX_PARAMETER_REQUESTS; done(values) with what it answers."""
        if self._parameter_requests >= MAX_PARAMETER_REQUESTS:
            raise RequestError(f"{op}: refused, {MAX_PARAMETER_REQUESTS} parameter requests of this client under way")

        def reply(ok, values):
            self._parameter_requests -= 1
            if self.is_closed:
                return
            if not ok:
                self.status("error", f"{op}: {values}")
                return
            done(values)

        self._parameter_requests += 1
        try:
            ask(reply)
        except ClientError:
            self._parameter_requests -= 1
            raise

    def _parameter_values(self, values, request_id=None):
        entries = [
            {"name": name} if value is DELETE else params.to_client(name, value)
            for name, value in values.items()
            if self._catalog.parameter_allowed(name)
        ]
        answer = {"op": "parameterValues", "parameters": entries}
        if request_id is not None:
            answer["id"] = request_id
        self.send_json(answer)

    def _op_subscribeParameterUpdates(self, req):  # noqa: N802
        names = set(self._names(req) or [params.ALL])
        if len(self.parameter_subscriptions | names) > MAX_PARAMETER_NAMES:
            raise RequestError(f"subscribeParameterUpdates: at most {MAX_PARAMETER_NAMES} names subscribed")
        self.parameter_subscriptions |= names
        self._catalog.parameters_wanted()

    def _op_unsubscribeParameterUpdates(self, req):  # noqa: N802
        names = self._names(req)
        if names:
            self.parameter_subscriptions.difference_update(names)
        else:
            self.parameter_subscriptions.clear()
        self._catalog.parameters_wanted()

    def parameters_updated(self, values):
        """Parameters that changed ({name: value or DELETE}); those the client subscribes to are sent."""
        subscribed = self.parameter_subscriptions
        if not subscribed:
            return
        if params.ALL not in subscribed:
            values = {name: value for name, value in values.items() if name in subscribed}
        if values:
            self._parameter_values(values)

    # ---- the graph, assets ------------------------------------------------------------------------
    def _op_subscribeConnectionGraph(self, req):  # noqa: N802
        self.graph_subscribed = True
        update = self._catalog.full_graph()
        if update is not None:
            self.tell((update,))

    def _op_unsubscribeConnectionGraph(self, req):  # noqa: N802
        self.graph_subscribed = False

    def _op_fetchAsset(self, req):  # noqa: N802
        request_id, uri = _u32(req, "requestId"), _string(req, "uri")
        if self._assets_in_flight >= MAX_ASSETS_IN_FLIGHT:
            self._queue(None, (wire.fetch_asset_response(request_id, error="busy: too many fetches at once"),))
            return
        self._assets_in_flight += 1

        def reply(ok, result):
            self._assets_in_flight -= 1
            if self.is_closed:
                return
            answer = (
                wire.fetch_asset_response(request_id, result)
                if ok
                else wire.fetch_asset_response(request_id, error=str(result))
            )
            self._queue(None, (answer,))

        try:
            self.backend.fetch_asset(self, uri, reply)
        except ClientError as error:
            reply(False, str(error))

    # ---- from the ROS side (contract.Client) ------------------------------------------------------
    def deliver(self, read):
        topic = read.topic
        sub_id = self._topics.get(topic)
        if sub_id is None:
            return
        clock = self._catalog.sim_clock
        receive_ns = clock.now_ns() if clock is not None else int(read.stamp * 1e9)
        self._queue_each(topic, wire.message_data(sub_id, receive_ns, read.datas))

    def ros_refused(self, op, name, text):
        if op == "subscribe" and name in self._topics:
            del self._subscriptions[self._topics.pop(name)]
        self.status("error", text)

    def request_service(self, call_id, service, args):
        log_bug("a Foxglove client asked to serve a service", RuntimeError(service))

    # ---- from the catalog ---------------------------------------------------------------------------
    def channels_gone(self, removed):
        """Channels gone (their entries): the client's subscriptions of those end."""
        for channel in removed:
            sub_id = self._topics.pop(channel["topic"], None)
            if sub_id is not None:
                del self._subscriptions[sub_id]
                self.backend.unsubscribe(self, channel["topic"])

    def tell(self, frames):
        """Frames every client is told alike (advertisements, graph updates), encoded once by the catalog."""
        for frame in frames:
            self._queue(None, (frame,))

    def send_time(self, frame):
        """The simulated time (sim_clock.py), kept fresh on a slow link as a topic's messages are."""
        self._queue("/clock", (frame,))

    # ---- outgoing -------------------------------------------------------------------------------------
    def status(self, level, msg, request_id=None, status_id=None):
        frame = {"op": "status", "level": LEVELS[level], "message": msg}
        if status_id is not None:
            frame["id"] = status_id
        self.send_json(frame)

    def send_json(self, obj):
        self._queue(None, (dumps(obj),))

    def report_frame(self, level, text):
        return dumps({"op": "status", "level": LEVELS[level], "message": text, "id": level})  # (a newer replaces it)

    def closed(self):
        if self.is_closed:
            return
        self.is_closed = True
        self._subscriptions.clear()
        self._topics.clear()
        self._client_channels.clear()
        self.parameter_subscriptions.clear()
        self._outbox.clear()
        self._catalog.leave(self)
        self.backend.release(self)


_OPS = {name[len("_op_") :]: method for name, method in vars(FoxgloveSession).items() if name.startswith("_op_")}


def _list(req, field):
    value = req.get(field)
    if not isinstance(value, list):
        raise RequestError(f"{req.get('op')}: field {field!r} must be a list")
    return value


def _u32(entry, field):
    value = entry.get(field) if isinstance(entry, dict) else None
    if type(value) is not int or not 0 <= value <= wire.U32_MAX:
        raise RequestError(f"field {field!r} must be an integer 0..{wire.U32_MAX}, got {str(value)[:40]}")
    return value


def _string(entry, field):
    value = entry.get(field)
    if not isinstance(value, str) or not value:
        raise RequestError(f"field {field!r} must be a non-empty string")
    return value


def _request_id(req):
    value = req.get("id")
    if value is not None and not isinstance(value, str):
        raise RequestError("field 'id' must be a string")
    return value
