"""ROS parameters (as the master's XML-RPC gives them) <-> the Foxglove protocol's parameter values: a float is
sent with type "float64" and a list holding one with "float64_array" (JSON would turn 1.0 into 1, and a value set
back would become an int), XML-RPC binary with "byte_array" (base64). Dicts (namespaces) go as nested objects.
Pure."""

import base64
import binascii
import math
import xmlrpc.client

from rosbridge.contract import DELETE
from rosbridge.errors import RequestError

MAX_DEPTH = 32  # nesting of a value a client sets (a list in a dict in ...)


def to_client(name, value):
    """One parameter as the protocol's {"name", "value", "type"?}."""
    entry = {"name": name, "value": _plain(value)}
    if isinstance(value, float):
        entry["type"] = "float64"
    elif isinstance(value, xmlrpc.client.Binary):
        entry["type"] = "byte_array"
    elif (
        isinstance(value, list)
        and value
        and all(_is_number(v) for v in value)
        and any(isinstance(v, float) for v in value)
    ):
        entry["type"] = "float64_array"
    return entry


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _plain(value):
    if isinstance(value, float):
        return value if math.isfinite(value) else None  # (JSON has no NaN or infinities)
    if isinstance(value, xmlrpc.client.Binary):
        return base64.b64encode(value.data).decode()
    if isinstance(value, list):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (int, bool, str)) or value is None:
        return value
    return str(value)  # (a date: the master's XML-RPC has them, ROS params rarely)


ALL = ""  # a subscription to every parameter (no parameter has the empty name)


def from_client(entry):
    """A client's {"name", "value"?, "type"?} -> (name, the value to set, or DELETE); RequestError naming the
    field that is wrong."""
    if not isinstance(entry, dict):
        raise RequestError(f"setParameters: each parameter must be an object, got {str(entry)[:60]}")
    name, kind = entry.get("name"), entry.get("type")
    if not isinstance(name, str) or not name:
        raise RequestError("setParameters: field 'name' must be a non-empty string")
    if "value" not in entry or entry["value"] is None:
        return name, DELETE
    value = entry["value"]
    if kind is None:
        _check_plain(value, 0)
        return name, value
    if kind == "float64":
        if not _is_number(value):
            raise RequestError(f"setParameters {name}: a float64 value must be a number")
        return name, float(value)
    if kind == "float64_array":
        if not isinstance(value, list) or not all(_is_number(v) for v in value):
            raise RequestError(f"setParameters {name}: a float64_array value must be a list of numbers")
        return name, [float(v) for v in value]
    if kind == "byte_array":
        try:
            return name, xmlrpc.client.Binary(base64.b64decode(value, validate=True))
        except (TypeError, ValueError, binascii.Error):
            raise RequestError(f"setParameters {name}: a byte_array value must be base64 text") from None
    raise RequestError(f"setParameters {name}: field 'type' must be byte_array, float64 or float64_array")


def _check_plain(value, depth):
    if depth > MAX_DEPTH:
        raise RequestError(f"setParameters: a value nested deeper than {MAX_DEPTH} levels")
    if isinstance(value, float) and not math.isfinite(value):
        raise RequestError("setParameters: a value is not a finite number")
    if isinstance(value, int) and not isinstance(value, bool) and not -(2**31) <= value < 2**31:
        raise RequestError("setParameters: an integer outside 32 bits (XML-RPC's int)")
    if isinstance(value, list):
        for item in value:
            _check_plain(item, depth + 1)
    elif isinstance(value, dict):
        for item in value.values():
            _check_plain(item, depth + 1)
    elif not isinstance(value, (int, float, bool, str)):
        raise RequestError(f"setParameters: unsupported value {str(value)[:40]}")
