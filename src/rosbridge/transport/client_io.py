"""A websocket client's bytes in and out, after the handshake, for a ClientConnection (connection.py): what it
received, what it writes, when the socket has taken everything, when the client has gone. Two kinds, one
interface (ClientIO):

- PlainSocket, for a plain TCP client: the socket itself, read and written by a handler of the loop's
  (IOLoop.add_handler, as ros_side/links.py reads a publisher). Each read hands its bytes over in the same turn of
  the loop, and a read is asked again without a system call while the socket stays watched. Tornado's read_bytes
  costs a future, a second turn of the loop and a second recv, which met EAGAIN, for every message a client sends
  (profiled: two of each per message at 1 kHz).
- TlsStream, for a TLS client: Tornado's SSLIOStream (the SSL object's state is the stream's own).

Loop thread only. The callbacks: received(bytes) for each read asked (read()), drained() once a write that
waited has gone (after when_drained()), closed() once, in a later turn, when the connection has ended (the client
left, a read or write failed, or close())."""

import collections
import socket
import time
from typing import Protocol

import tornado.ioloop
import tornado.iostream

from rosbridge.transport.unsent import limit_unsent

READ_CHUNK = 64 * 1024  # bytes asked of a client's socket per read: every frame complete in them is taken at once
# What the socket did not take at once leaves in pieces of at most this many bytes (by reference). Each piece
# written is progress, so that a slow link taking a map for longer than websocket_ping_timeout is not taken for one
# that stopped reading (TLS: Tornado's stream). A plain socket is handed one piece each time it is writable. Handed
# an image's whole remainder instead, it came up short on a third of the next images' first sends, against 1.5 % in
# pieces (bench, twenty clients on loopback), and each short send costs more turns and system calls.
WRITE_PIECE_BYTES = 64 * 1024
SEND_BUFFERS = 64  # unsent buffers handed to the kernel in one sendmsg (small frames that waited)


class ClientIO(Protocol):
    progressed_at: float | None
    """When the socket last took some of what waited for it (time.monotonic)."""

    def start(self, answer: bytes) -> bool:
        """Writes the handshake's answer; False if the client has left already."""

    def read(self) -> bool:
        """Asks for the client's next bytes (received, once); False if the connection has ended."""

    def write(self, data: bytes | memoryview) -> None:
        """Sends data, kept by reference while the socket has not taken it; nothing once the connection ended."""

    def writing(self) -> bool:
        """Some of what was written waits for the socket."""

    def when_drained(self) -> None:
        """drained() once what waits now has gone (not if the connection ends first)."""

    def close_once_written(self) -> None:
        """Closes once what waits has gone (the close callback ends the waiting otherwise)."""

    def close(self) -> None:
        """Closes now, dropping what waits."""

    def closed(self) -> bool: ...


def client_io(stream, received, drained, closed) -> ClientIO:
    """The connection's bytes for a stream Tornado detached from its HTTP request (handshake.BridgeSocket)."""
    if type(stream) is tornado.iostream.IOStream:
        return PlainSocket(stream, received, drained, closed)
    return TlsStream(stream, received, drained, closed)


