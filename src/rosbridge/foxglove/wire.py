"""The Foxglove WebSocket protocol's binary messages, both ways (`foxglove.websocket.v1`; its spec is docs/spec.md
of github:foxglove/ws-protocol, last in commit 8e2a044^). Integers are little-endian. Pure: bytes in, bytes out."""

import struct

from rosbridge.codec import BIG_BYTES
from rosbridge.errors import RequestError
from rosbridge.protocol.encoded import SplicedFrame

SUBPROTOCOLS = ("foxglove.websocket.v1", "foxglove.sdk.v1")  # the same protocol under its two names

# server -> client opcodes
MESSAGE_DATA, TIME, SERVICE_CALL_RESPONSE, FETCH_ASSET_RESPONSE = 0x01, 0x02, 0x03, 0x04
# client -> server opcodes
CLIENT_MESSAGE_DATA, SERVICE_CALL_REQUEST = 0x01, 0x02

_MESSAGE_HEAD = struct.Struct("<BIQ")  # opcode, subscription id, receive time (ns)
_TIME = struct.Struct("<BQ")
_CALL_HEAD = struct.Struct("<BIII")  # opcode, service id, call id, encoding length
_ASSET_HEAD = struct.Struct("<BIBI")  # opcode, request id, status, error length
_CHANNEL_HEAD = struct.Struct("<BI")
U32_MAX = 2**32 - 1


def message_data(subscription_id, receive_ns, datas):
    """The frames of messages for one subscription that share their receive time (one read's): the 13-byte head
    (opcode, subscription id, receive time), then each message's bytes as they came from TCPROS. A big one (an
    image) is not copied: its frame refers to the same bytes for every client."""
    head = _MESSAGE_HEAD.pack(MESSAGE_DATA, subscription_id, receive_ns)
    return [head + data if len(data) < BIG_BYTES else SplicedFrame((head, data), text=False) for data in datas]


def time_frame(ns):
    return _TIME.pack(TIME, ns)


def service_call_response(service_id, call_id, encoding, payload):
    encoded = encoding.encode()
    return _CALL_HEAD.pack(SERVICE_CALL_RESPONSE, service_id, call_id, len(encoded)) + encoded + payload


def fetch_asset_response(request_id, data=None, error=None):
    """The asset's bytes, or (data None) the error's text."""
    if data is None:
        text = (error or "error").encode()
        return _ASSET_HEAD.pack(FETCH_ASSET_RESPONSE, request_id, 1, len(text)) + text
    head = _ASSET_HEAD.pack(FETCH_ASSET_RESPONSE, request_id, 0, 0)
    return SplicedFrame((head, data), text=False) if len(data) >= BIG_BYTES else head + data


def client_message(data):
    """A client's binary message -> ("publish", channel id, payload) or ("call", service id, call id, encoding,
    payload); RequestError naming what is wrong with it."""
    if not data:
        raise RequestError("empty binary message: expected an opcode (1: message data, 2: service call request)")
    opcode = data[0]
    if opcode == CLIENT_MESSAGE_DATA:
        if len(data) < _CHANNEL_HEAD.size:
            raise RequestError(f"client message data of {len(data)} bytes: shorter than its 5-byte head")
        _, channel_id = _CHANNEL_HEAD.unpack_from(data)
        return "publish", channel_id, memoryview(data)[_CHANNEL_HEAD.size :]
    if opcode == SERVICE_CALL_REQUEST:
        if len(data) < _CALL_HEAD.size:
            raise RequestError(f"service call request of {len(data)} bytes: shorter than its 13-byte head")
        _, service_id, call_id, length = _CALL_HEAD.unpack_from(data)
        end = _CALL_HEAD.size + length
        if end > len(data):
            raise RequestError(f"service call request: encoding length {length} runs past its {len(data)} bytes")
        try:
            encoding = bytes(data[_CALL_HEAD.size : end]).decode()
        except UnicodeDecodeError:
            raise RequestError("service call request: its encoding is not UTF-8 text") from None
        return "call", service_id, call_id, encoding, memoryview(data)[end:]
    raise RequestError(f"unknown binary opcode {opcode} (1: message data, 2: service call request)")
