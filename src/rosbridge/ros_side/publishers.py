"""Client -> ROS: the topics clients publish, one rospy publisher per topic shared by its clients."""
import collections
import sys
import threading
import time
import warnings

import rospy

from rosbridge.convert import from_json
from rosbridge.errors import RequestError
from rosbridge.ros_side.holders import Holders
from rosbridge.types import message_class

# A client usually publishes right after advertising, before any subscriber has connected to the new
# publisher (that takes the master's publisherUpdate and a TCP handshake): messages published while nobody was
# connected yet, in this window after advertising, are replayed to the subscribers that connect within it, so
# that the first Twist of a page is not lost. Never after a subscriber has left: a robot driver that restarts
# must not receive stale commands.
REPLAY_WINDOW = 1.0  # seconds after advertising


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
    queue keeps rospy's queue_size meaning: when full, the oldest message is dropped (0 = unbounded)."""

    def __init__(self, topic, cls, latch, queue_size):
        maxlen = queue_size if 0 < queue_size < sys.maxsize else None
        # (a latched publisher already sends its last message to every new subscriber)
        self._early = None if latch else EarlyReplay(maxlen or 100)
        with warnings.catch_warnings():  # rospy warns about queue_size=None: synchronous is meant here
            warnings.simplefilter("ignore")
            self._publisher = rospy.Publisher(topic, cls, latch=latch, queue_size=None,
                                              subscriber_listener=self._early)
        self._queue = collections.deque(maxlen=maxlen)
        self._ready = threading.Event()
        self._closed = False
        threading.Thread(target=self._run, name=f"publish {topic}", daemon=True).start()

    def put(self, msg):
        self._queue.append(msg)
        self._ready.set()
        if self._queue.maxlen and len(self._queue) * 2 > self._queue.maxlen:
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
                msg = self._queue.popleft()
                try:
                    self._publisher.publish(msg)
                except Exception as error:  # a broken connection: rospy drops it; keep publishing to the others
                    rospy.logwarn("publishing on %s failed: %s", self._publisher.resolved_name, error)
                if self._early is not None:
                    self._early.record(msg, self._publisher.get_num_connections)
            if self._closed:
                self._publisher.unregister()
                return


class _Entry:
    __slots__ = ("type", "cls", "publisher", "unregister_timer")

    def __init__(self, type_name, cls, publisher):
        self.type, self.cls, self.publisher = type_name, cls, publisher
        self.unregister_timer = None


class Publishers:
    """The topics clients publish. A topic's publisher outlives its last client by unregister_timeout seconds,
    so that a page reload finds its subscribers still connected."""

    def __init__(self, loop, graph_type, unregister_timeout):
        self._loop, self._graph_type, self._unregister_timeout = loop, graph_type, unregister_timeout
        self._entries = {}
        self._holders = Holders()

    def advertise(self, session, topic, type_name, latch, queue_size):
        entry = self._entries.get(topic)
        if entry is None:
            cls = message_class(type_name)
            graph_type = self._graph_type(topic)
            if graph_type not in (None, type_name):
                raise RequestError(f"advertise {topic}: the topic already has type {graph_type}, not {type_name}")
            entry = self._entries[topic] = _Entry(type_name, cls, ClientPublisher(topic, cls, latch, queue_size))
        elif entry.type != type_name:
            raise RequestError(f"advertise {topic}: the bridge already publishes it as {entry.type}, not {type_name}")
        if entry.unregister_timer is not None:  # a client came back in time (page reload): keep the publisher
            self._loop.remove_timeout(entry.unregister_timer)
            entry.unregister_timer = None
        self._holders.add(topic, session)

    def unadvertise(self, session, topic):
        if not self._holders.holds(topic, session):
            raise RequestError(f"unadvertise {topic}: not advertised by this client")
        self._leave(session, topic)

    def publish(self, session, topic, msg, latch, queue_size):
        entry = self._entries.get(topic)
        if entry is None or not self._holders.holds(topic, session):
            type_name = entry.type if entry is not None else self._graph_type(topic)
            if type_name is None:
                raise RequestError(f"publish {topic}: cannot infer the topic's type; advertise it first")
            self.advertise(session, topic, type_name, latch, queue_size)
            entry = self._entries[topic]
        entry.publisher.put(from_json(entry.cls, msg, now=rospy.Time.now))

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
            entry.publisher.close()
