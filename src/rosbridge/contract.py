"""The contracts of a protocol session (one per client: protocol.Session for rosbridge), both ways:
- with the ROS side (ros_side.RosBackend): Backend is what a session may ask of it, Client what it may call on a
  session;
- with its connection (transport/connection.ClientConnection): SessionHost is what a session may ask of it,
  ProtocolSession what it calls on a session.
A second protocol beside rosbridge implements ProtocolSession and Client, and gets the same SessionHost and Backend.

Every method of them runs on the event-loop thread. A Backend method that refuses raises a ClientError whose
text goes back to the client; any other exception is a bug. Work that can block (the master, making rospy
objects) is done off the loop: a refusal found out there comes later, through `Client.ros_refused`."""

import abc
import dataclasses
import typing
from collections.abc import Callable, Sequence

from rosbridge.globs import allowed

DELETE = object()  # the value of a parameter to unset (Backend.set_parameters), or one that is gone

DRIVE_TYPES = frozenset(("geometry_msgs/Twist", "geometry_msgs/TwistStamped"))  # velocity commands: a robot
# goes on with the last one it got, so a driver that goes away is stopped (Backend.stop_driving)


class Read(typing.Protocol):
    """What one read of a topic's publisher brought (protocol/encoded.TopicRead): one message or more, never
    none."""

    topic: str
    datas: list  # the messages' bytes, in order, as TCPROS carried them
    stamp: float  # when they were received (seconds, wall clock)

    @property
    def messages(self) -> list:
        """Their protocol/encoded.TopicMessages, made once for all clients."""


class Client(typing.Protocol):
    """What the ROS side may call on a client (protocol.Session), on the loop only: other threads hand their
    results to the loop first (IOLoop.add_callback; ros_side/__init__.py says who does)."""

    is_closed: bool  # the client left: nothing more is sent to it

    def deliver(self, read: "Read") -> None:
        """Messages of a topic the client subscribes to: those one read of a publisher brought, or one that a
        publisher latches."""

    def ros_refused(self, op: str, name: str, text: str) -> None:
        """The ROS side could not do what an earlier `op` on `name` asked (found out off the loop)."""

    def request_service(self, call_id: str, service: str, args: dict) -> None:
        """A ROS call of a service the client provides, to be answered with service_response."""

    def status(self, level: str, msg: str, request_id=None) -> None:
        """A status message for the client (shown at its status level)."""


class Bound(typing.Protocol):
    """Bytes that many holders share, at most `limit` together (transport/rfc6455.SharedBound). A holder that
    must make way for another is told by its evict()."""

    limit: int

    def hold(self, holder, count: int) -> bool:
        """`holder` now holds `count` bytes (0: nothing); False if refused (it then holds what it held)."""


class SessionHost(typing.Protocol):
    """What a protocol session may ask of its connection (transport/connection.ClientConnection). Protocol-neutral:
    a session never writes; it queues frames, wakes its host, and the host takes them (ProtocolSession.take_frames)
    when the client's socket can take them."""

    unfinished: Bound | None  # what the unfinished messages of all clients hold together (a session's fragments too)

    def clock(self) -> float:
        """Seconds since the epoch."""

    def call_later(self, delay: float, fn: Callable[[], None]) -> object:
        """Runs fn() on the loop `delay` seconds from now; returns a handle for cancel_later."""

    def cancel_later(self, handle: object) -> None:
        """The timer of `handle` (from call_later) does not run after all (nothing, if it has run)."""

    def wake(self) -> None:
        """Frames are queued: the host takes them (ProtocolSession.take_frames) until there are none."""

    def may_write_now(self) -> bool:
        """Whether write_now may be called, in this turn of the loop: nothing of the client's waits to be written,
        and frames go as they are (not deflated, not paced)."""

    def write_now(self, frames: Sequence[object], size: int) -> None:
        """Writes the frames (as take_frames gives them; `size` bytes in all) to the client at once, as if they had
        been queued and taken; only when may_write_now() said so. The session holds their shared buffers in its
        pool (protocol/outbox.Outbox.take_at_once): the host tells it when they have left (backed_up(False)), as
        for frames it took."""

    def close_after_sending(self, reason: str) -> None:
        """Closes the connection once the frames queued so far are sent; `reason` goes in the close frame."""

    def resume_reading(self) -> None:
        """The session no longer holds the client's requests (ProtocolSession.holding): read the client again."""

    def off_loop(self, fn: Callable[[], typing.Any], then: Callable[[typing.Any], None]) -> None:
        """Runs fn() on another thread (the bridge's encoder), then then(its result) on the loop; the result is
        None if fn raised (logged)."""


class ProtocolSession(typing.Protocol):
    """What the connection (transport/connection.ClientConnection) calls on the protocol session of its client,
    which it chose at the handshake. The session is also the ROS side's Client, and gets a SessionHost."""

    @property
    def authenticated(self) -> bool:
        """Whether the client may do more than authenticate (True unless the authenticate setting is on):
        max_clients makes room by closing the client that has waited longest without."""

    @property
    def holding(self) -> bool:
        """Whether the session holds the client's next requests (behind ROS work under way): the connection
        reads nothing more meanwhile, until SessionHost.resume_reading."""

    def handle_text(self, text: str) -> None:
        """A whole text message from the client."""

    def handle_binary(self, data: bytes) -> None:
        """A whole binary message from the client."""

    def take_frames(self, most_bytes: int) -> list:
        """The next frames to write, in order (str or protocol/encoded.Utf8Text: text; bytes: binary; SplicedFrame:
        either): at least one, and more while they come to less than most_bytes; none ([]) when none is queued
        (the next one queued wakes the host again)."""

    def backed_up(self, flag: bool, in_flight: int = 0) -> None:
        """Whether the client's socket has stopped taking frames, and how many bytes taken from the session have
        not left yet (the session then keeps each topic fresh, and within its bounds)."""

    def closed(self) -> None:
        """The connection is gone: the session releases everything it held (on the ROS side too)."""


