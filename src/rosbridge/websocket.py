"""One websocket client on the event loop: reads its frames in turns with the other clients (budget.py), feeds
them to its protocol Session, and writes the Session's frames as fast as the client reads them."""
import struct
import time

import tornado.ioloop
import tornado.iostream
import tornado.web
import tornado.websocket

from rosbridge import protocol
from rosbridge.budget import ClientBudget
from rosbridge.encoding import BIG_BYTES
from rosbridge.errors import log_bug
from rosbridge.frames import SplicedFrame, Utf8Text
from rosbridge.origins import origin_allowed
from rosbridge.pages import SECURITY_HEADERS
from rosbridge.websocket_protocol import FairProtocol

# Frames waiting for a client go to its socket together, up to this many bytes per write: one system call for a
# burst of small messages instead of one each.
WRITE_BATCH_BYTES = 64 * 1024


class BridgeSocket(tornado.websocket.WebSocketHandler):
    """One rosbridge client; a plain HTTP GET (or HEAD) of the same URL gets the index page instead."""

    def initialize(self, bridge, index_page=None):
        self.bridge, self.index_page = bridge, index_page
        self.session = None
        self.budget = None
        self._close_reason = None
        self._loop = None
        self._awaiting_drain = False  # frames were written that the socket has not taken yet

    def set_default_headers(self):
        for name, value in SECURITY_HEADERS.items():
            self.set_header(name, value)

    async def get(self, *args, **kwargs):
        if self.request.headers.get("Upgrade", "").lower() != "websocket":
            if self.index_page is None:
                raise tornado.web.HTTPError(404)
            self.set_header("Content-Type", "text/html; charset=UTF-8")
            self.finish(self.index_page.read_bytes())
            return
        if len(self.bridge.clients) >= self.bridge.settings.max_clients:
            self.bridge.log_refusal("max_clients", f"a client refused: {len(self.bridge.clients)} connected "
                                    f"(max_clients {self.bridge.settings.max_clients})")
            self.set_status(503)
            self.finish("too many clients")
            return
        await super().get(*args, **kwargs)

    def head(self, *args, **kwargs):
        if self.index_page is None:
            raise tornado.web.HTTPError(404)
        self.set_header("Content-Type", "text/html; charset=UTF-8")
        self.set_header("Content-Length", self.index_page.stat().st_size)
        self.finish()

    def get_websocket_protocol(self):
        websocket = super().get_websocket_protocol()
        if websocket is not None:
            websocket.__class__ = FairProtocol  # same state and settings, its own reading (websocket_protocol.py)
        return websocket

    def check_origin(self, origin):
        peer = self.request.remote_ip
        if origin_allowed(origin, super().check_origin(origin), peer, self.bridge.allowed_origins):
            return True
        self.bridge.refused_origin(origin, peer)
        return False

    def get_compression_options(self):
        return {} if self.bridge.settings.use_compression else None

    def open(self, *args):
        loop = self._loop = tornado.ioloop.IOLoop.current()
        settings = self.bridge.settings
        self.budget = ClientBudget(settings.max_frames_per_second, settings.max_bytes_per_second, time.monotonic)
        self.session = protocol.Session(self.bridge.backend, self.bridge.config, time.time, loop.call_later,
                                        self._wake, self._close_after_sending, name=self.request.remote_ip)
        self.set_nodelay(True)
        self.bridge.client_opened(self)

    def on_message(self, message):
        if isinstance(message, bytes):
            self.session.handle_binary(message)
        else:
            self.session.handle_text(message)

    def on_ping(self, data):
        # Tornado has queued the pong: a client that pings but never reads would grow that buffer forever
        stream = self.ws_connection.stream if self.ws_connection is not None else None
        if stream is not None and not stream.closed() \
                and len(stream._write_buffer) > self.bridge.config.max_queue_bytes:
            self.close(1008, "not reading (pongs piling up)")

    def on_close(self):
        if self.session is not None:
            self.session.closed()
        self.bridge.client_closed(self)

    def _wake(self):
        self._loop.add_callback(self._flush)

    def _close_after_sending(self, reason):
        self._close_reason = reason
        self._wake()

    def _flush(self):
        """Writes the session's queued frames until the socket is backed up, then resumes when it has
        drained: a slow client's backlog stays in the session's bounded queue, not in Tornado's buffer."""
        if self._awaiting_drain:
            return  # _drained flushes again
        conn, session = self.ws_connection, self.session
        one_at_a_time = bool(self.bridge.settings.delay_between_messages)
        while conn is not None and not conn.is_closing():
            frames, size = [], 0
            while size < WRITE_BATCH_BYTES:
                frame = session.take_frame()
                if frame is None:
                    break
                if isinstance(frame, str):
                    try:
                        frame = Utf8Text(frame.encode())
                    except UnicodeEncodeError:  # a bug (dumps escapes what UTF-8 lacks): skip it, go on
                        log_bug("encoding an outgoing frame")
                        continue
                frames.append(frame)
                size += len(frame)
                if one_at_a_time:
                    break
            if frames:
                try:
                    written = self._write(conn, frames)
                except (tornado.iostream.StreamClosedError, tornado.websocket.WebSocketClosedError):
                    return
                if conn.stream.writing():
                    self._awaiting_drain = True
                    written.add_done_callback(self._drained)
                    return
            if frame is None:  # the queue is empty: the next frame queued wakes us again
                if self._close_reason is not None:
                    self.close(1008, self._close_reason)
                return
            if one_at_a_time:
                self._loop.call_later(self.bridge.settings.delay_between_messages, self._flush)
                return

    def _drained(self, written):
        self._awaiting_drain = False
        if not written.cancelled() and written.exception() is None:
            self._flush()

    def _write(self, conn, frames):
        """Sends frames; returns the stream's write future. Without permessage-deflate they go straight to the
        stream, small ones joined in one write, a big payload or part (an image) by reference, not copied: the
        same bytes for every client, and none of the Task that write_message wraps around each frame."""
        if self.bridge.settings.use_compression:
            for frame in frames:
                written = self.write_message(bytes(frame) if isinstance(frame, SplicedFrame) else frame,
                                             binary=_is_binary(frame))
            return written
        stream, joined = conn.stream, []
        for frame in frames:
            if isinstance(frame, SplicedFrame):
                parts, size = frame.parts, len(frame)
            else:
                parts, size = (frame,), len(frame)
            joined.append(websocket_header(size, 0x2 if _is_binary(frame) else 0x1))
            for part in parts:
                if len(part) < BIG_BYTES:
                    joined.append(part)
                else:
                    stream.write(b"".join(joined))
                    joined.clear()
                    stream.write(part)
        return stream.write(b"".join(joined))  # (done once everything before it is written too)


def _is_binary(frame):
    if isinstance(frame, SplicedFrame):
        return not frame.text
    return not isinstance(frame, str) and not isinstance(frame, Utf8Text)


def websocket_header(length, opcode):
    """The header of an unmasked, unfragmented server-to-client websocket frame (RFC 6455 section 5.2)."""
    if length < 126:
        return struct.pack("!BB", 0x80 | opcode, length)
    if length <= 0xFFFF:
        return struct.pack("!BBH", 0x80 | opcode, 126, length)
    return struct.pack("!BBQ", 0x80 | opcode, 127, length)
