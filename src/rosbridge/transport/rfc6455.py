"""RFC 6455 websockets, server side, without I/O (as h11 is for HTTP, or tcpros.FrameReader for TCPROS): the
opening handshake's answer, a FrameReader that turns what a client sent into its messages and control frames,
and the bytes of the server's own frames; permessage-deflate (RFC 7692) both ways, each message on its own: the
answer asks the client to keep no context between its messages (client_no_context_takeover) and we keep none
(server_no_context_takeover), so that nothing of zlib's lives per client between messages (a thousand idle clients
hold no compressor or inflater), and a message deflated once is the same bytes for every client. Pure: no tornado,
no sockets; the shell (transport/connection.py) moves the bytes and chooses which messages go deflated.

A client's frames come out one event per frame, so that whoever reads can weigh every frame a client sends
(budget.py), the parts of a fragmented message and the control frames included."""

import base64
import hashlib
import struct
import time
import zlib

CONTINUATION, TEXT, BINARY, CLOSE, PING, PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA
PART = -1  # the event of a frame that only carries part of a message
_FIN, _RSV1, _RESERVED, _MASKED = 0x80, 0x40, 0x70, 0x80

# close codes (RFC 6455 section 7.4.1)
NORMAL, GOING_AWAY, PROTOCOL_ERROR, NO_STATUS, INVALID_DATA, POLICY, TOO_BIG = 1000, 1001, 1002, 1005, 1007, 1008, 1009
TRY_AGAIN = 1013
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
INFLATE_SLICE = 1 << 16  # bytes a client's compressed message is unpacked by at a time: well under a millisecond
OWN_BYTES = 1 << 17  # what a client's unfinished message may hold before it counts against the shared bound: about
# one read and a frame begun, so that the many clients that are mid-frame for a moment never draw on it
RECENT = 1.0  # s: a holder of the shared bound is judged by the bytes it received in the last one to two of these


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


def choose_subprotocol(offers, ours):
    """The subprotocol to answer a client's Sec-WebSocket-Protocol header with: the first it offers that is one of
    `ours`, or None (then the header is not answered, and the client gets the default protocol)."""
    for offer in offers.split(","):
        if offer.strip() in ours:
            return offer.strip()
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
            if key in asked or key not in (
                "server_no_context_takeover",
                "client_no_context_takeover",
                "server_max_window_bits",
                "client_max_window_bits",
            ):
                ok = False
            asked[key] = value
        server_bits, client_bits = asked.get("server_max_window_bits", "15"), asked.get("client_max_window_bits")
        if (
            not ok
            or not (server_bits.isdigit() and int(server_bits) in _WINDOW_BITS)
            or client_bits
            and not (client_bits.isdigit() and 8 <= int(client_bits) <= 15)
        ):
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
    data.append(compressor.flush(zlib.Z_SYNC_FLUSH)[: -len(_DEFLATE_TAIL)])  # (a sync flush ends with the tail)
    return b"".join(data)


# the header of each binary frame shorter than 126 bytes, by its length: a Foxglove client's small message (a Twist's
# is 61 bytes) takes its header from here, a fifth of what making it costs
SHORT_PAYLOAD = 126  # payloads shorter than this have their length in the header's second byte
SHORT_BINARY_HEADERS = tuple(bytes((_FIN | BINARY, length)) for length in range(SHORT_PAYLOAD))


def frame_header(length, opcode, compressed=False):
    """The header of a server frame: unmasked, final (RFC 6455 section 5.2)."""
    first = _FIN | opcode | (_RSV1 if compressed else 0)
    if length < SHORT_PAYLOAD:
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


