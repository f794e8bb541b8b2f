"""ROS -> client: the topics clients subscribe to, one rospy subscriber per topic shared by its clients."""

import time

import rospy

from rosbridge.errors import RequestError, log_bug, refusal_text
from rosbridge.message_types import message_class
from rosbridge.protocol.encoded import TopicRead
from rosbridge.ros_side.holders import Holders

# messages delivered before the clients write them: one read may bring thousands of small ones (after the loop was
# held up), and a client's outbox keeps max_queue (1000 by default) at most, however fast the client reads
DELIVERY_BATCH = 100


class TopicSubscriber:
    """One topic that clients subscribe to. Its messages are read on the loop (ros_side/links.py: one
    InboundLink per publisher) and handed to the topic's clients there. rospy's subscriber, made and dropped on
    the worker, only registers the topic with the master (which then tells rospy of the publishers, and rospy
    asks the links to connect) and lists the connections for getBusInfo."""

    __slots__ = (
        "topic",
        "type",
        "asked",
        "ready",
        "latched",
        "active",
        "_loop",
        "_links",
        "_clients",
        "_delivery",
        "_subscriber",
        "_class",
    )

    def __init__(self, loop, links, topic, clients, delivery):
        self._loop, self._links, self.topic = loop, links, topic
        self._clients = clients  # topic -> its clients (Holders.by_name: a tuple, which no delivery copies)
        self._delivery = delivery  # (the clients write once each DELIVERY_BATCH of a read is delivered)
        self.type = None  # known once made (loop)
        self.asked = {}  # session -> the type it asked for, checked once the type is known (loop)
        self.ready = False  # (loop)
        self.active = True  # False once every client left: messages still read are dropped (loop)
        # link -> the last message of each latching publisher, for clients that subscribe later (loop): as in ROS,
        # each publisher latches its own (two static TF broadcasters on /tf_static), and a message goes with
        # its publisher (its link done: rospy would not give it to a new subscriber either)
        self.latched = {}
        self._subscriber = None  # (worker)
        self._class = None  # the messages' genpy class: set on the worker before the links may use it

    def make(self, graph, asked_type):
        """On the worker: the topic's type (asked_type, or the graph's), and its rospy subscriber."""
        if asked_type is None:
            asked_type = graph.topic_type(self.topic)
            if asked_type is None:
                raise RequestError(
                    f"subscribe {self.topic}: cannot infer the topic's type (nobody publishes it yet); give 'type'"
                )
        else:
            published_type = graph.topic_type(self.topic, published=True)
            if published_type not in (None, asked_type):
                raise RequestError(
                    f"subscribe {self.topic}: the topic is published as {published_type}, not {asked_type}"
                )
        self._class = message_class(asked_type)
        self._links.subscriptions[self.topic] = (self._class, self._deliver)
        try:
            self._subscriber = rospy.Subscriber(self.topic, self._class)
        except Exception:
            self.unregister()
            raise
        return asked_type

    def unregister(self):
        """On the worker: rospy closes the topic's links."""
        if self._links.subscriptions.get(self.topic, (None, None))[1] == self._deliver:
            del self._links.subscriptions[self.topic]
        if self._subscriber is not None:
            self._subscriber.unregister()

    def latched_reads(self):
        """The latched message of each publisher still linked, as a TopicRead of its own (loop)."""
        for link in [link for link in self.latched if link.done]:
            del self.latched[link]
        return list(self.latched.values())

    def _deliver(self, messages, latched_by):
        """On the loop: messages (their bytes) read from one publisher: its link if it latches, else None."""
        if len(messages) > DELIVERY_BATCH:
            for start in range(0, len(messages), DELIVERY_BATCH):
                self._deliver(messages[start : start + DELIVERY_BATCH], latched_by)
            return
        if not self.active:  # (every client may leave as one batch is written)
            return
        topic = self.topic
        read = TopicRead(topic, self._class, messages, time.time())
        if latched_by is not None:
            if latched_by not in self.latched:  # a new publisher: forget those gone
                self.latched_reads()
            self.latched[latched_by] = read.last()
        with self._delivery:
            for session in self._clients.get(topic, ()):
                try:
                    session.deliver(read)
                except Exception:  # one client's failure must not starve the others
                    log_bug(f"delivering {topic}")


class Subscribers:
    """The topics clients subscribe to. A new topic's subscriber is made on the worker; a client learns of a
    failure there through session.ros_refused."""

    def __init__(self, loop, worker, links, delivery):
        self._loop, self._worker, self._links, self._delivery = loop, worker, links, delivery
        self._entries = {}
        self._holders = Holders()

    def subscribe(self, session, topic, type_name):
        if type_name is not None:
            message_class(type_name)  # an unknown type is refused at once
        entry = self._entries.get(topic)
        if entry is None:
            entry = self._entries[topic] = TopicSubscriber(
                self._loop, self._links, topic, self._holders.by_name, self._delivery
            )
            self._worker.submit(
                lambda: entry.make(self._worker.graph, type_name),
                lambda error, made_type: self._made(entry, error, made_type),
            )
        elif entry.ready and type_name not in (None, entry.type):
            raise RequestError(f"subscribe {topic}: the topic has type {entry.type}, not {type_name}")
        if self._holders.holds(topic, session):
            return
        self._holders.add(topic, session)
        entry.asked[session] = type_name
        for read in entry.latched_reads():
            self._loop.add_callback(session.deliver, read)

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
                self._refuse(
                    session, topic, RequestError(f"subscribe {topic}: the topic has type {made_type}, not {asked}")
                )
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
            entry.active = False
            if entry.ready:
                self._worker.submit(self._unregister(entry))

    def latched_messages(self, topic):
        entry = self._entries.get(topic)
        return [read.messages[0] for read in entry.latched_reads()] if entry is not None else []

    def release(self, session):
        for topic in self._holders.names_of(session):
            self.unsubscribe(session, topic)

    def _unregister(self, entry):
        """A worker job dropping the topic's rospy subscriber."""

        def job():
            entry.unregister()
            self._worker.dropped()

        return job
