"""The /rosapi/* services (what roslibjs's getTopics, getServices, getNodes, Param... call), answered inside
the bridge instead of by a separate rosapi node.

Request and response field names are those of the reference rosapi package. Graph facts come from the ROS
master over XML-RPC; no rospy node is needed here. topics_glob / services_glob / params_glob hide topics,
services and parameters from every answer, and hidden parameters cannot be read, written or deleted. A
parameter is visible when its name or the name of a namespace holding it matches params_glob, so reading an
allowed namespace never shows a hidden parameter.

Where the reference fails silently, we answer with an error instead: an unreachable master, a bad argument,
an unknown type, a parameter value that is not JSON."""

import base64
import concurrent.futures
import io
import json
import math
import socket
import urllib.parse
import xmlrpc.client

import rosgraph
import rosgraph.names
import rosgraph.network

from rosbridge.errors import ClientError
from rosbridge.globs import Globs, allowed, filter_names
from rosbridge.message_types import UnknownType, message_class, service_class

# Field types without a typedef of their own. The reference forgets `char`; we count it as a number.
ATOMIC_TYPES = {
    "bool",
    "byte",
    "char",
    "int8",
    "uint8",
    "int16",
    "uint16",
    "int32",
    "uint32",
    "int64",
    "uint64",
    "float32",
    "float64",
    "string",
}
TIME_TYPES = {"time", "duration"}
# An action server is a namespace with all five of these topics.
ACTION_TOPICS = {"cancel", "feedback", "goal", "result", "status"}

# name -> (rosapi service type, request fields in their positional order); all request fields are strings.
# Each is answered by the Rosapi method named after its last part, e.g. /rosapi/topic_type by _topic_type.
SERVICES = {
    "/rosapi/topics": ("rosapi/Topics", ()),
    "/rosapi/topics_for_type": ("rosapi/TopicsForType", ("type",)),
    "/rosapi/topics_and_raw_types": ("rosapi/TopicsAndRawTypes", ()),
    "/rosapi/topic_type": ("rosapi/TopicType", ("topic",)),
    "/rosapi/publishers": ("rosapi/Publishers", ("topic",)),
    "/rosapi/subscribers": ("rosapi/Subscribers", ("topic",)),
    "/rosapi/services": ("rosapi/Services", ()),
    "/rosapi/services_for_type": ("rosapi/ServicesForType", ("type",)),
    "/rosapi/service_type": ("rosapi/ServiceType", ("service",)),
    "/rosapi/service_providers": ("rosapi/ServiceProviders", ("service",)),
    "/rosapi/service_node": ("rosapi/ServiceNode", ("service",)),
    "/rosapi/service_host": ("rosapi/ServiceHost", ("service",)),
    "/rosapi/message_details": ("rosapi/MessageDetails", ("type",)),
    "/rosapi/service_request_details": ("rosapi/ServiceRequestDetails", ("type",)),
    "/rosapi/service_response_details": ("rosapi/ServiceResponseDetails", ("type",)),
    "/rosapi/nodes": ("rosapi/Nodes", ()),
    "/rosapi/node_details": ("rosapi/NodeDetails", ("node",)),
    "/rosapi/action_servers": ("rosapi/GetActionServers", ()),
    "/rosapi/get_param": ("rosapi/GetParam", ("name", "default")),
    "/rosapi/set_param": ("rosapi/SetParam", ("name", "value")),
    "/rosapi/has_param": ("rosapi/HasParam", ("name",)),
    "/rosapi/search_param": ("rosapi/SearchParam", ("name",)),
    "/rosapi/delete_param": ("rosapi/DeleteParam", ("name",)),
    "/rosapi/get_param_names": ("rosapi/GetParamNames", ()),
    "/rosapi/get_time": ("rosapi/GetTime", ()),
}

# Asking service providers for their types (rosservice asks one at a time with a 5 s timeout, so one stopped
# node made a listing of 20 services take 100 s): at most this many at once, each given this long.
PROBE_THREADS = 8
PROBE_TIMEOUT = 2.0  # s
PROBED_TYPES_LIMIT = 4096  # remembered (service, provider URI) -> type pairs; forgotten all at once beyond


class RosapiError(ClientError):
    """A /rosapi call failed; the message says why and is meant for the client."""


