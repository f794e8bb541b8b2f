"""ROS -> client: the topics clients subscribe to, one rospy subscriber per topic shared by its clients."""
import collections
import time

import rospy

from rosbridge.errors import RequestError
from rosbridge.frames import TopicMessage
from rosbridge.protocol import log_bug
from rosbridge.ros_side.holders import Holders
from rosbridge.types import message_class

INBOX_LIMIT = 10_000  # messages per topic waiting for the loop; beyond that the oldest are dropped


class TopicSubscriber:
    """One topic's rospy subscriber. Messages arrive on rospy's threads, wait in the inbox and are handed to
    the topic's clients on the loop (see the package's thread rules)."""
    __slots__ = ("topic", "type", "inbox", "wake_pending", "latched", "_loop", "_clients", "_subscriber")

    def __init__(self, loop, topic, type_name, clients):
        self._loop, self.topic, self.type, self._clients = loop, topic, type_name, clients
        self.inbox = collections.deque(maxlen=INBOX_LIMIT)
        self.wake_pending = False
        self.latched = None  # the last message of a latched topic, for clients that subscribe later
        self._subscriber = rospy.Subscriber(topic, message_class(type_name), self._on_message)

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
            message = TopicMessage(topic, msg, stamp)
            header = getattr(msg, "_connection_header", None)
            if header is not None and header.get("latching") == "1":
                self.latched = message
            for session in self._clients(topic):
                try:
                    session.deliver(message)
                except Exception:  # one client's failure must not starve the others
                    log_bug(f"delivering {topic}")

    def unregister(self):
        self._subscriber.unregister()
        self.inbox.clear()


class Subscribers:
    def __init__(self, loop, graph_type):
        self._loop, self._graph_type = loop, graph_type
        self._entries = {}
        self._holders = Holders()

    def subscribe(self, session, topic, type_name):
        entry = self._entries.get(topic)
        if entry is None:
            graph_type = self._graph_type(topic)
            if type_name is None:
                type_name = graph_type
                if type_name is None:
                    raise RequestError(f"subscribe {topic}: cannot infer the topic's type (nobody publishes it "
                                       "yet); give 'type'")
            elif graph_type not in (None, type_name):
                raise RequestError(f"subscribe {topic}: the topic has type {graph_type}, not {type_name}")
            message_class(type_name)  # refuses an unknown type before anything is made
            entry = self._entries[topic] = TopicSubscriber(self._loop, topic, type_name, self._holders.holders)
        elif type_name not in (None, entry.type):
            raise RequestError(f"subscribe {topic}: the topic has type {entry.type}, not {type_name}")
        if not self._holders.holds(topic, session):
            self._holders.add(topic, session)
            if entry.latched is not None:
                latched = entry.latched
                self._loop.add_callback(lambda: session.deliver(latched))

    def unsubscribe(self, session, topic):
        if self._holders.discard(topic, session):
            self._entries.pop(topic).unregister()

    def release(self, session):
        for topic in self._holders.names_of(session):
            self.unsubscribe(session, topic)
