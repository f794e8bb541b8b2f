"""Reading a websocket client's frames: Tornado's RFC 6455 protocol (handshake, writing, closing, ping and pong,
permessage-deflate), with its reading replaced.

Tornado's frame loop (`WebSocketProtocol13._receive_frame`) awaits a stream read for each piece of each frame.
A read that has to wait costs a future, a task step in a later turn of the loop and a recv that finds nothing
first: at a fixed rate, where every message waits, that was most of the work of taking a small message
(bench/README.md). Here the loop's readiness callback reads the socket once and parses every frame complete in
what it has, with no future and no task step; and every frame a client sends, pings included, counts against
its budget (budget.py): over budget, the socket is left unread for a while, and the kernel holds the client
back."""
import struct
import zlib

import tornado.iostream
import tornado.websocket
from tornado.concurrent import Future
from tornado.util import _websocket_mask

from rosbridge.errors import log_bug

READ_CHUNK = 64 * 1024  # bytes read from a client per wake: every frame complete in them is taken at once
# Every client's reads go into this one buffer: they all happen on the loop's thread, one at a time, and what a
# read brought is copied out (FairProtocol._take) before any other read (a buffer per client: 64 KB each).
_read_buffer = bytearray(READ_CHUNK)
_LENGTH_16, _LENGTH_64 = struct.Struct("!H"), struct.Struct("!Q")


class _LoopReading:
    """For a client's stream (IOStream or SSLIOStream): its reading driven by the loop. Each time the socket is
    readable, one read, handed to `take(data)` (data: valid only during the call); paused, the socket is not
    watched for reading. Writing and closing are the stream's own."""

    def read_to(self, take):
        self._take, self._paused = take, False
        if self._state is not None:  # watched already, with IOStream's own _handle_events as the handler
            self.io_loop.remove_handler(self.fileno())
            self._state = None
        self._watch()
        if self._buffered():  # (decrypted with the handshake's last read)
            self._read()

    def pause(self):
        self._paused = True
        self._watch()

    def resume(self):
        self._paused = False
        self._watch()

    def _watch(self):
        """Watches the socket for what is wanted now: reading unless paused, writing while data waits."""
        if self.closed():
            return
        loop = self.io_loop
        state = loop.ERROR | (0 if self._paused else loop.READ) | (loop.WRITE if self.writing() else 0)
        if self._state is None:
            self._state = state
            loop.add_handler(self.fileno(), self._handle_events, state)
        elif state != self._state:
            self._state = state
            loop.update_handler(self.fileno(), state)

    def _handle_events(self, fd, events):
        if self.closed():
            return
        try:
            if events & self.io_loop.READ and not self._paused:
                self._read()
                if self.closed():
                    return
            if events & self.io_loop.WRITE:
                self._handle_write()
                if self.closed():
                    return
            self._watch()  # (Tornado's asyncio loop reports READ and WRITE only: errors show as either)
        except OSError as error:  # the connection broke
            self.close(exc_info=error)
        except Exception as error:  # a bug: this client is dropped, the loop goes on
            self.close(exc_info=error)
            raise

    def stop_reading(self):
        """The connection is over: drop the reader (and with it the protocol's buffers)."""
        self._take = None

    def _read(self):
        while True:
            count = self.read_from_fd(_read_buffer)  # (None: nothing to read after all)
            if count == 0:  # the client closed its end
                self.close()
                return
            if count is None:
                return
            with memoryview(_read_buffer) as view, view[:count] as data:
                self._take(data)
            if self.closed() or self._paused or not self._buffered():
                return

    def _buffered(self):
        return False


class ClientStream(_LoopReading, tornado.iostream.IOStream):
    pass


class TlsClientStream(_LoopReading, tornado.iostream.SSLIOStream):
    def _buffered(self):
        """Decrypted bytes the SSL layer holds: the socket's readiness does not show them."""
        return self.socket.pending() > 0


