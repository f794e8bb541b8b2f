"""RFC 6455 websockets, server side, without I/O (as h11 is for HTTP, or tcpros.FrameReader for TCPROS): the
opening handshake's answer, a FrameReader that turns what a client sent into its messages and control frames,
and the bytes of the server's own frames; permessage-deflate (RFC 7692) both ways, each message on its own: the
answer asks the client to keep no context between its messages (client_no_context_takeover) and we keep none
(server_no_context_takeover), so that nothing of zlib's lives per client between messages (a thousand idle clients
hold no compressor or inflater), and a message deflated once is the same bytes for every client. Pure: no tornado,
no sockets; the shell (websocket.py) moves the bytes and chooses which messages go deflated.

A client's frames come out one event per frame, so that whoever reads can weigh every frame a client sends
(budget.py), the parts of a fragmented message and the control frames included."""
import base64
import hashlib
import struct
import zlib

CONTINUATION, TEXT, BINARY, CLOSE, PING, PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA
PART = -1  # the event of a frame that only carries part of a message
_FIN, _RSV1, _RESERVED, _MASKED = 0x80, 0x40, 0x70, 0x80

# close codes (RFC 6455 section 7.4.1)
NORMAL, GOING_AWAY, PROTOCOL_ERROR, NO_STATUS, INVALID_DATA, POLICY, TOO_BIG = 1000, 1001, 1002, 1005, 1007, 1008, 1009
_SENDABLE_CODES = {1000, 1001, 1002, 1003, 1007, 1008, 1009, 1010, 1011, 1012, 1013, 1014}  # and 3000-4999

_GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"
_LENGTH_16, _LENGTH_64, _CODE = struct.Struct("!H"), struct.Struct("!Q"), struct.Struct("!H")
_DEFLATE_TAIL = b"\x00\x00\xff\xff"  # what a sync flush ends with, left off on the wire (RFC 7692 7.2.1)
PART_COST = 64  # what a frame of a fragmented message counts beyond its bytes: empty parts are not free
# zlib's fastest level: a camera's base64 goes to 0.5-0.6 of its size at 60-85 MB/s (level 6: a few percent
# smaller, up to 7 times slower), and zlib lets go of Python's lock meanwhile
DEFLATE_LEVEL = 1
_WINDOW_BITS = range(9, 16)  # the windows zlib writes raw deflate with (RFC 7692 allows 8 to 15)
CONTEXT_BYTES = 1 << 15  # the largest window: how far back a client's compressed message may point


class ProtocolError(Exception):
    """The client broke the protocol: the connection ends with this close code and reason."""

    def __init__(self, code, reason):
        super().__init__(reason)
        self.code, self.reason = code, reason


def accept_key(key):
    """Sec-WebSocket-Accept for a client's Sec-WebSocket-Key."""
    return base64.b64encode(hashlib.sha1(key.encode() + _GUID).digest()).decode()


def handshake_error(headers):
    """Why a GET with these request headers (a case-insensitive mapping) cannot be a websocket, as
    (HTTP status, text), or None if it can."""
    if "upgrade" not in headers.get("Connection", "").lower():
        return 400, "Connection header must include 'Upgrade'"
    if headers.get("Sec-WebSocket-Version") != "13":
        return 426, "only websocket version 13 is supported (Sec-WebSocket-Version: 13)"
    key = headers.get("Sec-WebSocket-Key", "")
    try:
        if len(base64.b64decode(key, validate=True)) != 16:
            raise ValueError
    except ValueError:
        return 400, "Sec-WebSocket-Key must be 16 bytes in base64"
    return None


def negotiate_deflate(offers):
    """The answer to a client's Sec-WebSocket-Extensions header: (our Sec-WebSocket-Extensions value, the largest
    window, in bits, our messages may use), or (None, None) if no permessage-deflate offer can be taken. Neither
    side keeps context between messages: server_no_context_takeover always, and client_no_context_takeover
    whether offered or not (RFC 7692 7.1.1.2 lets the server add it), so each message is inflated on its own."""
    for offer in offers.split(","):
        name, *params = [part.strip() for part in offer.split(";")]
        if name != "permessage-deflate":
            continue
        asked, ok = {}, True
        for param in params:
            key, _, value = param.partition("=")
            key, value = key.strip(), value.strip().strip('"')
            if key in asked or key not in ("server_no_context_takeover", "client_no_context_takeover",
                                           "server_max_window_bits", "client_max_window_bits"):
                ok = False
            asked[key] = value
        server_bits, client_bits = asked.get("server_max_window_bits", "15"), asked.get("client_max_window_bits")
        if not ok or not (server_bits.isdigit() and int(server_bits) in _WINDOW_BITS) or client_bits and not (
                client_bits.isdigit() and 8 <= int(client_bits) <= 15):
            continue  # (zlib writes raw deflate with windows of 9 to 15 bits only; we inflate any window)
        answer = ["permessage-deflate", "server_no_context_takeover", "client_no_context_takeover"]
        if "server_max_window_bits" in asked:
            answer.append(f"server_max_window_bits={server_bits}")
        return "; ".join(answer), int(server_bits)
    return None, None


