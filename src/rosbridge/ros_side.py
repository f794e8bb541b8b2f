"""The ROS side of the bridge (the protocol's backend): rospy publishers, subscribers, service servers and
service calls, shared by every client with reference counts.

Everything here runs on the one event-loop thread, except three things that must not block it: rospy's own
threads (a received message only goes into the topic's inbox and wakes the loop once), service calls (run in
a small thread pool; their answers come back to the loop), and publishing (a thread per advertised topic takes
the converted messages from a bounded queue, see _Outbox)."""
import collections
import concurrent.futures
import itertools
import sys
import threading
import time
import warnings

import rosgraph
import rospy
import rosservice

from rosbridge.convert import ConversionError, from_json, request_from_args, to_json
from rosbridge.protocol import RequestError, TopicMessage
from rosbridge.types import message_class, service_class

INBOX_LIMIT = 10_000  # messages per topic waiting for the loop; beyond that the oldest are dropped
# A client usually publishes right after advertising, before any subscriber has connected to the new
# publisher (that takes the master's publisherUpdate and a TCP handshake): messages published while nobody was
# connected yet, in this window after advertising, are replayed to the subscribers that connect within it, so
# that the first Twist of a page is not lost. Never after a subscriber has left: a robot driver that restarts
# must not receive stale commands.
REPLAY_WINDOW = 1.0  # seconds after advertising


class _Publisher:
    __slots__ = ("type", "cls", "outbox", "clients", "unregister_timer")

    def __init__(self, type_name, cls, outbox):
        self.type, self.cls, self.outbox = type_name, cls, outbox
        self.clients = set()
        self.unregister_timer = None


class _Outbox(rospy.SubscribeListener):
    """Publishes one topic's messages from a thread of its own, with a synchronous rospy publisher.

    Not rospy's queued publisher on the loop: it yields the thread after every message (time.sleep(0)), which
    on a busy machine costs the loop far more than the publishing itself (client -> ROS: 4x fewer msg/s). Not
    a synchronous publisher on the loop either: one stalled subscriber would then freeze every client. The
    queue keeps rospy's queue_size meaning: when full, the oldest message is dropped (0 = unbounded)."""

    def __init__(self, topic, cls, latch, queue_size):
        with warnings.catch_warnings():  # rospy warns about queue_size=None: synchronous is meant here
            warnings.simplefilter("ignore")
            self._publisher = rospy.Publisher(topic, cls, latch=latch, queue_size=None, subscriber_listener=self)
        self._queue = collections.deque(maxlen=queue_size if 0 < queue_size < sys.maxsize else None)
        # (a latched publisher already sends its last message to every new subscriber)
        self._early = None if latch else collections.deque(maxlen=self._queue.maxlen or 100)
        self._early_until = time.monotonic() + REPLAY_WINDOW
        self._ready = threading.Event()
        self._closed = False
        threading.Thread(target=self._run, name=f"publish {topic}", daemon=True).start()

    def put(self, msg):
        self._queue.append(msg)
        self._ready.set()
        if self._queue.maxlen and len(self._queue) * 2 > self._queue.maxlen:
            time.sleep(0)  # the publishing thread falls behind: let it have the GIL before the queue overflows

    def peer_subscribe(self, topic_name, topic_publish, peer_publish):
        """On a rospy thread, when a subscriber connects: replay the early messages to it alone."""
        early = self._early
        if early is not None and time.monotonic() < self._early_until:
            for msg in list(early):
                peer_publish(msg)

    def peer_unsubscribe(self, topic_name, num_peers):
        self._early = None

    def close(self):
        """Publishes what is queued, then unregisters (in the publishing thread)."""
        self._closed = True
        self._ready.set()

    def _run(self):
        while True:
            self._ready.wait()
            self._ready.clear()
            while self._queue:
                msg = self._queue.popleft()
                try:
                    self._publisher.publish(msg)
                except Exception as error:  # a broken connection: rospy drops it; keep publishing to the others
                    rospy.logwarn("publishing on %s failed: %s", self._publisher.resolved_name, error)
                if self._early is not None:
                    if time.monotonic() >= self._early_until:
                        self._early = None
                    elif not self._publisher.get_num_connections():
                        self._early.append(msg)
            if self._closed:
                self._publisher.unregister()
                return


