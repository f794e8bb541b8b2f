"""What every Foxglove client of the bridge is told about, kept once for all of them: the channels (one per topic
in the graph, subscribed-only topics too), the services, the connection graph and the watched parameters.

The ROS side polls the master while a Foxglove client is connected (contract.Backend.watch_graph) and hands each
new contract.GraphState to `graph_changed`, on the loop; the catalog turns it into advertisements and graph
updates for each session. Parameters are polled here (Backend.get_parameters) while a client subscribes to them.
Pure: no rospy, no tornado; the loop's call_later and cancel_later are given."""

import itertools
import time

from rosbridge.codec.json_values import dumps
from rosbridge.contract import DELETE
from rosbridge.foxglove.parameters import ALL
from rosbridge.foxglove.sim_clock import SimClock
from rosbridge.globs import allowed

PARAMETER_POLL = 1.0  # s: how often the master's parameters are read while a client subscribes to updates...
# ...but a poll waits at least this many times as long as the last one took: what the polls cost the bridge and
# the master stays a small share, however many parameters there are (28 MB of them took 8% of a core at 1 s)
POLL_SPACING = 10


def channel_entry(channel_id, topic, type_name, schema):
    return {
        "id": channel_id,
        "topic": topic,
        "encoding": "ros1",
        "schemaName": type_name,
        "schema": schema,
        "schemaEncoding": "ros1msg",
    }


def service_entry(service_id, name, type_name, request_schema, response_schema):
    def half(suffix, schema):
        return {"encoding": "ros1", "schemaName": type_name + suffix, "schemaEncoding": "ros1msg", "schema": schema}

    return {
        "id": service_id,
        "name": name,
        "type": type_name,
        "request": half("_Request", request_schema),
        "response": half("_Response", response_schema),
    }


def graph_update(old, new):
    """The connectionGraphUpdate that takes a client from `old` (a GraphState, or None: nothing) to `new`."""

    def changed(before, after, key):
        return [
            {"name": name, key: sorted(nodes)} for name, nodes in sorted(after.items()) if before.get(name) != nodes
        ]

    empty = {}
    old_pubs, old_subs, old_providers = (old.publishers, old.subscribers, old.providers) if old else (empty,) * 3
    old_topics = set(old_pubs) | set(old_subs)
    new_topics = set(new.publishers) | set(new.subscribers)
    return {
        "op": "connectionGraphUpdate",
        "publishedTopics": changed(old_pubs, new.publishers, "publisherIds"),
        "subscribedTopics": changed(old_subs, new.subscribers, "subscriberIds"),
        "advertisedServices": changed(old_providers, new.providers, "providerIds"),
        "removedTopics": sorted(old_topics - new_topics),
        "removedServices": sorted(set(old_providers) - set(new.providers)),
    }


