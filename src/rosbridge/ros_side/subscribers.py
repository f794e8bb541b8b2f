"""ROS -> client: the topics clients subscribe to, one rospy subscriber per topic shared by its clients."""
import collections
import time

import rospy

from rosbridge.errors import RequestError, log_bug, refusal_text
from rosbridge.frames import TopicMessage
from rosbridge.ros_side.holders import Holders
from rosbridge.types import message_class
from rosbridge.wire import raw_class

INBOX_LIMIT = 10_000  # messages per topic waiting for the loop; beyond that the oldest are dropped


class TopicSubscriber:
    """One topic's rospy subscriber. Made and dropped on the worker; messages arrive on rospy's threads, wait in
    the inbox and are handed to the topic's clients on the loop (see the package's thread rules)."""
    __slots__ = ("topic", "type", "asked", "ready", "inbox", "wake_pending", "latched", "_loop", "_clients",
                 "_subscriber", "_class")

    def __init__(self, loop, topic, clients):
        self._loop, self.topic, self._clients = loop, topic, clients
        self.type = None  # known once made (loop)
        self.asked = {}  # session -> the type it asked for, checked once the type is known (loop)
        self.ready = False  # (loop)
        self.inbox = collections.deque(maxlen=INBOX_LIMIT)
        self.wake_pending = False
        self.latched = None  # the last message of a latched topic, for clients that subscribe later (loop)
        self._subscriber = None  # (worker)
        self._class = None  # the messages' genpy class: set on the worker before the rospy subscriber exists

    def make(self, graph, asked_type):
        """On the worker: the topic's type (asked_type, or the graph's), and its rospy subscriber."""
        if asked_type is None:
            asked_type = graph.topic_type(self.topic)
            if asked_type is None:
                raise RequestError(f"subscribe {self.topic}: cannot infer the topic's type (nobody publishes it "
                                   "yet); give 'type'")
        else:
            published_type = graph.topic_type(self.topic, published=True)
            if published_type not in (None, asked_type):
                raise RequestError(f"subscribe {self.topic}: the topic is published as {published_type}, "
                                   f"not {asked_type}")
        self._class = message_class(asked_type)
        # (the bytes as they came: the loop writes JSON straight from them, see rosbridge.wire)
        self._subscriber = rospy.Subscriber(self.topic, raw_class(self._class), self._on_message)
        return asked_type

    def unregister(self):
        """On the worker."""
        if self._subscriber is not None:
            self._subscriber.unregister()
        self.inbox.clear()

    def _on_message(self, msg):
        """On a rospy thread: hand the message to the loop, waking it once per batch."""
        self.inbox.append((msg, time.time()))
        if not self.wake_pending:
            self.wake_pending = True
            self._loop.add_callback(self._drain)

    def _drain(self):
        self.wake_pending = False
        inbox, topic = self.inbox, self.topic
        for _ in range(len(inbox)):  # what is there now: a busy topic must not hold the loop (it wakes again)
            msg, stamp = inbox.popleft()
            message = TopicMessage(topic, self._class, msg._buff, stamp)
            header = getattr(msg, "_connection_header", None)
            if header is not None and header.get("latching") == "1":
                self.latched = message
            for session in self._clients(topic):
                try:
                    session.deliver(message)
                except Exception:  # one client's failure must not starve the others
                    log_bug(f"delivering {topic}")


class Subscribers:
    """The topics clients subscribe to. A new topic's subscriber is made on the worker; a client learns of a
    failure there through session.ros_refused."""

    def __init__(self, loop, worker):
        self._loop, self._worker = loop, worker
        self._entries = {}
        self._holders = Holders()

    def subscribe(self, session, topic, type_name):
        if type_name is not None:
            message_class(type_name)  # an unknown type is refused at once
        entry = self._entries.get(topic)
        if entry is None:
            entry = self._entries[topic] = TopicSubscriber(self._loop, topic, self._holders.holders)
            self._worker.submit(lambda: entry.make(self._worker.graph, type_name),
                                lambda error, made_type: self._made(entry, error, made_type))
        elif entry.ready and type_name not in (None, entry.type):
            raise RequestError(f"subscribe {topic}: the topic has type {entry.type}, not {type_name}")
        if self._holders.holds(topic, session):
            return
        self._holders.add(topic, session)
        entry.asked[session] = type_name
        if entry.latched is not None:
            latched = entry.latched
            self._loop.add_callback(lambda: session.deliver(latched))

    def _made(self, entry, error, made_type):
        topic = entry.topic
        if self._entries.get(topic) is not entry:  # everyone left meanwhile
            if error is None:
                self._worker.submit(self._unregister(entry))
            return
        if error is not None:
            del self._entries[topic]
            for session in self._holders.holders(topic):
                self._holders.discard(topic, session)
                self._refuse(session, topic, error)
            return
        entry.type, entry.ready = made_type, True
        for session, asked in entry.asked.items():
            if asked not in (None, made_type) and self._holders.holds(topic, session):
                self._refuse(session, topic, RequestError(f"subscribe {topic}: the topic has type {made_type}, "
                                                          f"not {asked}"))
                self.unsubscribe(session, topic)
        entry.asked.clear()

    @staticmethod
    def _refuse(session, topic, error):
        session.ros_refused("subscribe", topic, refusal_text(error, f"subscribing {topic}"))

    def unsubscribe(self, session, topic):
        entry = self._entries.get(topic)
        if entry is not None:
            entry.asked.pop(session, None)
        if self._holders.discard(topic, session):
            del self._entries[topic]
            if entry.ready:
                self._worker.submit(self._unregister(entry))

    def release(self, session):
        for topic in self._holders.names_of(session):
            self.unsubscribe(session, topic)

    def _unregister(self, entry):
        """A worker job dropping the topic's rospy subscriber."""
        def job():
            entry.unregister()
            self._worker.dropped()
        return job