def message_window_bits(size, max_window_bits):
    """The window to deflate a message of `size` bytes with: the smallest that holds all of it, up to
    max_window_bits (a small message costs little memory, and deflates the same)."""
    return min(max_window_bits, max(_WINDOW_BITS[0], (size - 1).bit_length()))


def deflate_message(parts, bits):
    """The payload of one permessage-deflate message holding `parts` (bytes-likes, one after another), compressed
    on its own with a compressor made for it and dropped after (no context kept: RFC 7692 7.2.1), with a window
    of `bits` (message_window_bits)."""
    compressor = zlib.compressobj(DEFLATE_LEVEL, zlib.DEFLATED, -bits)
    data = [compressor.compress(part) for part in parts]
    data.append(compressor.flush(zlib.Z_SYNC_FLUSH)[:-len(_DEFLATE_TAIL)])  # (a sync flush ends with the tail)
    return b"".join(data)


def frame_header(length, opcode, compressed=False):
    """The header of a server frame: unmasked, final (RFC 6455 section 5.2)."""
    first = _FIN | opcode | (_RSV1 if compressed else 0)
    if length < 126:
        return bytes((first, length))
    if length <= 0xFFFF:
        return bytes((first, 126)) + _LENGTH_16.pack(length)
    return bytes((first, 127)) + _LENGTH_64.pack(length)


def control_frame(opcode, payload=b""):
    """A ping, pong or close frame of the server (payload: at most 125 bytes)."""
    return frame_header(len(payload), opcode) + payload


def close_frame(code=None, reason=""):
    """A close frame; code None: without a status (what answers a client's close without one)."""
    if code is None:
        return control_frame(CLOSE)
    return control_frame(CLOSE, _CODE.pack(code) + reason.encode()[:123])