class Catalog:
    def __init__(self, backend, globs, call_later, cancel_later, sim_now_ns=None):
        """sim_now_ns: the ROS time in ns, with /use_sim_time (else None: the `time` capability is off)."""
        self._backend, self._globs = backend, globs
        self._call_later, self._cancel_later = call_later, cancel_later
        self.sessions = set()
        self.sim_clock = None if sim_now_ns is None else SimClock(sim_now_ns, call_later, cancel_later, self.sessions)
        self.graph = None  # the latest GraphState (globs applied), None before the first poll
        self.channels = {}  # id -> channel entry
        self._channel_ids = {}  # (topic, type, schema) -> id: a channel keeps its id while it lasts
        self.services = {}  # id -> service entry
        self._service_ids = {}  # (name, type) -> id
        self._ids = itertools.count(1)
        # what every client that comes is told (advertise, advertiseServices) and one that subscribes to the graph,
        # encoded once until the graph changes: 308 channels took 1.5 ms of the loop per connection, 0.26 ms for a
        # rosbridge client's
        self._encoded = {}
        self._polling = False  # while a client subscribes to parameters
        self._parameter_timer = None  # the next poll, if not under way
        self._parameters = None  # {name: value} of the last poll...
        self._asked = None  # ...and the names it asked for (None: every parameter)
        self._poll_started = 0.0

    # ---- sessions -------------------------------------------------------------------------------
    def join(self, session):
        first = not self.sessions
        self.sessions.add(session)
        if first:
            self._backend.watch_graph(self.graph_changed)
            if self.sim_clock is not None:
                self.sim_clock.start()
        elif self.graph is not None:
            session.tell(self._everything())

    def leave(self, session):
        self.sessions.discard(session)
        if not self.sessions:
            self._backend.unwatch_graph(self.graph_changed)
            if self.sim_clock is not None:
                self.sim_clock.stop()
            self.graph = None  # (a client that comes later gets a fresh poll, not what was true then)
            self._encoded.clear()
            self.channels.clear()
            self._channel_ids.clear()
            self.services.clear()
            self._service_ids.clear()
        self.parameters_wanted()

    def channel(self, channel_id):
        return self.channels.get(channel_id)

    def service(self, service_id):
        return self.services.get(service_id)

    # ---- the graph ------------------------------------------------------------------------------
    def graph_changed(self, graph):
        """A new GraphState from the ROS side (on the loop)."""
        if not self.sessions:
            return
        graph = graph.filtered(self._globs)
        old, self.graph = self.graph, graph
        topics = {
            (topic, type_name, schema) for topic, (type_name, schema) in graph.topics.items() if schema is not None
        }
        gone = [key for key in self._channel_ids if key not in topics]
        removed = [self.channels.pop(self._channel_ids.pop(key)) for key in gone]
        added = []
        for key in sorted(topics - set(self._channel_ids)):
            channel_id = self._channel_ids[key] = next(self._ids)
            added.append(channel_entry(channel_id, *key))
            self.channels[channel_id] = added[-1]
        services = {  # (a service whose type is not known, or not installed here, as a topic's: not advertised)
            (name, type_name): schemas
            for name, (type_name, *schemas) in graph.services.items()
            if type_name and schemas[0] is not None
        }
        gone = [key for key in self._service_ids if key not in services]
        removed_services = [self._service_ids.pop(key) for key in gone]
        for service_id in removed_services:
            del self.services[service_id]
        added_services = []
        for key in sorted(set(services) - set(self._service_ids)):
            service_id = self._service_ids[key] = next(self._ids)
            added_services.append(service_entry(service_id, *key, *services[key]))
            self.services[service_id] = added_services[-1]
        self._encoded.clear()
        if old is None:
            frames = self._everything()
        else:
            frames = [
                dumps(message)
                for message, due in (
                    ({"op": "unadvertise", "channelIds": [channel["id"] for channel in removed]}, removed),
                    ({"op": "advertise", "channels": added}, added),
                    ({"op": "unadvertiseServices", "serviceIds": removed_services}, removed_services),
                    ({"op": "advertiseServices", "services": added_services}, added_services),
                )
                if due
            ]
        nodes_changed, update = old is None or old.nodes_differ(graph), None
        for session in list(self.sessions):
            if removed:
                session.channels_gone(removed)
            session.tell(frames)
            if nodes_changed and session.graph_subscribed:
                update = update or dumps(graph_update(old, graph))
                session.tell((update,))

    def _everything(self):
        """The advertise of every channel (even none) and the advertiseServices of every service (if any)."""
        frames = [self._encoded_list("advertise", "channels", self.channels)]
        if self.services:
            frames.append(self._encoded_list("advertiseServices", "services", self.services))
        return frames

    def _encoded_list(self, op, field, entries):
        if op not in self._encoded:
            self._encoded[op] = dumps({"op": op, field: list(entries.values())})
        return self._encoded[op]

    def full_graph(self):
        """The connectionGraphUpdate a client gets when it subscribes (encoded), None before the first poll."""
        if self.graph is not None and "graph" not in self._encoded:
            self._encoded["graph"] = dumps(graph_update(None, self.graph))
        return self._encoded.get("graph")

    # ---- parameters ------------------------------------------------------------------------------
    def parameter_allowed(self, name):
        return allowed(name, self._globs.params)

    def parameters_wanted(self):
        """Starts or stops the poll as clients subscribe to parameters or stop."""
        wanted = any(session.parameter_subscriptions for session in self.sessions)
        if wanted and not self._polling:
            self._polling = True
            self._parameter_timer = self._call_later(0, self._poll_parameters)
        elif not wanted and self._polling:
            self._polling, self._parameters = False, None
            if self._parameter_timer is not None:
                self._cancel_later(self._parameter_timer)
                self._parameter_timer = None

    def _wanted_names(self):
        """The names the clients subscribe to, or None: one of them subscribes to every parameter."""
        names = set()
        for session in self.sessions:
            if ALL in session.parameter_subscriptions:
                return None
            names |= session.parameter_subscriptions
        return names

    def _poll_parameters(self):
        """Reads what the clients subscribe to: only those names, unless one subscribes to every parameter (a
        client watching one parameter does not make the bridge read them all)."""
        self._parameter_timer = None
        asked = self._wanted_names()
        self._poll_started = time.monotonic()
        self._backend.get_parameters(
            self, None if asked is None else sorted(asked), lambda ok, values: self._polled(ok, values, asked)
        )

    def _polled(self, ok, values, asked):
        if not self._polling:  # (stopped meanwhile)
            return
        took = time.monotonic() - self._poll_started
        self._parameter_timer = self._call_later(max(PARAMETER_POLL, took * POLL_SPACING), self._poll_parameters)
        if not ok:
            return
        values = {name: value for name, value in values.items() if self.parameter_allowed(name)}
        before, asked_before = self._parameters, self._asked
        self._parameters, self._asked = values, asked
        if before is None or (asked is None) != (asked_before is None):  # (what later polls are compared with)
            return

        def compared(name):  # (a name asked both times: one asked only now is not news)
            return asked_before is None or name in asked_before

        changed = [name for name, value in values.items() if compared(name) and before.get(name, DELETE) != value]
        changed += [name for name in before if name not in values and (asked is None or name in asked)]
        if changed:
            self.parameters_changed({name: values.get(name, DELETE) for name in changed})

    def parameters_changed(self, values):
        """{name: value or DELETE} changed (by a poll, or by a client's setParameters): told to subscribers."""
        if self._parameters is not None:
            for name, value in values.items():
                if value is DELETE:
                    self._parameters.pop(name, None)
                else:
                    self._parameters[name] = value
        for session in list(self.sessions):
            session.parameters_updated(values)
