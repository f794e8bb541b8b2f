"""RosBackend: the protocol's backend (backend.Backend), a short front over publishers, subscribers and
services, plus the bridge's own /client_count and the master look-ups they share."""

import functools

import rospy

from rosbridge.contract import Backend
from rosbridge.message_types import message_class
from rosbridge.ros_side import parameters
from rosbridge.ros_side.assets import read_asset
from rosbridge.ros_side.graph_watch import GraphWatch
from rosbridge.ros_side.links import TopicLinks
from rosbridge.ros_side.publishers import Publishers
from rosbridge.ros_side.services import ProvidedServices, ServiceCalls, call_raw_service
from rosbridge.ros_side.subscribers import Subscribers
from rosbridge.ros_side.worker import RosWorker

MAX_CALLS_RUNNING_PER_CLIENT = 16  # service calls of one client running at once (each on a thread)
MAX_CALLS_RUNNING = 128  # service calls running at once in all
MAX_CALLS_PENDING_PER_CLIENT = 1000  # running or waiting


class RosBackend(Backend):
    def __init__(
        self,
        loop,
        delivery,
        rosapi=None,
        unregister_timeout=10.0,
        service_timeout=60.0,
        stop_drivers_leaving=False,
        driving_began=lambda: None,
    ):
        """delivery: the context that each delivery of topics' messages runs in (write_turns.WriteTurns).
        driving_began(): a client began to drive (Backend.drives became true for it; transport/deadman.py)."""
        self._stop_drivers_leaving = stop_drivers_leaving
        worker = self._worker = RosWorker(loop)
        links = TopicLinks(loop, lambda text: rospy.logwarn_throttle(60, "bridge topics: " + text))
        self._publishers = Publishers(loop, worker, links, unregister_timeout, driving_began)
        self._subscribers = Subscribers(loop, worker, links, delivery)
        self._calls = ServiceCalls(
            loop, rosapi, MAX_CALLS_RUNNING_PER_CLIENT, MAX_CALLS_RUNNING, MAX_CALLS_PENDING_PER_CLIENT
        )
        self._provided = ProvidedServices(loop, worker, service_timeout)
        self._graph = GraphWatch(loop)
        self._client_count = rospy.Publisher("/client_count", message_class("std_msgs/Int32"), latch=True, queue_size=1)

    def set_client_count(self, count):
        self._client_count.publish(message_class("std_msgs/Int32")(count))

    def advertise(self, session, topic, type_name, latch=False, queue_size=100):
        self._publishers.advertise(session, topic, type_name, latch, queue_size)

    def unadvertise(self, session, topic):
        self._publishers.unadvertise(session, topic)

    def publish(self, session, topic, msg, latch=False, queue_size=100):
        self._publishers.publish(session, topic, msg, latch, queue_size)

    def subscribe(self, session, topic, type_name=None):
        self._subscribers.subscribe(session, topic, type_name)

    def unsubscribe(self, session, topic):
        self._subscribers.unsubscribe(session, topic)

    def latched_messages(self, topic):
        return self._subscribers.latched_messages(topic)

    def resolve_name(self, name):
        """As the reference (rospy.resolve_name): roslib 2.x calls rosapi by relative names ("rosapi/topics")."""
        return rospy.resolve_name(name)

    def call_service(self, session, service, args, type_name, timeout, reply):
        self._calls.call(session, self.resolve_name(service), args, type_name, timeout, reply)

    def advertise_service(self, session, service, type_name):
        self._provided.advertise(session, self.resolve_name(service), service, type_name)

    def unadvertise_service(self, session, service):
        self._provided.unadvertise(session, self.resolve_name(service))

    def service_response(self, session, service, call_id, result, values):
        self._provided.respond(session, self.resolve_name(service), call_id, result, values)

    def publish_bytes(self, session, topic, data):
        self._publishers.publish_bytes(session, topic, data)

    def call_service_bytes(self, session, service, type_name, data, timeout, reply):
        service = self.resolve_name(service)
        work = functools.partial(call_raw_service, service, type_name, data)
        text = f"Service {service} timed out after {timeout} s"
        self._calls.run(session, f"call_service {service}", work, reply, timeout, text, through_proxy=True)

    def get_parameters(self, session, names, reply):
        self._calls.run(session, "getParameters", functools.partial(parameters.get_parameters, names), reply)

    def set_parameters(self, session, values, reply):
        self._calls.run(session, "setParameters", functools.partial(parameters.set_parameters, values), reply)

    def fetch_asset(self, session, uri, reply):
        self._calls.run(session, "fetchAsset", functools.partial(read_asset, uri), reply)

    def watch_graph(self, listener):
        self._graph.watch(listener)

    def unwatch_graph(self, listener):
        self._graph.unwatch(listener)

    def after_pending(self, session, then):
        # (the worker runs every client's jobs in one order: waiting for all submitted so far is exact)
        return self._worker.after_submitted(then)

    def drives(self, session):
        return self._publishers.drives(session)

    def stop_driving(self, session):
        self._publishers.stop_driving(session)

    def release(self, session):
        if self._stop_drivers_leaving:
            self._publishers.stop_driving(session)
        self._publishers.release(session)
        self._subscribers.release(session)
        self._calls.release(session)
        self._provided.release(session)