class PlainSocket:
    """A plain TCP client's socket, read and written on the loop by its own handler. Tornado's stream, detached from
    the handshake's request, stays open but unused until the end: it owns the socket object, and it is what the
    server counts as the address's connection while it is open (accepting.BoundedHTTPServer)."""

    def __init__(self, stream, received, drained, closed):
        self._stream, self._sock = stream, stream.socket
        self._received, self._drained, self._on_closed = received, drained, closed
        self._loop = tornado.ioloop.IOLoop.current()
        self._events = 0  # what the loop watches the socket for (IOLoop.READ | IOLoop.WRITE)
        self._reading = False  # a read is asked
        self._early = None  # bytes the stream had read before the handshake's answer
        self._unsent = collections.deque()  # what the socket has not taken yet, in order (by reference)
        self._drain_wanted = False
        self._close_when_written = False
        self._closed = False
        self.progressed_at = None

    def start(self, answer):
        stream = self._stream
        try:
            # A client must wait for the answer before it sends anything (RFC 6455 4.1); what one sent anyway, and
            # Tornado read, is taken as the first bytes.
            early = stream.read_bytes(READ_CHUNK, partial=True)
        except tornado.iostream.StreamClosedError:
            return False
        if early.done():
            self._early = early.result()
        # (the stream's own watch of the socket ends: its handler, and a read left waiting, never run again)
        self._loop.remove_handler(self._sock)
        self._loop.add_handler(self._sock, self._on_events, 0)
        try:
            self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except OSError:
            self.close()
            return False
        limit_unsent(self._sock)
        self.write(answer)
        return not self._closed

    def read(self):
        if self._closed:
            return False
        self._reading = True
        if self._early is not None:
            early, self._early = self._early, None
            self._loop.add_callback(self._received_early, early)
        else:
            self._watch(self._events | self._loop.READ)
        return True

    def _received_early(self, early):
        if self._reading:  # (not closed meanwhile)
            self._reading = False
            self._received(early)

    def _watch(self, events):
        if events != self._events and not self._closed:
            self._events = events
            self._loop.update_handler(self._sock, events)

    def _on_events(self, fd, events):
        if events & self._loop.WRITE:
            self._send_unsent()
        if events & self._loop.READ and self._reading:
            self._read_once()

    def _read_once(self):
        try:
            data = self._sock.recv(READ_CHUNK)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            self.close()
            return
        if not data:  # the client closed its side
            self.close()
            return
        self._reading = False
        self._received(data)
        if not self._reading:  # (asked again meanwhile: the socket stays watched, with no system call)
            self._watch(self._events & ~self._loop.READ)

    def write(self, data):
        if self._closed or not data:
            return
        if not self._unsent:
            try:
                sent = self._sock.send(data)
            except (BlockingIOError, InterruptedError):
                sent = 0
            except OSError:
                self.close()
                return
            if sent == len(data):
                return
            data = memoryview(data)[sent:]
            self._watch(self._events | self._loop.WRITE)
        self._unsent.append(data)

    def _send_unsent(self):
        unsent, piece, room = self._unsent, [], WRITE_PIECE_BYTES
        for data in unsent:
            if len(data) >= room:
                piece.append(memoryview(data)[:room])
                break
            piece.append(data)
            room -= len(data)
            if len(piece) == SEND_BUFFERS:
                break
        try:
            sent = self._sock.sendmsg(piece)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            self.close()
            return
        self.progressed_at = time.monotonic()
        while unsent:
            size = len(unsent[0])
            if size > sent:
                if sent:
                    unsent[0] = memoryview(unsent[0])[sent:]
                break
            unsent.popleft()
            sent -= size
        if unsent:
            return
        self._watch(self._events & ~self._loop.WRITE)
        if self._close_when_written:
            self.close()
        elif self._drain_wanted:
            self._drain_wanted = False
            self._drained()

    def writing(self):
        return bool(self._unsent)

    def when_drained(self):
        self._drain_wanted = True

    def close_once_written(self):
        if self._unsent:
            self._close_when_written = True
        else:
            self.close()

    def close(self):
        if self._closed:
            return
        self._closed, self._reading, self._early = True, False, None
        self._unsent.clear()
        self._loop.remove_handler(self._sock)
        self._stream.close()  # (it closes the socket, and the server counts the connection gone)
        self._loop.add_callback(self._on_closed)

    def closed(self):
        return self._closed


class TlsStream:
    """A TLS client's connection: Tornado's stream, through its public API."""

    def __init__(self, stream, received, drained, closed):
        self._stream, self._received, self._drained = stream, received, drained
        self._last = None  # the future of the latest write
        self.progressed_at = None
        stream.set_close_callback(closed)

    def start(self, answer):
        try:
            self._stream.set_nodelay(True)
            limit_unsent(self._stream.socket)
            self._last = self._stream.write(answer)
        except tornado.iostream.StreamClosedError:
            return False
        return True

    def read(self):
        try:
            self._stream.read_bytes(READ_CHUNK, partial=True).add_done_callback(self._read_done)
        except tornado.iostream.StreamClosedError:
            return False
        return True

    def _read_done(self, read):
        if not (read.cancelled() or read.exception() is not None):  # (else the close callback comes)
            self._received(read.result())

    def write(self, data):
        stream = self._stream
        try:
            if len(data) <= WRITE_PIECE_BYTES:
                self._last = stream.write(data)
                return
            view = memoryview(data)
            for start in range(0, len(view), WRITE_PIECE_BYTES):
                self._last = stream.write(view[start : start + WRITE_PIECE_BYTES])
                self._last.add_done_callback(self._progressed)
        except tornado.iostream.StreamClosedError:  # (the close callback comes)
            pass

    def _progressed(self, _):
        self.progressed_at = time.monotonic()

    def writing(self):
        return self._stream.writing()

    def when_drained(self):
        self._last.add_done_callback(self._written)

    def _written(self, written):
        if not (written.cancelled() or written.exception() is not None):
            self._drained()

    def close_once_written(self):
        stream = self._stream
        if self._last is None:
            stream.close()
        else:  # (writes end in order: the latest's end is everyone's)
            self._last.add_done_callback(lambda _: stream.close())

    def close(self):
        self._stream.close()

    def closed(self):
        return self._stream.closed()