class Rosapi:
    def __init__(self, master_uri, caller_id, globs=None, now=None):
        """caller_id: the bridge's node name (it is reported as the provider of the /rosapi services).
        globs: a Globs or a dict with topics/services/params pattern lists (None = all allowed).
        now: zero-argument callable returning the ROS time (genpy.Time), for /rosapi/get_time."""
        self.master_uri = master_uri
        self.caller_id = caller_id
        self.globs = Globs(**globs) if isinstance(globs, dict) else (globs or Globs())
        self.now = now
        # (service, provider URI) -> type: a provider's service keeps its type while it lives. Filled from several
        # call threads: single dict operations are atomic, and a lost entry is only asked again.
        self._probed_types = {}

    # ---- the bridge's side

    def handles(self, service):
        return service in SERVICES

    def services(self):
        """name -> type of every /rosapi service."""
        return {name: srv_type for name, (srv_type, _) in SERVICES.items()}

    def call(self, service, args=None):
        """Answers one /rosapi call (blocking: it talks to the master). args: dict, list of positional
        values, or None. Returns the response as a JSON-ready dict; raises RosapiError or UnknownType."""
        if service not in SERVICES:
            raise RosapiError(f"Service {service} does not exist")
        request = _request_fields(service, args)
        handler = getattr(self, "_" + service.rsplit("/", 1)[1])
        return handler(**request)

    # ---- topics

    def _topics(self):
        topics = self._topic_types()
        return {"topics": list(topics), "types": list(topics.values())}

    def _topics_for_type(self, type):
        return {"topics": [t for t, t_type in self._topic_types().items() if t_type == type]}

    def _topics_and_raw_types(self):
        topics = self._topic_types()
        return {
            "topics": list(topics),
            "types": list(topics.values()),
            "typedefs_full_text": [_full_text(t_type) for t_type in topics.values()],
        }

    def _topic_type(self, topic):
        return {"type": self._topic_types().get(topic, "")}

    def _publishers(self, topic):
        return {"publishers": self._topic_nodes(topic, 0)}

    def _subscribers(self, topic):
        return {"subscribers": self._topic_nodes(topic, 1)}

    def _action_servers(self):
        suffixes = {}
        for topic in self._topic_types():
            namespace, _, last = topic.rpartition("/")
            if namespace:
                suffixes.setdefault(namespace, set()).add(last)
        return {"action_servers": sorted(ns for ns, found in suffixes.items() if ACTION_TOPICS <= found)}

    def _topic_types(self):
        """{topic: type} for every allowed topic with a publisher or a subscriber, by name ("" when the master
        knows no type). getTopicTypes alone also lists topics whose nodes are gone."""
        pubs, subs, _ = self._ask("getSystemState")
        types = dict(self._ask("getTopicTypes"))
        names = sorted({t for t, _ in pubs} | {t for t, _ in subs})
        return {t: types.get(t, "") for t in filter_names(names, self.globs.topics)}

    def _topic_nodes(self, topic, which):
        if not allowed(topic, self.globs.topics):
            return []
        return sorted(dict(self._ask("getSystemState")[which]).get(topic, []))

    # ---- services

    def _services(self):
        return {"services": list(self._service_nodes())}

    def _services_for_type(self, type):
        types = self._service_types(self._service_nodes())
        return {"services": [s for s, s_type in types.items() if s_type == type]}

    def _service_type(self, service):
        return {"type": self._service_type_of(service) if allowed(service, self.globs.services) else ""}

    def _service_providers(self, service):
        """The reference takes a service *type* here; a service name (always starting with /) works too."""
        services = self._service_nodes()
        if service.startswith("/"):
            return {"providers": services.get(service, [])}
        types = self._service_types(services)
        return {
            "providers": sorted({node for name, nodes in services.items() if types[name] == service for node in nodes})
        }

    def _service_node(self, service):
        nodes = self._service_nodes().get(service, [])
        return {"node": nodes[0] if nodes else ""}

    def _service_host(self, service):
        if not allowed(service, self.globs.services):
            return {"host": ""}
        if service in SERVICES:
            uri = self._lookup("lookupNode", self.caller_id)
        else:
            uri = self._lookup("lookupService", service)
        return {"host": urllib.parse.urlsplit(uri).hostname or ""}

    def _service_nodes(self):
        """{service: [nodes]} for every allowed service, by name, the /rosapi ones included (provided by us)."""
        services = {name: nodes for name, nodes in self._ask("getSystemState")[2]}
        services.update({name: [self.caller_id] for name in SERVICES})
        return {name: services[name] for name in filter_names(sorted(services), self.globs.services)}

    def _service_types(self, services):
        """{service: type} of these services, their providers asked at once: one that never answers (a stopped
        node) delays the answer by PROBE_TIMEOUT, not by that much for each service after it."""
        services = list(services)
        with concurrent.futures.ThreadPoolExecutor(max(1, min(PROBE_THREADS, len(services)))) as pool:
            return dict(zip(services, pool.map(self._service_type_of, services)))

    def _service_type_of(self, service):
        """The type of a service, asked of its provider as rosservice does; "" if it cannot be found."""
        if service in SERVICES:
            return SERVICES[service][0]
        uri = self._lookup("lookupService", service)
        if not uri:
            return ""
        known = self._probed_types.get((service, uri))
        if known is None:
            known = probe_service_type(service, uri)
            if known:
                if len(self._probed_types) >= PROBED_TYPES_LIMIT:
                    self._probed_types.clear()
                self._probed_types[(service, uri)] = known
        return known

    # ---- nodes

    def _nodes(self):
        return {
            "nodes": sorted(
                {node for kind in self._ask("getSystemState") for _, nodes in kind for node in nodes} | {self.caller_id}
            )
        }

    def _node_details(self, node):
        pubs, subs, _ = self._ask("getSystemState")

        def of_node(entries, patterns):
            return filter_names(sorted(name for name, nodes in entries if node in nodes), patterns)

        return {
            "subscribing": of_node(subs, self.globs.topics),
            "publishing": of_node(pubs, self.globs.topics),
            "services": [name for name, nodes in self._service_nodes().items() if node in nodes],
        }

    # ---- types

    def _message_details(self, type):
        return {"typedefs": typedefs(message_class(type))}

    def _service_request_details(self, type):
        return {"typedefs": typedefs(service_class(type)._request_class)}

    def _service_response_details(self, type):
        return {"typedefs": typedefs(service_class(type)._response_class)}

    # ---- parameters (values travel as JSON text)

    def _get_param(self, name, default):
        name = self._param_name(name, refuse_hidden=True)
        try:
            value = self._ask("getParam", name)
        except rosgraph.masterapi.MasterException:  # not set
            if default == "":
                return {"value": "null"}
            try:
                value = json.loads(default)
            except ValueError:
                value = default  # the reference takes a non-JSON default as a string
        return {"value": json.dumps(_jsonable(value))}

    def _set_param(self, name, value):
        name = self._param_name(name, refuse_hidden=True)
        try:
            parsed = json.loads(value)
        except ValueError:
            raise RosapiError(
                f'the value of parameter {name} must be JSON text (e.g. 1, "text", [1, 2]), got {value!r}'
            ) from None
        if _contains_null(parsed):
            raise RosapiError(f"the value of parameter {name} contains null, which ROS parameters cannot hold")
        try:
            self._ask("setParam", name, parsed)
        except (OverflowError, TypeError) as err:  # XML-RPC holds 32-bit ints only
            raise RosapiError(f"cannot store {value!r} in parameter {name}: {err}") from None
        return {}

    def _has_param(self, name):
        name = self._param_name(name)
        return {"exists": self._param_allowed(name) and bool(self._ask("hasParam", name))}

    def _search_param(self, name):
        """The global name the parameter resolves to searching up from the bridge's namespace, "" if none."""
        if not name:
            raise RosapiError("search_param needs a parameter name")
        try:
            found = self._ask("searchParam", name)
        except rosgraph.masterapi.MasterException:
            return {"global_name": ""}
        return {"global_name": found if found and self._param_allowed(found) else ""}

    def _delete_param(self, name):
        name = self._param_name(name, refuse_hidden=True)
        try:
            self._ask("deleteParam", name)
        except rosgraph.masterapi.MasterException:
            pass  # nothing to delete: not an error, as in the reference
        return {}

    def _get_param_names(self):
        return {"names": [name for name in sorted(self._ask("getParamNames")) if self._param_allowed(name)]}

    def _param_name(self, name, refuse_hidden=False):
        """The global name of a parameter; relative names are relative to the bridge's namespace."""
        if not name or not rosgraph.names.is_legal_name(name):
            raise RosapiError(f"invalid parameter name {name!r}")
        name = rosgraph.names.resolve_name(name, self.caller_id)
        if refuse_hidden and not self._param_allowed(name):
            raise RosapiError(f"parameter {name} is hidden by params_glob")
        return name

    def _param_allowed(self, name):
        """Whether params_glob allows the global name itself or one of the namespaces holding it."""
        parts = name.strip("/").split("/")
        return any(allowed("/" + "/".join(parts[:depth]), self.globs.params) for depth in range(len(parts), 0, -1))

    # ---- time

    def _get_time(self):
        if self.now is None:
            raise RosapiError("get_time is not available: the bridge gave rosapi no clock")
        now = self.now()
        return {"time": {"secs": now.secs, "nsecs": now.nsecs}}

    # ---- master access

    def _ask(self, method, *args):
        """Calls the master (a fresh XML-RPC proxy each time: calls come from several threads)."""
        master = rosgraph.Master(self.caller_id, master_uri=self.master_uri)
        try:
            return getattr(master, method)(*args)
        except (OSError, xmlrpc.client.ProtocolError) as err:
            raise RosapiError(f"cannot reach the ROS master at {self.master_uri}: {err}") from None

    def _lookup(self, method, name):
        """lookupService / lookupNode: the URI, or "" when the master does not know the name."""
        try:
            return self._ask(method, name)
        except rosgraph.masterapi.MasterException:
            return ""