@dataclasses.dataclass(frozen=True)
class GraphState:
    """The ROS graph as the master told it (Backend.watch_graph). Names map to frozensets of node names."""

    topics: dict  # topic -> (type, its full definition as TCPROS sends it, or None: the type is not installed here)
    publishers: dict  # topic -> nodes
    subscribers: dict  # topic -> nodes
    services: dict  # service -> (type, request definition, response definition); ("", None, None): not known
    providers: dict  # service -> nodes

    def filtered(self, globs):
        """The same without the topics and services that the bridge's globs hide."""

        def keep(names, patterns):
            return {name: value for name, value in names.items() if allowed(name, patterns)}

        return GraphState(
            keep(self.topics, globs.topics),
            keep(self.publishers, globs.topics),
            keep(self.subscribers, globs.topics),
            keep(self.services, globs.services),
            keep(self.providers, globs.services),
        )

    def nodes_differ(self, other):
        return (self.publishers, self.subscribers, self.providers) != (
            other.publishers,
            other.subscribers,
            other.providers,
        )


class Backend(abc.ABC):
    @abc.abstractmethod
    def advertise(self, session, topic, type_name, latch, queue_size):
        """The client will publish `topic` as `type_name`."""

    @abc.abstractmethod
    def unadvertise(self, session, topic):
        """The client no longer publishes `topic`."""

    @abc.abstractmethod
    def publish(self, session, topic, msg, latch, queue_size):
        """One message (JSON-parsed dict) from the client; advertises `topic` first if needed."""

    @abc.abstractmethod
    def subscribe(self, session, topic, type_name):
        """The client wants `topic`'s messages (type_name None: the graph's type)."""

    @abc.abstractmethod
    def unsubscribe(self, session, topic):
        """The client no longer wants `topic`."""

    @abc.abstractmethod
    def latched_messages(self, topic):
        """The messages of `topic` that its publishers still latch: what a new subscriber would be given first
        (a client subscribed already may hold them)."""

    @abc.abstractmethod
    def call_service(self, session, service, args, type_name, timeout, reply):
        """Calls a ROS service (or rosapi) with JSON args; reply(ok, values) later, on the loop, exactly once.
        timeout: seconds or None."""

    @abc.abstractmethod
    def advertise_service(self, session, service, type_name):
        """The client provides `service`: ROS calls of it go to session.request_service."""

    @abc.abstractmethod
    def unadvertise_service(self, session, service):
        """The client no longer provides `service`."""

    @abc.abstractmethod
    def service_response(self, session, service, call_id, result, values):
        """The client's answer to a call forwarded with request_service."""

    @abc.abstractmethod
    def resolve_name(self, name):
        """A client's (maybe relative) service name as ROS resolves it in the bridge's namespace. The service
        methods take the client's spelling and resolve it themselves."""

    @abc.abstractmethod
    def after_pending(self, session, then):
        """Whether ROS work that the client's requests so far started (off the loop) is still under way: if so,
        then() runs on the loop once it is done, and True is returned; else False (then is not called). The
        protocol holds the client's next requests meanwhile, so that they take effect in the order sent."""

    @abc.abstractmethod
    def drives(self, session):
        """Whether the client has published on a topic that moves a robot (DRIVE_TYPES) since it last stopped."""

    @abc.abstractmethod
    def stop_driving(self, session):
        """Publishes one zero message on each DRIVE_TYPES topic the client has driven (the dead-man stop)."""

    @abc.abstractmethod
    def release(self, session):
        """The client left: release everything it held."""

    # ---- what the Foxglove protocol asks besides ------------------------------------------------
    @abc.abstractmethod
    def publish_bytes(self, session, topic, data):
        """One message as its ROS bytes, on a topic the client advertised; RequestError if they are not one
        whole message of the topic's type."""

    @abc.abstractmethod
    def call_service_bytes(self, session, service, type_name, data, timeout, reply):
        """Calls a ROS service with a request's ROS bytes; reply(ok, the response's bytes or the failure's text)
        later, on the loop, exactly once (timeout: seconds, or None)."""

    @abc.abstractmethod
    def get_parameters(self, session, names, reply):
        """reply(ok, {name: value} or the failure's text) later, on the loop: these parameters (names None:
        every one, by leaf name)."""

    @abc.abstractmethod
    def set_parameters(self, session, values, reply):
        """Sets {name: value, or DELETE to unset}; reply(ok, {name: value} set, or the failure's text) later."""

    @abc.abstractmethod
    def fetch_asset(self, session, uri, reply):
        """reply(ok, the bytes of the file a package:// URI names, or the refusal's text) later, on the loop."""

    @abc.abstractmethod
    def watch_graph(self, listener):
        """listener(GraphState) on the loop, soon and then whenever the graph changes, until unwatch_graph."""

    @abc.abstractmethod
    def unwatch_graph(self, listener):
        """Stops telling listener."""
