"""The ROS graph for Foxglove clients (contract.Backend.watch_graph): topics with their types and full
definitions, services with theirs, and who publishes, subscribes and provides what. Polled from the master every
GRAPH_POLL seconds on a thread of its own while anyone watches (a slow master, or a service provider that does not
answer its probe, holds only this thread); each new state goes to the watchers on the loop."""

import concurrent.futures
import threading

import rosgraph
import rospy

from rosbridge.contract import GraphState
from rosbridge.errors import ClientError, log_bug
from rosbridge.message_types import message_class, service_class
from rosbridge.ros_side.master_proxy import MasterError, api_proxy, succeeded
from rosbridge.ros_side.rosapi import PROBE_THREADS, probe_service_type

GRAPH_POLL = 0.5  # s: channels appear and go within a second
MAX_TYPES_KNOWN = 4096  # service types remembered by (service, providers), found or not


class GraphWatch:
    def __init__(self, loop):
        self._loop = loop
        self._watchers = []  # (loop only)
        self._wake = threading.Event()
        self._running = False  # the thread is polling (set on the loop; the thread clears it under the lock)
        self._lock = threading.Lock()
        self._wanted = False
        self._newcomer = False  # a watcher came since the last poll: it gets the state even if unchanged
        self._service_types = {}  # (service, providers) -> type (the thread's, as are:)
        self._last_system, self._last_state = None, None  # the master's last getSystemState, and what it gave
        self._master = None

    def watch(self, listener):
        self._watchers.append(listener)
        with self._lock:
            self._wanted = self._newcomer = True
            start = not self._running
            self._running = True
        self._wake.set()
        if start:
            threading.Thread(target=self._poll_while_wanted, name="rosbridge-graph", daemon=True).start()

    def unwatch(self, listener):
        if listener in self._watchers:
            self._watchers.remove(listener)
        if not self._watchers:
            with self._lock:
                self._wanted = False

    def _poll_while_wanted(self):
        last = None
        while True:
            with self._lock:
                if not self._wanted:
                    self._running = False
                    return
                newcomer, self._newcomer = self._newcomer, False
            try:
                state = self._poll()
            except Exception as error:  # (the master away: tried again next time)
                if not isinstance(error, OSError):
                    log_bug("polling the ROS graph", error)
                state = None
                self._newcomer = self._newcomer or newcomer
            if state is not None and (state is not last or newcomer):
                last = state
                self._loop.add_callback(self._tell, state)
            self._wake.wait(GRAPH_POLL)
            self._wake.clear()

    @staticmethod
    def _probe(name, nodes):
        """On a probe thread: a service's type, "" if its provider does not say (kept as such until its providers
        change: a provider that does not answer is not asked again at every poll). A master proxy of its own:
        one XML-RPC connection cannot carry two calls at once."""
        try:
            uri = succeeded(api_proxy(rosgraph.get_master_uri()).lookupService(rospy.get_name(), name)) if nodes else ""
        except (MasterError, OSError):  # (gone since the master listed it)
            return ""
        return probe_service_type(name, uri) if uri else ""

    def _tell(self, state):
        for listener in list(self._watchers):
            try:
                listener(state)
            except Exception:
                log_bug("telling a watcher of the ROS graph")

    def _poll(self):
        """The graph now: one call to the master while nothing changed (the same state is returned), the types
        and definitions only when who publishes, subscribes or provides what has changed. (A poll is most of what
        an idle Foxglove client costs the bridge: twice a second.)"""
        if self._master is None:  # (kept: its connection to the master too, instead of a new one at every poll)
            self._master = api_proxy(rosgraph.get_master_uri())
        master, me = self._master, rospy.get_name()
        try:
            system = succeeded(master.getSystemState(me))
        except Exception:
            self._master = None  # (the master restarted, or the connection broke: a new one next time)
            raise
        if system == self._last_system and self._last_state is not None:
            return self._last_state
        self._last_system, self._last_state = system, None
        self._last_state = self._state(dict(succeeded(master.getTopicTypes(me))), *system)
        return self._last_state

    def _state(self, types, publications, subscriptions, services):
        publishers = {topic: frozenset(nodes) for topic, nodes in publications}
        subscribers = {topic: frozenset(nodes) for topic, nodes in subscriptions}
        topics = {}
        for topic in set(publishers) | set(subscribers):
            type_name = types.get(topic)
            if type_name and type_name != "*":
                topics[topic] = (type_name, _definition(type_name))
        providers = {name: frozenset(nodes) for name, nodes in services}
        unknown = [(name, nodes) for name, nodes in providers.items() if (name, nodes) not in self._service_types]
        if unknown:  # (asked at once: a provider that never answers costs PROBE_TIMEOUT once, not once each)
            with concurrent.futures.ThreadPoolExecutor(min(PROBE_THREADS, len(unknown))) as pool:
                found = list(pool.map(lambda key: self._probe(*key), unknown))
            if len(self._service_types) + len(unknown) > MAX_TYPES_KNOWN:
                self._service_types.clear()
            self._service_types.update(zip(unknown, found))
        service_types = {}
        for name, nodes in providers.items():
            type_name = self._service_types[(name, nodes)]
            service_types[name] = (type_name, *_service_definitions(type_name))
        return GraphState(topics, publishers, subscribers, service_types, providers)


def _definition(type_name):
    """A message type's full definition, its dependencies' included (what TCPROS sends as message_definition),
    or None when the type is not installed here."""
    try:
        return message_class(type_name)._full_text
    except ClientError:
        return None


def _service_definitions(type_name):
    if not type_name:
        return None, None
    try:
        cls = service_class(type_name)
    except ClientError:
        return None, None
    return cls._request_class._full_text, cls._response_class._full_text
