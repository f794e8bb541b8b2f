"""TCPROS, ROS 1's topic transport, without I/O: the connection headers the two sides exchange, and the framing
of messages on the stream (each a 4-byte little-endian length, then the serialized message). The sockets that
use it are in rosbridge.ros_side.links.

The rules are rospy's (rospy.impl.tcpros_pubsub), so that stock nodes see the bridge as any rospy node."""
import struct

from rosgraph.network import ROSHandshakeException, decode_ros_handshake_header, encode_ros_handshake_header

LENGTH = struct.Struct("<I")
MAX_HEADER = 1 << 20  # bytes: a connection header (message definitions included) is a few kB
ANY_TYPE = "*"  # the md5sum of a subscriber that takes any type (rostopic's)


class HandshakeError(Exception):
    """The other side's connection header is malformed, or it refused the connection."""


def frame(data):
    """One message as it goes on the stream."""
    return LENGTH.pack(len(data)) + data


def header_size(prefix):
    """The size of a connection header from its first 4 bytes; refused beyond MAX_HEADER."""
    (size,) = LENGTH.unpack(prefix)
    if size > MAX_HEADER:
        raise HandshakeError(f"connection header of {size} bytes (at most {MAX_HEADER})")
    return size


def encode_header(fields):
    return encode_ros_handshake_header(fields)


def decode_header(prefix, body):
    try:
        return decode_ros_handshake_header(prefix + body)
    except (ROSHandshakeException, ValueError, UnicodeDecodeError, struct.error) as error:
        raise HandshakeError(f"malformed connection header: {error}") from None


def subscriber_header(topic, cls, callerid):
    """What the bridge sends a publisher it subscribes to. tcp_nodelay: every message is sent at once, as the
    bridge forwards each as soon as it comes."""
    return {"topic": topic, "md5sum": cls._md5sum, "type": cls._type, "message_definition": cls._full_text,
            "callerid": callerid, "tcp_nodelay": "1"}


def publisher_reply(header, topic, cls, latch, callerid):
    """The bridge's answer, as the publisher of `topic` (messages of class `cls`), to a subscriber's header: the
    reply's fields, or {"error": why} (then the connection is closed)."""
    for required in ("topic", "md5sum", "callerid"):
        if required not in header:
            return {"error": f"Missing required '{required}' field"}
    md5sum = header["md5sum"]
    if md5sum not in (ANY_TYPE, cls._md5sum):
        asked_type = header.get("type", cls._type)
        if asked_type != cls._type:
            return {"error": f"topic types do not match: [{asked_type}] vs. [{cls._type}]"}
        return {"error": f"Client [{header['callerid']}] wants topic [{topic}] to have datatype/md5sum "
                         f"[{asked_type}/{md5sum}], but our version has [{cls._type}/{cls._md5sum}] Dropping "
                         "connection."}
    return {"callerid": callerid, "md5sum": cls._md5sum, "type": cls._type, "topic": topic,
            "message_definition": cls._full_text, "latching": "1" if latch else "0"}


def wants_nodelay(header):
    return header.get("tcp_nodelay", "0").strip() == "1"


class FrameReader:
    """Splits the bytes read from a publisher into messages."""
    __slots__ = ("_pending",)

    def __init__(self):
        self._pending = b""

    def feed(self, chunk):
        """The messages completed by `chunk` (bytes each, in order); the rest waits for more."""
        data = self._pending + chunk if self._pending else chunk
        messages, offset, end = [], 0, len(data)
        while end - offset >= 4:
            (size,) = LENGTH.unpack_from(data, offset)
            start = offset + 4
            if end - start < size:
                break
            messages.append(data[start:start + size])
            offset = start + size
        self._pending = data[offset:] if offset else data
        return messages

    def missing(self):
        """How many more bytes the message begun needs (0 if none is begun or its length is not read yet)."""
        pending = self._pending
        if len(pending) < 4:
            return 0
        return LENGTH.unpack_from(pending)[0] + 4 - len(pending)
