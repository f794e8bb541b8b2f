"""TCPROS, ROS 1's topic transport, without I/O: the connection headers the two sides exchange, and the framing
of messages on the stream (each a 4-byte little-endian length, then the serialized message). The sockets that
use it are in rosbridge.ros_side.links.

The rules are rospy's (rospy.impl.tcpros_pubsub), so that stock nodes see the bridge as any rospy node."""

import struct

from rosgraph.network import ROSHandshakeException, decode_ros_handshake_header, encode_ros_handshake_header

LENGTH = struct.Struct("<I")
SEQ = struct.Struct("<I")  # a header's seq: the first 4 bytes of a message whose first field is its header
MAX_HEADER = 1 << 20  # bytes: a connection header (message definitions included) is a few kB
MAX_MESSAGE = 1 << 28  # bytes: room for a 4K camera's raw images and big point clouds, not for a bogus length
BIG_FRAME = 1 << 16  # bytes: a message at least this long is read in place (FrameReader)
ANY_TYPE = "*"  # the md5sum of a subscriber that takes any type (rostopic's)


class TcprosError(Exception):
    """The other side broke TCPROS: its connection header is malformed or too big, it refused the connection,
    or it announced a message too big."""


def frame(data, seq=None):
    """One message as it goes on the stream; with `seq`, numbered as a rospy publisher numbers its messages
    (their header.seq, wrapping as rospy's uint32 does)."""
    if seq is None:
        return LENGTH.pack(len(data)) + data
    return LENGTH.pack(len(data)) + SEQ.pack(seq & 0xFFFFFFFF) + memoryview(data)[4:]  # (one copy, not two)


def header_size(prefix):
    """The size of a connection header from its first 4 bytes; refused beyond MAX_HEADER."""
    (size,) = LENGTH.unpack(prefix)
    if size > MAX_HEADER:
        raise TcprosError(f"connection header of {size} bytes (at most {MAX_HEADER})")
    return size


def encode_header(fields):
    return encode_ros_handshake_header(fields)


def decode_header(body):
    """The fields of a connection header, from the bytes after its length."""
    try:
        return decode_ros_handshake_header(LENGTH.pack(len(body)) + body)
    except (ROSHandshakeException, ValueError, UnicodeDecodeError, struct.error) as error:
        raise TcprosError(f"malformed connection header: {error}") from None


def subscriber_header(topic, cls, callerid):
    """What the bridge sends a publisher it subscribes to. tcp_nodelay: every message is sent at once, as the
    bridge forwards each as soon as it comes."""
    return {
        "topic": topic,
        "md5sum": cls._md5sum,
        "type": cls._type,
        "message_definition": cls._full_text,
        "callerid": callerid,
        "tcp_nodelay": "1",
    }


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
        return {
            "error": f"Client [{header['callerid']}] wants topic [{topic}] to have datatype/md5sum "
            f"[{asked_type}/{md5sum}], but our version has [{cls._type}/{cls._md5sum}] Dropping "
            "connection."
        }
    return {
        "callerid": callerid,
        "md5sum": cls._md5sum,
        "type": cls._type,
        "topic": topic,
        "message_definition": cls._full_text,
        "latching": "1" if latch else "0",
    }


def wants_nodelay(header):
    return header.get("tcp_nodelay", "0").strip() == "1"


class FrameReader:
    """Splits the bytes read from a publisher into frames: its connection header, then its messages. A frame
    longer than `max_size` is refused (TcprosError) before its bytes are awaited. A message of BIG_FRAME bytes or
    more is read in place: once its length is known, the rest goes straight into its own buffer (`into`,
    `received`), which becomes the message (a bytearray) - no copy of a camera image on the way."""

    __slots__ = ("_pending", "_big", "_filled", "max_size")

    def __init__(self, max_size=MAX_MESSAGE):
        self._pending = bytearray()  # the bytes of frames not complete yet (below BIG_FRAME, or their length)
        self._big = None  # the buffer of the big message under way
        self._filled = 0  # bytes of it read so far
        self.max_size = max_size

    def feed(self, chunk, most=None):
        """The frames completed by `chunk` (in order; at most `most` of them); the rest waits."""
        messages = []
        if self._big is not None:
            taken = min(len(chunk), len(self._big) - self._filled)
            self._big[self._filled : self._filled + taken] = chunk[:taken]
            messages = self.received(taken)
            if not messages:
                return messages
            chunk = chunk[taken:]
        pending = self._pending
        if pending:
            pending += chunk
            data = memoryview(pending)
        else:
            data = chunk
        offset, end = 0, len(data)
        while end - offset >= 4 and most != len(messages):
            (size,) = LENGTH.unpack_from(data, offset)
            if size > self.max_size:
                raise TcprosError(f"a frame of {size} bytes (at most {self.max_size})")
            start = offset + 4
            if end - start < size:
                if size >= BIG_FRAME and most is None:  # (messages only: the header is taken alone)
                    self._big = bytearray(size)
                    self._big[: end - start] = data[start:end]
                    self._filled, offset = end - start, end
                break
            messages.append(bytes(data[start : start + size]))
            offset = start + size
        if pending:
            data.release()
            del pending[:offset]
        elif offset < end:
            pending += chunk[offset:]
        return messages

    def into(self):
        """Where the rest of the big message under way goes (a writable memoryview to read into, then call
        `received`), or None."""
        return None if self._big is None else memoryview(self._big)[self._filled :]

    def received(self, count):
        """`count` bytes were read into `into()`: the big message once it is complete ([] until then)."""
        self._filled += count
        if self._filled < len(self._big):
            return []
        message, self._big = self._big, None
        return [message]