def xor_mask(mask, data):
    """data unmasked with a client's 4-byte mask (the shell may pass a faster one to FrameReader)."""
    count = len(data)
    key = (mask * (count // 4 + 1))[:count]
    return (int.from_bytes(data, "little") ^ int.from_bytes(key, "little")).to_bytes(count, "little")


class FrameReader:
    """The frames of one client. `receive(data)` takes what was read; each `next_event()` gives the next frame's
    event, or None until more bytes come:
      (TEXT, str, size)    a whole text message (UTF-8 checked)
      (BINARY, bytes, size) a whole binary message
      (PART, None, size)   a frame holding part of a message that is not complete yet
      (PING, bytes, size), (PONG, bytes, size)
      (CLOSE, (code, reason), size)    code NO_STATUS if the client gave none
    size: the frame's payload bytes, or for the last frame of a compressed message what the whole message
    unpacked to beyond the frames before. A frame that breaks the protocol raises ProtocolError, and so does
    a message over max_size bytes (TOO_BIG, before its payload is read); the reader is done after that.

    What it holds: at most one incomplete frame (max_size bytes) and the bytes given to it beyond that, which
    the shell keeps small by reading only when next_event() has said None; one message being put together
    (max_size bytes, each of its frames counted PART_COST more); with deflate, no zlib object between messages,
    and the end of what the client's compressed messages held, 2 * CONTEXT_BYTES at most (see _inflate)."""

    def __init__(self, max_size, deflate=False, unmask=xor_mask):
        self.max_size, self._unmask = max_size, unmask
        self._buffer = bytearray()
        self._start = 0  # where the next frame starts in _buffer
        self._parts = None  # the message being put together from its frames (bytearray), or None
        self._parts_weight = 0  # what those frames count against max_size: their bytes, and PART_COST each
        self._opcode = None  # the opcode of that message
        self._compressed = False  # whether it is compressed
        self._deflate = deflate  # permessage-deflate negotiated: each compressed message inflated on its own
        self._inflated = bytearray()  # the end of what the client's compressed messages held, for _inflate

    @property
    def buffered(self):
        """Bytes received and not taken yet."""
        return len(self._buffer) - self._start

    def receive(self, data):
        if self._start:
            del self._buffer[:self._start]
            self._start = 0
        self._buffer += data

    def next_event(self):
        buf, start = self._buffer, self._start
        available = len(buf) - start
        if available < 2:
            return None
        first, second = buf[start], buf[start + 1]
        opcode, length, head = first & 0x0F, second & 0x7F, 2
        if first & _RESERVED and not (first & _RESERVED == _RSV1 and self._deflate and opcode in
                                      (TEXT, BINARY)):
            raise ProtocolError(PROTOCOL_ERROR, "reserved bits set without an extension that uses them")
        if not second & _MASKED:
            raise ProtocolError(PROTOCOL_ERROR, "a client's frames must be masked")
        if opcode & 0x8:
            if length > 125 or not first & _FIN:
                raise ProtocolError(PROTOCOL_ERROR, "control frames must be final and at most 125 bytes")
            if opcode not in (CLOSE, PING, PONG):
                raise ProtocolError(PROTOCOL_ERROR, f"unknown opcode {opcode}")
        elif opcode == CONTINUATION:
            if self._parts is None:
                raise ProtocolError(PROTOCOL_ERROR, "continuation frame without a message to continue")
        elif opcode in (TEXT, BINARY):
            if self._parts is not None:
                raise ProtocolError(PROTOCOL_ERROR, "new message before the last one was finished")
        else:
            raise ProtocolError(PROTOCOL_ERROR, f"unknown opcode {opcode}")
        if length == 126:
            if available < 4:
                return None
            (length,), head = _LENGTH_16.unpack_from(buf, start + 2), 4
        elif length == 127:
            if available < 10:
                return None
            (length,), head = _LENGTH_64.unpack_from(buf, start + 2), 10
        if length + (self._parts_weight + PART_COST if opcode == CONTINUATION else 0) > self.max_size:
            raise ProtocolError(TOO_BIG, "message too big")
        payload_at = start + head + 4
        end = payload_at + length
        if len(buf) < end:
            return None
        if length:
            with memoryview(buf) as view:
                payload = self._unmask(view[payload_at - 4:payload_at].tobytes(), view[payload_at:end])
        else:
            payload = b""
        if end == len(buf):  # all taken: what the last frames held goes now, not with the next read
            buf.clear()
            end = 0
        self._start = end
        if opcode & 0x8:
            return self._control(opcode, payload)
        if opcode != CONTINUATION:
            self._opcode, self._compressed = opcode, bool(first & _RSV1)
            if not first & _FIN:
                self._parts, self._parts_weight = bytearray(payload), length + PART_COST
                return PART, None, length
        else:
            self._parts += payload
            self._parts_weight += length + PART_COST
            if not first & _FIN:
                return PART, None, length
            payload, self._parts = bytes(self._parts), None
        size = length
        if self._compressed:  # weighed as what it unpacks to, less what its earlier frames weighed
            earlier = len(payload) - length
            payload = self._inflate(payload)
            size = max(length, len(payload) - earlier)
        if self._opcode == TEXT:
            try:
                return TEXT, payload.decode(), size
            except UnicodeDecodeError:
                raise ProtocolError(INVALID_DATA, "text message is not valid UTF-8") from None
        return BINARY, payload, size

    def _inflate(self, payload):
        """A compressed message unpacked by an inflater of its own, dropped after it: the client keeps no context
        between its messages either (client_no_context_takeover, in our answer). Some clients keep it anyway
        (Tornado 6.2's parser drops the answer's parameters that have no value): a message that points back
        before its start is unpacked again from the end of what the client's earlier compressed messages held,
        kept here as bytes (a client's requests are small; 2 * CONTEXT_BYTES at most)."""
        try:
            data = self._unpack(payload)
        except zlib.error as error:
            if not self._inflated:
                raise ProtocolError(INVALID_DATA, f"compressed message cannot be unpacked ({error})") from None
            try:
                data = self._unpack(payload, bytes(self._inflated[-CONTEXT_BYTES:]))
            except zlib.error as error:
                raise ProtocolError(INVALID_DATA, f"compressed message cannot be unpacked ({error})") from None
        inflated = self._inflated
        inflated += data[-CONTEXT_BYTES:]
        if len(inflated) > 2 * CONTEXT_BYTES:  # (trimmed once per CONTEXT_BYTES taken: a byte copied per byte)
            del inflated[:-CONTEXT_BYTES]
        return data

    def _unpack(self, payload, context=b""):
        inflater = zlib.decompressobj(-15, zdict=context) if context else zlib.decompressobj(-15)
        data = inflater.decompress(payload + _DEFLATE_TAIL, self.max_size + 1)
        if len(data) > self.max_size or inflater.unconsumed_tail:
            raise ProtocolError(TOO_BIG, "message too big (unpacked)")
        return data

    def _control(self, opcode, payload):
        if opcode != CLOSE:
            return opcode, payload, len(payload)
        if not payload:
            return CLOSE, (NO_STATUS, ""), 0
        if len(payload) < 2:
            raise ProtocolError(PROTOCOL_ERROR, "close frame with a 1-byte payload")
        (code,) = _CODE.unpack_from(payload)
        if code not in _SENDABLE_CODES and not 3000 <= code <= 4999:
            raise ProtocolError(PROTOCOL_ERROR, f"invalid close code {code}")
        try:
            reason = payload[2:].decode()
        except UnicodeDecodeError:
            raise ProtocolError(INVALID_DATA, "close reason is not valid UTF-8") from None
        return CLOSE, (code, reason), len(payload)