class SharedBound:
    """What the unfinished messages of every client hold together, in bytes: at most `limit`. Its holders are each
    client's FrameReader (beyond OWN_BYTES) and its Session's `fragment` ops (reassembly.Fragments), each with an
    evict() that lets go of all it holds. When a holder would go beyond the limit, the holders whose bytes came
    slower lately make way: those that received fewer in the last RECENT to 2 * RECENT seconds than the one asking
    are evicted, the slowest first, if that makes room; else the one asking is refused. So a client stalled in the
    middle of a message (or trickling it) keeps no one out for long, and one whose bytes keep coming (a phone's
    slow upload) makes way only for a faster one."""

    def __init__(self, limit, clock=time.monotonic):
        self.limit, self.held, self._clock = limit, 0, clock
        self._holders = {}  # holder -> its _Holding

    def hold(self, holder, count):
        """`holder` now holds `count` bytes (0: nothing). False if that is refused: it then holds what it held."""
        holding = self._holders.get(holder)
        before = holding.count if holding is not None else 0
        if count <= before:
            if count:
                holding.count = count
            elif holding is not None:
                del self._holders[holder]
            self.held -= before - count
            return True
        now = self._clock()
        if holding is None:
            holding = self._holders[holder] = _Holding(now)
        holding.arrived(count - before, now)
        over = self.held + count - before - self.limit
        if over > 0 and not self._make_room(holder, holding.recent(now), over, now):
            if not before:
                del self._holders[holder]
            return False
        self.held += count - before
        holding.count = count
        return True

    def _make_room(self, asking, pace, needed, now):
        slower = sorted(
            (
                (holding.recent(now), holding.count, holder)
                for holder, holding in self._holders.items()
                if holder is not asking and holding.recent(now) < pace
            ),
            key=lambda item: item[0],
        )
        evicted, freed = [], 0
        for _, count, holder in slower:
            if freed >= needed:
                break
            evicted.append(holder)
            freed += count
        if freed < needed:
            return False
        for holder in evicted:
            self.held -= self._holders.pop(holder).count
            holder.evict()
        return True


class _Holding:
    """What one holder of a SharedBound holds, and the bytes it received lately (in the window begun at `since`,
    and the one before it)."""

    __slots__ = ("count", "since", "now_bytes", "before_bytes")

    def __init__(self, now):
        self.count, self.since, self.now_bytes, self.before_bytes = 0, now, 0, 0

    def arrived(self, size, now):
        self._roll(now)
        self.now_bytes += size

    def recent(self, now):
        self._roll(now)
        return self.now_bytes + self.before_bytes

    def _roll(self, now):
        if now - self.since >= RECENT:
            self.before_bytes = self.now_bytes if now - self.since < 2 * RECENT else 0
            self.now_bytes, self.since = 0, now