def probe_service_type(service, uri):
    """The type a service provider states in its TCPROS header when probed (what rosservice reads), or "" when
    it does not answer within PROBE_TIMEOUT (gone, stopped, or not a service)."""
    try:
        address = urllib.parse.urlsplit(uri)
        if address.scheme != "rosrpc" or not address.hostname or not address.port:
            return ""
        with socket.create_connection((address.hostname, address.port), timeout=PROBE_TIMEOUT) as sock:
            rosgraph.network.write_ros_handshake_header(
                sock, {"probe": "1", "md5sum": "*", "callerid": "/rosapi", "service": service}
            )
            return rosgraph.network.read_ros_handshake_header(sock, io.BytesIO(), 2048).get("type", "")
    except (OSError, ValueError, rosgraph.network.ROSHandshakeException):  # (ValueError: a bad port in the URI)
        return ""


def _request_fields(service, args):
    """The request of a /rosapi call as {field: str}; missing fields are "" as in a ROS request."""
    fields = SERVICES[service][1]
    if args is None:
        args = {}
    elif isinstance(args, list):
        if len(args) > len(fields):
            raise RosapiError(
                f"{service} takes {len(fields)} argument(s) ({', '.join(fields) or 'none'}), got {len(args)}"
            )
        args = dict(zip(fields, args))
    elif not isinstance(args, dict):
        raise RosapiError(f"the args of {service} must be an object, got {args!r}")
    for key, value in args.items():
        if key not in fields:
            raise RosapiError(f"{service} has no field {key!r} (fields: {', '.join(fields) or 'none'})")
        if not isinstance(value, str):
            raise RosapiError(f"field {key!r} of {service} must be a string, got {value!r}")
    return {field: args.get(field, "") for field in fields}