class FairProtocol(tornado.websocket.WebSocketProtocol13):
    """Tornado's protocol reading through a ClientStream or TlsClientStream (see the module). All of it runs on
    the loop's thread."""

    async def _receive_frame_loop(self):
        """Reads until the connection is closed (by either side, or lost); then tells the handler."""
        stream = self.stream
        closed = Future()
        stream.set_close_callback(lambda: closed.done() or closed.set_result(None))
        self._unparsed = bytearray()  # read, not parsed yet: the rest of one read, and a frame not complete yet
        self._resume_timer = None
        try:
            if stream._read_buffer_size:  # what came with the handshake, read by Tornado already
                self._unparsed += await stream.read_bytes(stream._read_buffer_size)
        except tornado.iostream.StreamClosedError:
            pass
        if not stream.closed():
            stream.__class__ = TlsClientStream if isinstance(stream, tornado.iostream.SSLIOStream) else ClientStream
            stream.read_to(self._take)
            self._parse()
            await closed
            stream.stop_reading()
        if self._resume_timer is not None:
            stream.io_loop.remove_timeout(self._resume_timer)
        self._unparsed, self._fragmented_message_buffer = bytearray(), None
        self._abort()
        self.handler.on_ws_connection_close(self.close_code, self.close_reason)

    def _take(self, data):
        """What one read brought (data: valid during the call only)."""
        self._wire_bytes_in += len(data)
        self._unparsed += data
        self._parse()

    def _resume(self):
        self._resume_timer = None
        self.stream.resume()
        self._parse()

    def _parse(self):
        """Takes every complete frame in the unparsed bytes, until the client is over its budget: then it waits
        (for 0 s: the others get a turn first) with its socket unread, or for 0 s with at most one more read."""
        if self._resume_timer is not None:
            return
        unparsed, start = self._unparsed, 0
        try:
            while not self.client_terminated and not self.stream.closed():
                taken = self._frame(unparsed, start)
                if taken is None:
                    break
                start, delay = taken
                if delay is not None:
                    if delay:
                        self.stream.pause()
                    self._resume_timer = self.stream.io_loop.call_later(delay, self._resume)
                    break
        except (UnicodeDecodeError, zlib.error):  # a close frame's reason, or deflated data, that is broken
            self._abort()
        except Exception:  # a bug: this client is dropped, the others go on
            log_bug("reading a websocket client's frames")
            self._abort()
        finally:
            del unparsed[:start]

    def _frame(self, buf, start):
        """The frame at `start`, if complete: handled, then (where the next starts, how long the client must wait
        before the next is read or None); None if incomplete or the connection was aborted."""
        available = len(buf) - start
        if available < 2:
            return None
        first, second = buf[start], buf[start + 1]
        is_final = first & self.FIN
        reserved = first & self.RSV_MASK
        opcode = first & self.OPCODE_MASK
        if self._decompressor is not None and opcode != 0:  # (compressed: flagged in a message's first frame)
            self._frame_compressed = bool(reserved & self.RSV1)
            reserved &= ~self.RSV1
        length, head = second & 0x7F, 2
        if reserved or (opcode & 0x8 and (length >= 126 or not is_final)):  # unknown extension; bad control frame
            self._abort()
            return None
        if length == 126:
            if available < 4:
                return None
            (length,), head = _LENGTH_16.unpack_from(buf, start + 2), 4
        elif length == 127:
            if available < 10:
                return None
            (length,), head = _LENGTH_64.unpack_from(buf, start + 2), 10
        fragmented = self._fragmented_message_buffer
        if length + (len(fragmented) if fragmented is not None else 0) > self.params.max_message_size:
            self.close(1009, "message too big")
            self._abort()
            return None
        masked = second & 0x80
        payload_at = start + head + (4 if masked else 0)
        end = payload_at + length
        if len(buf) < end:
            return None
        data = bytes(memoryview(buf)[payload_at:end])
        if masked:
            data = _websocket_mask(bytes(buf[payload_at - 4:payload_at]), data)
        if opcode == 0:  # continuation
            if fragmented is None:
                self._abort()
                return None
            fragmented += data
            if is_final:
                opcode, data = self._fragmented_message_opcode, bytes(fragmented)
                self._fragmented_message_buffer = None
        elif not opcode & 0x8:  # a new data message
            if fragmented is not None:
                self._abort()
                return None
            if not is_final:
                self._fragmented_message_opcode, self._fragmented_message_buffer = opcode, bytearray(data)
        if is_final:
            unpacked = self._message_bytes_in
            self._handle_message(opcode, data)
            # a deflated message counts as what it unpacks to (Tornado adds that to _message_bytes_in)
            length = max(length, self._message_bytes_in - unpacked)
        return end, self.handler.budget.after_frame(length)
