"""The rosbridge v2 ops a client may send, each with its fields' JSON types and whether they are required (OPS), and
check_fields, which refuses a request naming its first wrong field before the op runs (protocol/session.py).
Pure."""

import json

from rosbridge.errors import RequestError

LARGEST_INT = 2**63 - 1  # the widest integer ROS has (int64/uint64 aside); any count or time fits

# JSON types of the fields of each op: (python types, name shown to the client)
STRING = ((str,), "a string")
INT = ((int,), "an integer")
NUMBER = ((int, float), "a number")
BOOL = ((bool,), "a boolean")
OBJECT = ((dict,), "an object")
ARGS = ((dict, list), "an object or a list")
ID = ((str, int, float), "a string or a number")
ANY = ((object,), "any value")

REQUIRED, OPTIONAL = True, False
FieldKind = tuple[tuple[type, ...], str]  # (the JSON-decoded types a field may have, how the client is told)
OPS: dict[str, dict[str, tuple[FieldKind, bool]]] = {
    "advertise": {
        "topic": (STRING, REQUIRED),
        "type": (STRING, REQUIRED),
        "id": (ID, OPTIONAL),
        "latch": (BOOL, OPTIONAL),
        "queue_size": (INT, OPTIONAL),
    },
    "unadvertise": {"topic": (STRING, REQUIRED), "id": (ID, OPTIONAL)},
    "publish": {
        "topic": (STRING, REQUIRED),
        "msg": (OBJECT, REQUIRED),
        "id": (ID, OPTIONAL),
        "latch": (BOOL, OPTIONAL),
        "queue_size": (INT, OPTIONAL),
    },
    "subscribe": {
        "topic": (STRING, REQUIRED),
        "id": (ID, OPTIONAL),
        "type": (STRING, OPTIONAL),
        "throttle_rate": (NUMBER, OPTIONAL),
        "queue_length": (INT, OPTIONAL),
        "fragment_size": (INT, OPTIONAL),
        "compression": (STRING, OPTIONAL),
    },
    "unsubscribe": {"topic": (STRING, REQUIRED), "id": (ID, OPTIONAL)},
    "call_service": {
        "service": (STRING, REQUIRED),
        "id": (ID, OPTIONAL),
        "args": (ARGS, OPTIONAL),
        "type": (STRING, OPTIONAL),
        "fragment_size": (INT, OPTIONAL),
        "compression": (STRING, OPTIONAL),
        "timeout": (NUMBER, OPTIONAL),
    },
    "advertise_service": {"service": (STRING, REQUIRED), "type": (STRING, REQUIRED), "id": (ID, OPTIONAL)},
    "unadvertise_service": {"service": (STRING, REQUIRED), "id": (ID, OPTIONAL)},
    "service_response": {
        "service": (STRING, REQUIRED),
        "result": (BOOL, REQUIRED),
        "id": (ID, OPTIONAL),
        "values": (ANY, OPTIONAL),
    },
    "fragment": {"id": (ID, REQUIRED), "data": (STRING, REQUIRED), "num": (INT, REQUIRED), "total": (INT, REQUIRED)},
    "png": {"data": (STRING, REQUIRED), "id": (ID, OPTIONAL), "num": (INT, OPTIONAL), "total": (INT, OPTIONAL)},
    "auth": {
        "mac": (STRING, REQUIRED),
        "client": (STRING, REQUIRED),
        "dest": (STRING, REQUIRED),
        "rand": (STRING, REQUIRED),
        "t": (NUMBER, REQUIRED),
        "level": (STRING, REQUIRED),
        "end": (NUMBER, REQUIRED),
    },
    "set_level": {"level": (STRING, REQUIRED), "id": (ID, OPTIONAL)},
}


# per op: ({field: (exact JSON-decoded types, type text)}, required field names), for a fast check_fields
_FIELD_CHECKS = {
    op: (
        {name: (frozenset(types) if types != (object,) else None, text) for name, ((types, text), _) in fields.items()},
        tuple(name for name, (_, required) in fields.items() if required),
    )
    for op, fields in OPS.items()
}


def check_fields(op, request):
    """Raises RequestError naming the first missing, mistyped, out-of-range or unknown field of `request`."""
    fields, required = _FIELD_CHECKS[op]
    for name, value in request.items():
        check = fields.get(name)
        if check is None:
            if name == "op":
                continue
            raise RequestError(f"{op}: unknown field {name!r} (expected: {', '.join(fields)})")
        types, type_text = check
        # json.loads makes exact types (a bool is not an int here); None means absent (roslibpy sends null)
        if value is not None and types is not None and type(value) not in types:
            raise RequestError(f"{op}: field {name!r} must be {type_text}, got {json.dumps(value)[:80]}")
        if type(value) is int and name != "id" and not -LARGEST_INT <= value <= LARGEST_INT:  # JSON has no bound
            raise RequestError(f"{op}: field {name!r} is out of range: {str(value)[:40]}...")
    for name in required:
        if request.get(name) is None:
            raise RequestError(f"{op}: missing required field {name!r}")
