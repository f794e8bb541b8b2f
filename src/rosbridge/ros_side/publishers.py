"""Client -> ROS: the topics clients publish, one rospy publisher per topic shared by its clients."""

import collections
import sys
import time
import warnings

import rospy

from rosbridge.codec.json_to_ros import packer
from rosbridge.codec.ros_to_json import check_whole
from rosbridge.contract import DRIVE_TYPES
from rosbridge.errors import RequestError, refusal_text
from rosbridge.message_types import message_class
from rosbridge.ros_side import tcpros
from rosbridge.ros_side.holders import Holders

# A client usually publishes right after advertising, before any subscriber has connected to the new
# publisher (that takes the master's publisherUpdate and a TCP handshake): messages published while nobody was
# connected yet, in this window after the master knows the publisher, are replayed to the subscribers that connect
# within it, so that the first Twist of a page is not lost. (From advertising, a loaded machine's worker could take
# the whole window to register it: a page's first Twist was lost beside a CPU hog.) Never after a subscriber has
# left: a robot driver that restarts must not receive stale commands.
REPLAY_WINDOW = 1.0  # seconds after the publisher is registered
# bytes kept for that per topic (the newest messages; a bigger one is not kept): a client that advertised new topics
# and published 8 MB messages at once on each held 620 MB in 5 s, until it left
REPLAY_BYTES = 64 * 1024
INFERRING_LIMIT = 100  # messages kept per topic while the master is asked for its type
# publishers that outlive their last client (unregister_timeout) at once, at most; beyond, the one left longest goes
# now: clients that advertise and unadvertise new topics in a loop made 20,000 (1.5 GB) in a minute
MAX_LINGERING = 256


class EarlyReplay:
    """The messages published before any subscriber connected, for the subscribers that connect within
    REPLAY_WINDOW of registered(): the newest maxlen of them within REPLAY_BYTES. On the loop only."""

    def __init__(self, maxlen, clock=time.monotonic):
        self._clock = clock
        self._until = float("inf")  # (until the publisher is registered: no subscriber can connect before)
        self._messages = collections.deque()
        self._maxlen, self._bytes = maxlen, 0
        self._over = False  # set once (window passed, or a subscriber left), never cleared

    def record(self, data):
        """A message published while nobody was connected."""
        if self._over:
            return
        if self._clock() >= self._until:
            self.end()
        elif len(data) <= REPLAY_BYTES:
            self._messages.append(data)
            self._bytes += len(data)
            while len(self._messages) > self._maxlen or self._bytes > REPLAY_BYTES:
                self._bytes -= len(self._messages.popleft())

    def registered(self):
        """The master knows the publisher: subscribers connect from now on."""
        self._until = self._clock() + REPLAY_WINDOW

    def replay(self):
        """What a subscriber that connects now gets first."""
        if self._over or self._clock() >= self._until:
            return ()
        return tuple(self._messages)

    def end(self):
        self._over = True
        self._messages.clear()
        self._bytes = 0


class ClientPublisher:
    """One topic that clients publish. The loop writes each message (its bytes from rosbridge.codec.json_to_ros)
    straight to the topic's subscribers (ros_side/links.py: one OutboundLink each). rospy's publisher, made on the
    worker, only registers the topic with the master and lists the connections for getBusInfo.

    A subscriber that reads slowly holds up nobody: its messages wait in its link, at most queue_size of them
    (rospy's meaning: the oldest are dropped; 0 = links.LINK_QUEUE_LIMIT). Like rospy, the publisher numbers
    the messages it sends in their header.seq (1, 2, ...)."""

    def __init__(self, links, topic, cls, latch, queue_size):
        self._links = links
        self.topic, self.cls, self.latch = topic, cls, latch
        self.queue_size = queue_size if 0 < queue_size < sys.maxsize else 0
        self.closed = False  # (loop; set once)
        self._subscribers = []  # OutboundLinks (loop)
        self._seq = 0
        self._latched = None  # the last message of a latched topic (loop)
        # (a latched topic already sends its last message to every new subscriber)
        self._early = None if latch else EarlyReplay(self.queue_size or 100)
        self._publisher = None  # (worker)

    def make(self, graph, type_name):
        """On the worker: check the graph's type, then register the topic (links first: a subscriber may connect
        as soon as rospy's publisher exists)."""
        graph_type = graph.topic_type(self.topic, published=True)
        if graph_type not in (None, type_name):
            raise RequestError(f"advertise {self.topic}: the topic is published as {graph_type}, not {type_name}")
        self._links.publications[self.topic] = self
        try:
            with warnings.catch_warnings():  # rospy warns about queue_size=None: rospy never queues here
                warnings.simplefilter("ignore")
                self._publisher = rospy.Publisher(self.topic, self.cls, latch=self.latch, queue_size=None)
        except Exception:
            self.unregister()
            raise

    def unregister(self):
        """On the worker, once closed: rospy closes the topic's links."""
        if self._links.publications.get(self.topic) is self:
            del self._links.publications[self.topic]
        if self._publisher is not None:
            self._publisher.unregister()

    def put(self, data):
        """On the loop: publishes a message's serialized bytes."""
        if self.latch:
            self._latched = data
        if not self._subscribers:
            if self._early is not None:
                self._early.record(data)
            return
        framed = self._framed(data)
        for link in self._subscribers:
            link.send(framed)

    def attach(self, link):
        """On the loop: a subscriber connected."""
        link.on_closed = self._detach
        self._subscribers.append(link)
        first = (self._latched,) if self._latched is not None else self._early.replay() if self._early else ()
        for data in first:
            link.send(self._framed(data))

    def registered(self):
        """On the loop: the worker has registered the topic with the master."""
        if self._early is not None:
            self._early.registered()

    def _detach(self, link):
        if link in self._subscribers:
            self._subscribers.remove(link)
            if self._early is not None:
                self._early.end()

    def _framed(self, data):
        if not self.cls._has_header:
            return tcpros.frame(data)
        self._seq += 1
        return tcpros.frame(data, self._seq)