class _Subscriber:
    __slots__ = ("topic", "type", "subscriber", "sessions", "inbox", "wake_pending", "latched")

    def __init__(self, topic, type_name):
        self.topic, self.type = topic, type_name
        self.sessions = set()
        self.inbox = collections.deque(maxlen=INBOX_LIMIT)
        self.wake_pending = False
        self.latched = None  # the last message of a latched topic, for clients that subscribe later
        self.subscriber = None


class _ProvidedService:
    """A ROS service whose answers come from one websocket client."""
    __slots__ = ("name", "client_name", "type", "cls", "session", "server", "pending")

    def __init__(self, name, client_name, type_name, cls, session):
        self.name, self.type, self.cls, self.session = name, type_name, cls, session
        self.client_name = client_name  # as the client spelled it: its library routes our calls by that name
        self.pending = {}  # call id -> concurrent.futures.Future waited on by a rospy thread
        self.server = None


class RosBackend:
    def __init__(self, loop, executor, rosapi=None, unregister_timeout=10.0, service_timeout=60.0):
        self._loop, self._executor, self._rosapi = loop, executor, rosapi
        self._unregister_timeout = unregister_timeout
        self._service_timeout = service_timeout
        self._publishers = {}
        self._subscribers = {}
        self._services = {}
        self._call_ids = itertools.count(1)
        self._master = rosgraph.Master(rospy.get_name())
        self._client_count = rospy.Publisher("/client_count", message_class("std_msgs/Int32"), latch=True,
                                             queue_size=1)

    def set_client_count(self, count):
        self._client_count.publish(message_class("std_msgs/Int32")(count))

    @staticmethod
    def resolve_name(name):
        """A client's service name as ROS resolves it in the bridge node's namespace, like the reference
        (rospy.resolve_name): roslib 2.x calls rosapi by relative names ("rosapi/topics")."""
        return rospy.resolve_name(name)

    def _graph_type(self, topic):
        """The topic's type as the master knows it, or None."""
        for name, type_name in self._master.getTopicTypes():
            if name == topic:
                return type_name
        return None

    # ---- topics, client -> ROS --------------------------------------------------------------------
    def advertise(self, session, topic, type_name, latch=False, queue_size=100):
        entry = self._publishers.get(topic)
        if entry is None:
            cls = message_class(type_name)
            graph_type = self._graph_type(topic)
            if graph_type not in (None, type_name):
                raise RequestError(f"advertise {topic}: the topic already has type {graph_type}, not {type_name}")
            entry = self._publishers[topic] = _Publisher(type_name, cls, _Outbox(topic, cls, latch, queue_size))
        elif entry.type != type_name:
            raise RequestError(f"advertise {topic}: the bridge already publishes it as {entry.type}, not {type_name}")
        if entry.unregister_timer is not None:  # a client came back in time (page reload): keep the publisher
            self._loop.remove_timeout(entry.unregister_timer)
            entry.unregister_timer = None
        entry.clients.add(session)

    def unadvertise(self, session, topic):
        entry = self._publishers.get(topic)
        if entry is None or session not in entry.clients:
            raise RequestError(f"unadvertise {topic}: not advertised by this client")
        self._leave_publisher(topic, entry, session)

    def _leave_publisher(self, topic, entry, session):
        entry.clients.discard(session)
        if not entry.clients and entry.unregister_timer is None:
            # Kept a while: subscribers need not reconnect when the client comes back (e.g. a page reload)
            entry.unregister_timer = self._loop.call_later(
                self._unregister_timeout, lambda: self._unregister_publisher(topic, entry))

    def _unregister_publisher(self, topic, entry):
        entry.unregister_timer = None
        if not entry.clients and self._publishers.get(topic) is entry:
            del self._publishers[topic]
            entry.outbox.close()

    def publish(self, session, topic, msg, latch=False, queue_size=100):
        entry = self._publishers.get(topic)
        if entry is None or session not in entry.clients:
            type_name = entry.type if entry is not None else self._graph_type(topic)
            if type_name is None:
                raise RequestError(f"publish {topic}: cannot infer the topic's type; advertise it first")
            self.advertise(session, topic, type_name, latch, queue_size)
            entry = self._publishers[topic]
        entry.outbox.put(from_json(entry.cls, msg, now=rospy.Time.now))

    # ---- topics, ROS -> client --------------------------------------------------------------------
    def subscribe(self, session, topic, type_name=None):
        entry = self._subscribers.get(topic)
        if entry is None:
            graph_type = self._graph_type(topic)
            if type_name is None:
                type_name = graph_type
                if type_name is None:
                    raise RequestError(f"subscribe {topic}: cannot infer the topic's type (nobody publishes it "
                                       "yet); give 'type'")
            elif graph_type not in (None, type_name):
                raise RequestError(f"subscribe {topic}: the topic has type {graph_type}, not {type_name}")
            cls = message_class(type_name)
            entry = self._subscribers[topic] = _Subscriber(topic, type_name)
            entry.subscriber = rospy.Subscriber(topic, cls, self._on_message, callback_args=entry)
        elif type_name not in (None, entry.type):
            raise RequestError(f"subscribe {topic}: the topic has type {entry.type}, not {type_name}")
        if session not in entry.sessions:
            entry.sessions.add(session)
            if entry.latched is not None:
                latched = entry.latched
                self._loop.add_callback(lambda: session.deliver(latched))

    def unsubscribe(self, session, topic):
        entry = self._subscribers.get(topic)
        if entry is not None:
            entry.sessions.discard(session)
            if not entry.sessions:
                del self._subscribers[topic]
                entry.subscriber.unregister()

    def _on_message(self, msg, entry):
        """On a rospy thread: hand the message to the loop, waking it once per batch."""
        entry.inbox.append((msg, time.time()))
        if not entry.wake_pending:
            entry.wake_pending = True
            self._loop.add_callback(self._drain, entry)

    def _drain(self, entry):
        entry.wake_pending = False
        inbox, topic = entry.inbox, entry.topic
        for _ in range(len(inbox)):  # what is there now: a busy topic must not hold the loop (it wakes again)
            msg, stamp = inbox.popleft()
            message = TopicMessage(topic, msg, stamp)
            header = getattr(msg, "_connection_header", None)
            if header is not None and header.get("latching") == "1":
                entry.latched = message
            for session in tuple(entry.sessions):
                session.deliver(message)

    # ---- services called by a client --------------------------------------------------------------
    def call_service(self, session, service, args, type_name, timeout, reply):
        service = self.resolve_name(service)
        if self._rosapi is not None and self._rosapi.handles(service):
            future = self._executor.submit(self._rosapi.call, service, args)
        else:
            future = self._executor.submit(self._call_ros_service, service, args, type_name)
        answered = []

        def answer(ok, values):
            if not answered:
                answered.append(ok)
                reply(ok, values)

        def done(future):
            error = future.exception()
            if error is None:
                answer(True, future.result())
            else:
                answer(False, str(error) or repr(error))

        self._loop.add_future(future, done)
        if timeout is not None:
            self._loop.call_later(timeout, lambda: answer(False, f"Service {service} timed out after {timeout} s"))

    @staticmethod
    def _call_ros_service(service, args, type_name):
        """In a pool thread: the service's response as JSON, or an exception whose text goes to the client."""
        if type_name is None:
            type_name = rosservice.get_service_type(service)
            if type_name is None:
                raise RequestError(f"Service {service} does not exist")
        cls = service_class(type_name)
        request = request_from_args(cls._request_class, args, now=rospy.Time.now)
        try:
            response = rospy.ServiceProxy(service, cls)(request)
        except rospy.ServiceException as error:
            raise RequestError(f"Service {service} failed: {error}") from None
        return to_json(response)

    # ---- services provided by a client ------------------------------------------------------------
    def advertise_service(self, session, service, type_name):
        client_name, service = service, self.resolve_name(service)
        cls = service_class(type_name)
        entry = self._services.get(service)
        if entry is not None:
            if entry.session is session and entry.type == type_name:
                return
            self._shutdown_service(entry, "advertised again by another client")
        else:
            me = rospy.get_name()
            for name, providers in self._master.getSystemState()[2]:
                if name == service and any(p != me for p in providers):
                    raise RequestError(f"advertise_service {service}: already provided by {', '.join(providers)}")
        entry = self._services[service] = _ProvidedService(service, client_name, type_name, cls, session)
        entry.server = rospy.Service(service, cls, lambda request: self._serve(entry, request))

    def unadvertise_service(self, session, service):
        entry = self._services.get(self.resolve_name(service))
        if entry is None or entry.session is not session:
            raise RequestError(f"unadvertise_service {service}: not advertised by this client")
        self._shutdown_service(entry, "unadvertised by its client")

    def _shutdown_service(self, entry, why):
        del self._services[entry.name]
        entry.server.shutdown(why)
        for future in entry.pending.values():
            if not future.done():
                future.set_exception(rospy.ServiceException(f"service {entry.name} {why}"))
        entry.pending.clear()

    def _serve(self, entry, request):
        """On a rospy thread: forward the call to the client and wait for its service_response."""
        future = concurrent.futures.Future()
        self._loop.add_callback(self._forward_call, entry, request, future)
        try:
            return future.result(timeout=self._service_timeout)
        except concurrent.futures.TimeoutError:
            raise rospy.ServiceException(f"service {entry.name}: the client did not answer within "
                                         f"{self._service_timeout} s") from None

    def _forward_call(self, entry, request, future):
        if self._services.get(entry.name) is not entry:
            future.set_exception(rospy.ServiceException(f"service {entry.name} is no longer provided"))
            return
        call_id = f"service_request:{entry.name}:{next(self._call_ids)}"
        entry.pending[call_id] = future
        future.add_done_callback(lambda _: self._loop.add_callback(entry.pending.pop, call_id, None))
        entry.session.request_service(call_id, entry.client_name, to_json(request))

    def service_response(self, session, service, call_id, result, values):
        entry = self._services.get(self.resolve_name(service))
        if entry is None or entry.session is not session:
            raise RequestError(f"service_response {service}: not advertised by this client")
        future = entry.pending.pop(call_id, None)
        if future is None or future.done():
            raise RequestError(f"service_response {service}: no call with id {call_id!r} is waiting")
        if not result:
            # As the reference: an object still answers the ROS caller (roslibpy's examples return False from
            # handlers that fill the response); anything else fails the call, an error text as the reason.
            if not isinstance(values, dict):
                reason = values if isinstance(values, str) else \
                    f"service {service}: the client answered result=false: {values}"
                future.set_exception(rospy.ServiceException(reason))
                return
            session.status("warning", f"service_response {service}: result is false, but its values are an "
                                      "object: they are the ROS caller's response", call_id)
        try:
            response = from_json(entry.cls._response_class, {} if values is None else values)
        except ConversionError as error:
            future.set_exception(rospy.ServiceException(f"service {service}: invalid response: {error}"))
            raise RequestError(f"service_response {service}: {error}") from None
        future.set_result(response)

    # ---- a client left ----------------------------------------------------------------------------
    def release(self, session):
        for topic, entry in list(self._publishers.items()):
            if session in entry.clients:
                self._leave_publisher(topic, entry, session)
        for topic, entry in list(self._subscribers.items()):
            if session in entry.sessions:
                self.unsubscribe(session, topic)
        for entry in list(self._services.values()):
            if entry.session is session:
                self._shutdown_service(entry, "lost its client (disconnected)")
