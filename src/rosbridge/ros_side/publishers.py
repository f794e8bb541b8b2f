"""Client -> ROS: the topics clients publish, one rospy publisher per topic shared by its clients."""
import collections
import sys
import threading
import time
import warnings

import rospy

from rosbridge.errors import RequestError, refusal_text
from rosbridge.packing import packer
from rosbridge.ros_side.holders import Holders
from rosbridge.types import message_class
from rosbridge.wire import raw_publish_class

# A client usually publishes right after advertising, before any subscriber has connected to the new
# publisher (that takes the master's publisherUpdate and a TCP handshake): messages published while nobody was
# connected yet, in this window after advertising, are replayed to the subscribers that connect within it, so
# that the first Twist of a page is not lost. Never after a subscriber has left: a robot driver that restarts
# must not receive stale commands.
REPLAY_WINDOW = 1.0  # seconds after advertising
INFERRING_LIMIT = 100  # messages kept per topic while the master is asked for its type


class EarlyReplay:
    """The messages published before any subscriber connected, replayed to the subscribers that connect
    within REPLAY_WINDOW. A rospy subscriber listener: peer_subscribe / peer_unsubscribe run on rospy's
    threads while record runs on the publishing thread, so the buffer is only touched under the lock."""

    def __init__(self, maxlen, clock=time.monotonic):
        self._clock = clock
        self._until = clock() + REPLAY_WINDOW
        self._lock = threading.Lock()
        self._messages = collections.deque(maxlen=maxlen)
        self._over = False  # set once (window passed, or a subscriber left), never cleared

    def record(self, msg, connections):
        """After publishing msg: keep it if nobody was connected (connections() -> how many are now; asked
        outside the lock, as rospy calls the listener while holding its own)."""
        nobody = not connections()
        with self._lock:
            if self._over:
                return
            if self._clock() >= self._until:
                self._end()
            elif nobody:
                self._messages.append(msg)

    def peer_subscribe(self, topic_name, topic_publish, peer_publish):
        with self._lock:
            replay = () if self._over or self._clock() >= self._until else tuple(self._messages)
        for msg in replay:
            peer_publish(msg)

    def peer_unsubscribe(self, topic_name, num_peers):
        with self._lock:
            self._end()

    def _end(self):
        self._over = True
        self._messages.clear()


class ClientPublisher:
    """Publishes one topic's messages from a thread of its own, with a synchronous rospy publisher.

    Not rospy's queued publisher on the loop: it yields the thread after every message (time.sleep(0)), which
    on a busy machine costs the loop far more than the publishing itself (client -> ROS: 4x fewer msg/s). Not
    a synchronous publisher on the loop either: one stalled subscriber would then freeze every client. The
    queue keeps rospy's queue_size meaning: when full, the oldest message is dropped (0 = unbounded).

    The loop puts messages, serialized (rosbridge.packing), from the start; the worker makes the rospy publisher (a
    master call) and only then starts the thread, which publishes what waits."""

    def __init__(self, topic, cls, latch, queue_size):
        self.topic, self._cls, self._latch = topic, raw_publish_class(cls), latch
        maxlen = queue_size if 0 < queue_size < sys.maxsize else None
        self._queue = collections.deque(maxlen=maxlen)
        self._ready = threading.Event()
        self._closed = False
        self._publisher = self._early = None  # made on the worker before the thread starts

    def make(self, graph, type_name):
        """On the worker: check the graph's type, make the rospy publisher, start publishing."""
        graph_type = graph.topic_type(self.topic, published=True)
        if graph_type not in (None, type_name):
            raise RequestError(f"advertise {self.topic}: the topic is published as {graph_type}, not {type_name}")
        # (a latched publisher already sends its last message to every new subscriber)
        self._early = None if self._latch else EarlyReplay(self._queue.maxlen or 100)
        with warnings.catch_warnings():  # rospy warns about queue_size=None: synchronous is meant here
            warnings.simplefilter("ignore")
            self._publisher = rospy.Publisher(self.topic, self._cls, latch=self._latch, queue_size=None,
                                              subscriber_listener=self._early)
        threading.Thread(target=self._run, name=f"publish {self.topic}", daemon=True).start()

    def put(self, data):
        """Queues a message's serialized bytes."""
        self._queue.append(data)
        self._ready.set()
        if self._queue.maxlen and len(self._queue) * 2 > self._queue.maxlen and self._publisher is not None:
            time.sleep(0)  # the publishing thread falls behind: let it have the GIL before the queue overflows

    def close(self):
        """Publishes what is queued, then unregisters (in the publishing thread)."""
        self._closed = True
        self._ready.set()

    def _run(self):
        while True:
            self._ready.wait()
            self._ready.clear()
            while self._queue:
                msg = self._cls()
                data = self._queue.popleft()
                msg._buff = bytearray(data) if self._cls._has_header else data  # (rospy writes seq into a header)
                try:
                    self._publisher.publish(msg)
                except Exception as error:  # a broken connection: rospy drops it; keep publishing to the others
                    rospy.logwarn("publishing on %s failed: %s", self.topic, error)
                if self._early is not None:
                    self._early.record(msg, self._publisher.get_num_connections)
            if self._closed:
                self._publisher.unregister()
                return