class FrameReader:
    """The frames of one client. `receive(data)` takes what was read; each `next_event()` gives the next frame's
    event, or None until more bytes come:
      (TEXT, str, size)    a whole text message (UTF-8 checked)
      (BINARY, bytes, size) a whole binary message
      (PART, None, size)   a frame holding part of a message that is not complete yet, or a slice of a
                           compressed frame unpacked
      (PING, bytes, size), (PONG, bytes, size)
      (CLOSE, (code, reason), size)    code NO_STATUS if the client gave none
    size: the frame's payload bytes; for a compressed frame, unpacked INFLATE_SLICE bytes at a time, each slice's
    event weighs what it unpacked (or the compressed bytes it took, if more), so that whoever reads counts the
    unpacking in the client's budget and serves other clients between slices. A frame that breaks the protocol
    raises ProtocolError, and so do a message over max_size bytes (TOO_BIG, before its payload is read), a
    compressed one unpacking to more than max_inflated (TOO_BIG, as soon as it does), and one that would take the
    unfinished messages of every client beyond their shared bound (TRY_AGAIN); the reader is done after that.
    A reader whose unfinished message makes way for a faster one (SharedBound) lets go of everything and calls
    `evicted` (the shell closes the connection).

    What it holds: at most one incomplete frame (max_size bytes) and the bytes given to it beyond that, which
    the shell keeps small by reading only when next_event() has said None; one message being put together
    (max_size bytes, each of its frames counted PART_COST more; a compressed one max_inflated bytes unpacked,
    and the zlib object unpacking it); no zlib object between messages, and the end of what the client's
    compressed messages held, 2 * CONTEXT_BYTES at most (see _start_inflating). While a message is unfinished
    (unfinished_since), what it holds beyond OWN_BYTES counts against `shared` (a SharedBound, if given)."""

    def __init__(
        self,
        max_size,
        deflate=False,
        unmask=xor_mask,
        max_inflated=None,
        shared=None,
        evicted=None,
        clock=time.monotonic,
    ):
        self.max_size, self._unmask = max_size, unmask
        self.max_inflated = max_size if max_inflated is None else max_inflated
        self._buffer = bytearray()
        self._start = 0  # where the next frame starts in _buffer
        self._parts = None  # the message being put together from its frames (bytearray; unpacked), or None
        self._parts_weight = 0  # what those frames count against max_size: their bytes, and PART_COST each
        self._opcode = None  # the opcode of that message
        self._compressed = False  # whether it is compressed
        self._deflate = deflate  # permessage-deflate negotiated: each compressed message inflated on its own
        self._inflater = None  # the zlib object of the compressed message being read
        self._input = None  # the compressed frame being unpacked (its payload), or None
        self._input_at = 0  # how much of it was given to the inflater
        self._final = False  # whether it is the message's last frame
        self._inflated = bytearray()  # the end of what the client's compressed messages held (_start_inflating)
        self._shared, self._held, self._clock = shared, 0, clock  # (_held: what this reader counts in _shared)
        self._evicted = evicted
        self._since = None  # when the message being received began to arrive

    @property
    def buffered(self):
        """Bytes received and not taken yet."""
        return len(self._buffer) - self._start

    @property
    def unfinished_since(self):
        """When (by the clock) the first bytes of the message being received came, or None between messages:
        what the shell expires."""
        return self._since

    def receive(self, data):
        if self._start:
            del self._buffer[: self._start]
            self._start = 0
        self._buffer += data

    def close(self):
        """Lets go of what it holds (the connection ended), its part of the shared bound too."""
        self._hold(0)
        self._buffer, self._start, self._parts, self._inflater, self._input = bytearray(), 0, None, None, None

    def evict(self):
        """The shared bound took back what this reader held, for a client whose bytes come faster: it lets go of
        the rest and says so."""
        self._held = 0
        self.close()
        if self._evicted is not None:
            self._evicted()

    def next_event(self):
        if self._input is not None:
            return self._inflate_step()
        buf, start = self._buffer, self._start
        available = len(buf) - start
        if available < 2:
            return self._incomplete(available)
        first, second = buf[start], buf[start + 1]
        opcode, length, head = first & 0x0F, second & 0x7F, 2
        if first & _RESERVED and not (first & _RESERVED == _RSV1 and self._deflate and opcode in (TEXT, BINARY)):
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
                return self._incomplete(available)
            (length,), head = _LENGTH_16.unpack_from(buf, start + 2), 4
        elif length == 127:
            if available < 10:
                return self._incomplete(available)
            (length,), head = _LENGTH_64.unpack_from(buf, start + 2), 10
        if length + (self._parts_weight + PART_COST if opcode == CONTINUATION else 0) > self.max_size:
            raise ProtocolError(TOO_BIG, "message too big")
        payload_at = start + head + 4
        end = payload_at + length
        if len(buf) < end:
            return self._incomplete(available)
        if length:
            with memoryview(buf) as view:
                payload = self._unmask(view[payload_at - 4 : payload_at].tobytes(), view[payload_at:end])
        else:
            payload = b""
        if end == len(buf):  # all taken: what the last frames held goes now, not with the next read
            buf.clear()
            end = 0
        self._start = end
        if opcode & 0x8:
            if self._parts is None:
                self._since = None
            return self._control(opcode, payload)
        fin = first & _FIN
        if opcode != CONTINUATION:
            self._opcode, self._compressed = opcode, bool(first & _RSV1)
            if self._compressed:
                self._start_inflating()
            elif fin:  # (a whole message in one frame: the usual case, kept short)
                return self._message(payload, length)
            else:
                self._parts, self._parts_weight = bytearray(), 0
        self._parts_weight += length + PART_COST
        if self._compressed:
            self._input, self._input_at, self._final = payload + _DEFLATE_TAIL if fin else payload, 0, fin
            return self._inflate_step()
        self._parts += payload
        if not fin:
            return self._part(length)
        payload, self._parts = bytes(self._parts), None
        return self._message(payload, length)

    def _incomplete(self, available):
        """None: the next frame is not all here yet; what it holds so far belongs to an unfinished message."""
        if available:
            if self._since is None:
                self._since = self._clock()
            self._hold(available + (len(self._parts) if self._parts is not None else 0))
        return None

    def _part(self, size):
        if self._since is None:
            self._since = self._clock()
        self._hold(len(self._parts))
        return PART, None, size

    def _message(self, payload, size):
        self._since = None
        if self._held:
            self._hold(0)
        if self._opcode == TEXT:
            try:
                return TEXT, payload.decode(), size
            except UnicodeDecodeError:
                raise ProtocolError(INVALID_DATA, "text message is not valid UTF-8") from None
        return BINARY, payload, size

    def _hold(self, count):
        """Counts `count` bytes held for the unfinished message (beyond OWN_BYTES) against the shared bound."""
        shared = self._shared
        if shared is None:
            return
        count = max(0, count - OWN_BYTES)
        if count == self._held:
            return
        if not shared.hold(self, count):
            raise ProtocolError(
                TRY_AGAIN, f"unfinished messages of all clients at their bound ({shared.limit} bytes): try again later"
            )
        self._held = count

    def _start_inflating(self):
        """A compressed message begins: an inflater of its own, dropped after it, since the client keeps no context
        between its messages either (client_no_context_takeover, in our answer). Some clients keep it anyway
        (Tornado 6.2's parser drops the answer's parameters that have no value), and their messages point back
        before their start: the inflater is given the end of what the client's earlier compressed messages held
        (kept here, 2 * CONTEXT_BYTES at most) as its dictionary, which changes nothing for a message that does
        not point back."""
        context = self._inflated[-CONTEXT_BYTES:]
        self._inflater = zlib.decompressobj(-15, zdict=context) if context else zlib.decompressobj(-15)
        self._parts, self._parts_weight = bytearray(), 0

    def _inflate_step(self):
        """Unpacks the next INFLATE_SLICE bytes of the compressed frame being read (its compressed bytes given
        INFLATE_SLICE at a time too, so that what zlib leaves unconsumed stays small): a PART, or the message
        once its last frame is all unpacked."""
        inflater, parts, packed = self._inflater, self._parts, self._input
        if inflater.eof:  # (a final block ended the message: what follows it is not part of it)
            data, fed, self._input_at = b"", len(packed) - self._input_at, len(packed)
        else:
            source, fed = inflater.unconsumed_tail, 0
            if not source:
                source = packed[self._input_at : self._input_at + INFLATE_SLICE]
                fed = len(source)
                self._input_at += fed
            asked = min(INFLATE_SLICE, self.max_inflated + 1 - len(parts))
            try:
                data = inflater.decompress(source, asked)
            except zlib.error as error:
                raise ProtocolError(INVALID_DATA, f"compressed message cannot be unpacked ({error})") from None
            if len(parts) + len(data) > self.max_inflated:
                raise ProtocolError(TOO_BIG, "message too big (unpacked)")
            parts += data
            inflated = self._inflated
            inflated += data[-CONTEXT_BYTES:]
            if len(inflated) > 2 * CONTEXT_BYTES:  # (trimmed once per CONTEXT_BYTES taken: a byte copied per byte)
                del inflated[:-CONTEXT_BYTES]
            if len(data) == asked or inflater.unconsumed_tail or self._input_at < len(packed):
                return self._part(max(fed, len(data)))  # (more to unpack from this frame)
        self._input = None
        if not self._final:
            return self._part(max(fed, len(data)))
        payload, self._parts, self._inflater = bytes(parts), None, None
        return self._message(payload, max(fed, len(data)))

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
