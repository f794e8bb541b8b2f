"""The contract between the protocol (one Session per client) and the ROS side (ros_side.RosBackend), both
ways: Backend is what the protocol may ask of the ROS side, Client what the ROS side may call on a client.

Every method of both runs on the event-loop thread. A Backend method that refuses raises a ClientError whose
text goes back to the client; any other exception is a bug. Work that can block (the master, making rospy
objects) is done off the loop: a refusal found out there comes later, through `Client.ros_refused`."""

import abc
import typing

DRIVE_TYPES = frozenset(("geometry_msgs/Twist", "geometry_msgs/TwistStamped"))  # velocity commands: a robot
# goes on with the last one it got, so a driver that goes away is stopped (Backend.stop_driving)


class Client(typing.Protocol):
    """What the ROS side may call on a client (protocol.Session), on the loop only: other threads hand their
    results to the loop first (IOLoop.add_callback; ros_side/__init__.py says who does)."""

    is_closed: bool  # the client left: nothing more is sent to it

    def deliver(self, message) -> None:
        """A protocol/encoded.TopicMessage of a topic the client subscribes to."""

    def ros_refused(self, op: str, name: str, text: str) -> None:
        """The ROS side could not do what an earlier `op` on `name` asked (found out off the loop)."""

    def request_service(self, call_id: str, service: str, args: dict) -> None:
        """A ROS call of a service the client provides, to be answered with service_response."""

    def status(self, level: str, msg: str, request_id=None) -> None:
        """A status message for the client (shown at its status level)."""


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