class _Entry:
    __slots__ = ("type", "cls", "publisher", "ready", "unregister_timer")

    def __init__(self, type_name, cls, publisher):
        self.type, self.cls, self.publisher = type_name, cls, publisher
        self.ready = False
        self.unregister_timer = None


class Publishers:
    """The topics clients publish. A topic's publisher is made on the worker, and outlives its last client by
    unregister_timeout seconds, so that a page reload finds its subscribers still connected. A client learns of
    a failure on the worker through session.ros_refused."""

    def __init__(self, loop, worker, unregister_timeout):
        self._loop, self._worker, self._unregister_timeout = loop, worker, unregister_timeout
        self._entries = {}
        self._holders = Holders()
        self._inferring = {}  # topic -> [(session, msg, latch, queue_size)] waiting for the graph's type

    def advertise(self, session, topic, type_name, latch, queue_size):
        entry = self._entries.get(topic)
        if entry is None:
            cls = message_class(type_name)
            entry = self._entries[topic] = _Entry(type_name, cls, ClientPublisher(topic, cls, latch, queue_size))
            self._worker.submit(lambda: entry.publisher.make(self._worker.graph, type_name),
                                lambda error, _: self._made(topic, entry, error))
        elif entry.type != type_name:
            raise RequestError(f"advertise {topic}: the bridge already publishes it as {entry.type}, not {type_name}")
        if entry.unregister_timer is not None:  # a client came back in time (page reload): keep the publisher
            self._loop.remove_timeout(entry.unregister_timer)
            entry.unregister_timer = None
        self._holders.add(topic, session)

    def _made(self, topic, entry, error):
        if error is None:
            entry.ready = True
            if self._entries.get(topic) is not entry:  # dropped while it was being made
                entry.publisher.close()
            return
        if self._entries.get(topic) is entry:
            del self._entries[topic]
            if entry.unregister_timer is not None:
                self._loop.remove_timeout(entry.unregister_timer)
        text = refusal_text(error, f"advertising {topic}")
        for session in self._holders.holders(topic):
            self._holders.discard(topic, session)
            session.ros_refused("advertise", topic, text)

    def unadvertise(self, session, topic):
        if not self._holders.holds(topic, session):
            raise RequestError(f"unadvertise {topic}: not advertised by this client")
        self._leave(session, topic)

    def publish(self, session, topic, msg, latch, queue_size):
        entry = self._entries.get(topic)
        if entry is not None:
            if not self._holders.holds(topic, session):
                self.advertise(session, topic, entry.type, latch, queue_size)
            entry.publisher.put(packer(entry.cls)(msg, now=rospy.Time.now))
            return
        waiting = self._inferring.get(topic)
        if waiting is None:  # ask the master for the topic's type, off the loop
            waiting = self._inferring[topic] = []
            self._worker.submit(lambda: self._worker.graph.topic_type(topic),
                                lambda error, type_name: self._inferred(topic, error, type_name))
        if len(waiting) >= INFERRING_LIMIT:
            raise RequestError(f"publish {topic}: {INFERRING_LIMIT} messages already wait for the topic's type")
        waiting.append((session, msg, latch, queue_size))

    def _inferred(self, topic, error, type_name):
        for session, msg, latch, queue_size in self._inferring.pop(topic, ()):
            if session.is_closed:
                continue
            if error is None and type_name is None:
                error = RequestError(f"publish {topic}: cannot infer the topic's type; advertise it first")
            try:
                if error is not None:
                    raise error
                if topic not in self._entries:
                    self.advertise(session, topic, type_name, latch, queue_size)
                self.publish(session, topic, msg, latch, queue_size)
            except Exception as refused:
                session.ros_refused("publish", topic, refusal_text(refused, f"publishing {topic}"))

    def release(self, session):
        for topic in self._holders.names_of(session):
            self._leave(session, topic)

    def _leave(self, session, topic):
        entry = self._entries[topic]
        if self._holders.discard(topic, session) and entry.unregister_timer is None:
            entry.unregister_timer = self._loop.call_later(
                self._unregister_timeout, lambda: self._unregister(topic, entry))

    def _unregister(self, topic, entry):
        entry.unregister_timer = None
        if not self._holders.holders(topic) and self._entries.get(topic) is entry:
            del self._entries[topic]
            if entry.ready:
                entry.publisher.close()