class _Entry:
    __slots__ = ("type", "cls", "publisher", "ready", "unregister_timer")

    def __init__(self, type_name, cls, publisher):
        self.type, self.cls, self.publisher = type_name, cls, publisher
        self.ready = False
        self.unregister_timer = None


class Publishers:
    """The topics clients publish. A topic's publisher is made on the worker, and outlives its last client by
    unregister_timeout seconds (MAX_LINGERING of them at most), so that a page reload finds its subscribers still
    connected. A client learns of a failure on the worker through session.ros_refused."""

    def __init__(self, loop, worker, links, unregister_timeout, driving_began=lambda: None):
        """driving_began(): a client began to drive (the dead-man stop watches it from then on)."""
        self._loop, self._worker, self._links, self._unregister_timeout = loop, worker, links, unregister_timeout
        self._driving_began = driving_began
        self._entries = {}
        self._holders = Holders()
        self._inferring = {}  # topic -> [(session, msg, latch, queue_size)] waiting for the graph's type
        self._driven = {}  # session -> the DRIVE_TYPES topics it published on since it last stopped
        self._lingering = collections.OrderedDict()  # topic -> its entry, while it outlives its last client

    def advertise(self, session, topic, type_name, latch, queue_size):
        entry = self._entries.get(topic)
        if entry is None:
            cls = message_class(type_name)
            entry = self._entries[topic] = _Entry(
                type_name, cls, ClientPublisher(self._links, topic, cls, latch, queue_size)
            )
            self._worker.submit(
                lambda: entry.publisher.make(self._worker.graph, type_name),
                lambda error, _: self._made(topic, entry, error),
            )
        elif entry.type != type_name:
            raise RequestError(f"advertise {topic}: the bridge already publishes it as {entry.type}, not {type_name}")
        if entry.unregister_timer is not None:  # a client came back in time (page reload): keep the publisher
            self._loop.remove_timeout(entry.unregister_timer)
            entry.unregister_timer = None
            del self._lingering[topic]
        self._holders.add(topic, session)

    def _made(self, topic, entry, error):
        if error is None:
            entry.ready = True
            entry.publisher.registered()
            if self._entries.get(topic) is not entry:  # dropped while it was being made
                self._drop(entry)
            return
        if self._entries.get(topic) is entry:
            del self._entries[topic]
            if entry.unregister_timer is not None:
                self._loop.remove_timeout(entry.unregister_timer)
                del self._lingering[topic]
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
            self._drove(session, entry, topic)
            return
        waiting = self._inferring.get(topic)
        if waiting is None:  # ask the master for the topic's type, off the loop
            waiting = self._inferring[topic] = []
            self._worker.submit(
                lambda: self._worker.graph.topic_type(topic),
                lambda error, type_name: self._inferred(topic, error, type_name),
            )
        if len(waiting) >= INFERRING_LIMIT:
            raise RequestError(f"publish {topic}: {INFERRING_LIMIT} messages already wait for the topic's type")
        waiting.append((session, msg, latch, queue_size))

    def publish_bytes(self, session, topic, data):
        """A message's ROS bytes from a client that advertised `topic` (the Foxglove protocol's `ros1`)."""
        entry = self._entries.get(topic)
        if entry is None or not self._holders.holds(topic, session):
            raise RequestError(f"publish {topic}: not advertised by this client")
        try:
            check_whole(entry.cls, data)
        except ValueError as error:
            raise RequestError(f"publish {topic}: {error}") from None
        entry.publisher.put(data)
        self._drove(session, entry, topic)

    def _drove(self, session, entry, topic):
        if entry.type in DRIVE_TYPES:
            driven = self._driven.get(session)
            if driven is None:  # (not setdefault: no new set for every message of a topic driven at 1 kHz)
                driven = self._driven[session] = set()
                self._driving_began()
            driven.add(topic)

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

    def drives(self, session):
        return session in self._driven

    def stop_driving(self, session):
        """One zero message (its header stamped now) on each velocity topic the client drove."""
        for topic in self._driven.pop(session, ()):
            entry = self._entries.get(topic)
            if entry is not None:
                entry.publisher.put(packer(entry.cls)({}, now=rospy.Time.now))

    def release(self, session):
        self._driven.pop(session, None)
        for topic in self._holders.names_of(session):
            self._leave(session, topic)

    def _leave(self, session, topic):
        entry = self._entries[topic]
        if self._holders.discard(topic, session) and entry.unregister_timer is None:
            entry.unregister_timer = self._loop.call_later(
                self._unregister_timeout, lambda: self._unregister(topic, entry)
            )
            self._lingering[topic] = entry
            if len(self._lingering) > MAX_LINGERING:
                oldest, its = next(iter(self._lingering.items()))
                self._loop.remove_timeout(its.unregister_timer)
                self._unregister(oldest, its)

    def _unregister(self, topic, entry):
        entry.unregister_timer = None
        del self._lingering[topic]
        if not self._holders.holders(topic) and self._entries.get(topic) is entry:
            del self._entries[topic]
            if entry.ready:
                self._drop(entry)

    def _drop(self, entry):
        entry.publisher.closed = True
        self._worker.submit(lambda: (entry.publisher.unregister(), self._worker.dropped()))