def typedefs(cls):
    """The reference's TypeDef list for a message class: its own typedef, then (depth first, each type once)
    those of every message, time or duration type among its fields."""
    result, seen = [], {cls._type}

    def visit(visited_cls):
        typedef = _typedef(visited_cls)
        result.append(typedef)
        for field_type in typedef["fieldtypes"]:
            if field_type in seen or field_type in ATOMIC_TYPES:
                continue
            seen.add(field_type)
            if field_type in TIME_TYPES:
                result.append(_time_typedef(field_type))
            else:
                visit(message_class(field_type))

    visit(cls)
    return result


def _typedef(cls):
    """One TypeDef: field types without array suffix, fieldarraylen -1 (not an array), 0 (variable) or the
    fixed length, and examples as the reference writes them: str() of an atomic default ("0", "0.0", "False",
    ""), "[]" for any array, "{}" for a message, time or duration."""
    instance = cls()
    fieldtypes, arraylens, examples = [], [], []
    for name, slot_type in zip(cls.__slots__, cls._slot_types):
        base, bracket, length = slot_type.partition("[")
        arraylen = (int(length[:-1]) if length[:-1] else 0) if bracket else -1
        fieldtypes.append(base)
        arraylens.append(arraylen)
        if arraylen >= 0:
            examples.append("[]")
        elif base in ATOMIC_TYPES:
            examples.append(str(getattr(instance, name)))
        else:
            examples.append("{}")
    constants = sorted(
        (name, value)
        for name, value in vars(cls).items()
        if not name.startswith("_") and name not in cls.__slots__ and not callable(value)
    )
    return {
        "type": cls._type,
        "fieldnames": list(cls.__slots__),
        "fieldtypes": fieldtypes,
        "fieldarraylen": arraylens,
        "examples": examples,
        "constnames": [name for name, _ in constants],
        "constvalues": [str(value) for _, value in constants],
    }


def _time_typedef(type_name):
    return {
        "type": type_name,
        "fieldnames": ["secs", "nsecs"],
        "fieldtypes": ["int32", "int32"],
        "fieldarraylen": [-1, -1],
        "examples": ["0", "0"],
        "constnames": [],
        "constvalues": [],
    }


def _full_text(type_name):
    """The message definition with those of its dependencies (as `gendeps --cat`), "" if unknown."""
    if not type_name:
        return ""
    try:
        return message_class(type_name)._full_text
    except UnknownType:
        return ""


def _jsonable(value):
    """A parameter value as JSON can hold it: NaN/Inf -> null, binary -> base64 text, dates -> ISO text."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _jsonable(sub) for key, sub in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(sub) for sub in value]
    if isinstance(value, xmlrpc.client.Binary):
        return base64.b64encode(value.data).decode()
    if isinstance(value, xmlrpc.client.DateTime):
        return value.value
    return value


def _contains_null(value):
    if value is None:
        return True
    if isinstance(value, dict):
        return any(_contains_null(sub) for sub in value.values())
    if isinstance(value, list):
        return any(_contains_null(sub) for sub in value)
    return False
