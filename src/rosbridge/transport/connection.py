"""The websocket clients on the event loop, after the handshake (handshake.BridgeSocket): a ClientConnection owns
the connection's bytes in and out (client_io: the socket itself, or Tornado's stream for TLS) and moves them
between it and two pure objects: rfc6455.FrameReader (what the client sent, frame by frame) and the client's
protocol session (a rosbridge protocol.Session, or a foxglove.FoxgloveSession: contract.ProtocolSession).

Threads: all of it runs on the loop's thread, but for deflating a big message for the clients whose link is slow
(slow_link.deflated_payload), which runs on the bridge's deflate thread (off_loop.EncodingThread, `bridge.deflater`,
apart from the encoder so that a map's encoding never holds a slow client's next frame): the thread only reads
the frame's bytes and returns new ones; the loop keeps them on the frame and resumes each client waiting for
them (its next frames wait meanwhile, and it counts as backed up)."""

import enum
import functools
import time

import tornado.ioloop

from rosbridge import borrowed, protocol
from rosbridge.codec import BIG_BYTES
from rosbridge.errors import log_bug
from rosbridge.foxglove import FoxgloveSession
from rosbridge.protocol.encoded import SplicedFrame, Utf8Text
from rosbridge.transport import rfc6455 as ws
from rosbridge.transport.client_io import client_io
from rosbridge.transport.slow_link import (
    DEFLATE_MIN_BYTES,
    LinkMeter,
    deflated_payload,
    deflates_some,
    sends_deflated,
)

# Frames waiting for a client go to its socket together, up to this many bytes per write: one system call for a
# burst of small messages instead of one each.
WRITE_BATCH_BYTES = 64 * 1024
_SHORT_HEADERS = ws.SHORT_BINARY_HEADERS
CLOSE_TIMEOUT = 5.0  # seconds a client has to answer our close frame before the connection is dropped


def frame_limit(settings):
    """The bytes a client's message may have on the wire: four times max_message_size, so that the Session
    refuses the ones between, politely (a status); 1 GB without max_message_size."""
    return 4 * settings.max_message_size or 1 << 30


def unfinished_bound(settings):
    """What the unfinished messages of all clients may hold together: one message at the frame limit (what
    the bridge holds for them is about twice that: buffers, and what malloc keeps of their growth)."""
    return ws.SharedBound(frame_limit(settings))


class Waiting(enum.Enum):
    """What a ClientConnection's reading waits for (None: nothing, it is taking the client's frames)."""

    READ = "read"
    """The client's next bytes: one read is asked."""
    TURN = "turn"
    """The client's next turn (a timer): it had a turn's worth of frames (budget.py)."""
    SESSION = "session"
    """The session, which holds the client's next requests (behind ROS work): resume_reading ends it."""
    END = "end"
    """Nothing more: the connection is ending, nothing more is read."""


class ClientConnection:
    """One websocket client after the handshake.

    Reading: one read of the client's socket at a time, asked for only when every frame of the last one has been taken,
    so that what waits in the bridge is at most one frame being received and one read. The frames are taken in
    turns with the other clients: after a turn's worth (budget.py), or while the Session holds the client's
    next requests, the rest waits, and the client's socket with it (backpressure). A compressed message is
    unpacked a slice at a time, each slice a turn's worth. A message must be whole within fragment_timeout of its
    first byte (_check_unfinished), and what unfinished messages hold is bounded for all clients together
    (bridge.unfinished), a client stalled in the middle of one making way for a client whose bytes keep coming
    (rfc6455.SharedBound: _made_way).

    Writing: the Session's queued frames go to the socket while it takes them; once it is backed up (the kernel
    holds at most unsent.UNSENT_LIMIT unsent), the rest stays in the Session's Outbox, which keeps each topic fresh
    meanwhile, until what was written has drained. A client whose socket takes nothing for websocket_ping_timeout
    meanwhile does not read: it is dropped (_check_stalled), and what waited for it with it.

    Deflating, with a client that offered permessage-deflate (window_bits: the largest window negotiated, else
    None): every message with use_compression; else, with compress_slow_links, the messages of DEFLATE_MIN_BYTES
    or more while its link is measured slow (slow_link.LinkMeter, from the writes that waited for the drain). Those
    are deflated once for every such client (slow_link.deflated_payload), on the deflate thread; a small one (only
    with use_compression) on the loop. RSV1 marks each compressed frame; the others go as they are."""

    def __init__(self, bridge, stream, peer, window_bits, subprotocol=None):
        self.bridge, self._window_bits = bridge, window_bits
        self._io = client_io(stream, self._received, self._drained, self._on_closed)
        self.peer, self.protocol_name = peer, subprotocol or "rosbridge"
        settings = bridge.settings
        self._loop = tornado.ioloop.IOLoop.current()
        self._reader = ws.FrameReader(
            frame_limit(settings),
            deflate=window_bits is not None,
            unmask=borrowed.websocket_mask,
            max_inflated=settings.max_message_size or None,
            shared=bridge.unfinished,
            evicted=self._made_way,
        )
        self.budget = bridge.budgets.budget(peer)
        self._answered = False  # the handshake's answer is written (start): only then may a frame be (may_write_now)
        if subprotocol is not None:
            self.session = FoxgloveSession(
                bridge.backend, bridge.config, self, bridge.foxglove, name=peer, session_id=bridge.session_id
            )
        else:
            self.session = protocol.Session(bridge.backend, bridge.config, self, name=peer)
        self._waiting = None  # what reading waits for: a Waiting, or None
        self._turn_timer = None
        self._unfinished_timer = None  # when the message the client is sending must be whole (_check_unfinished)
        self._closing = False  # our close frame is sent: nothing else goes out
        self._close_reason = None  # the Session asked to close once its queue is sent
        self._drop_timer = None
        self._awaiting_drain = False  # written data the socket has not taken yet
        self._write_waited = None  # (when, bytes) of the write the socket has not taken all of yet
        self._link = LinkMeter()
        self._deflating = 0  # the size of the frame taken last while it is being deflated off the loop...
        self._ready = None  # ...and once it is, it (a _Deflated, or as it is if that failed): it goes first
        self._pong = None  # the pong of the latest ping, waiting for the socket to drain (_write_control)
        self._stall_timer = None  # while the socket is backed up: when it must have taken something (_check_stalled)
        self._waited_since = None  # when the write it has not taken all of began
        self._pinger, self._ping_sent = None, None
        self._last_heard = self._opened = time.monotonic()  # when a read last brought something

    def start(self, handshake_answer):
        if not self._io.start(handshake_answer):  # the client left at once
            return
        self._answered = True
        self.bridge.client_opened(self)
        interval = self.bridge.settings.websocket_ping_interval
        if interval:
            self._pinger = tornado.ioloop.PeriodicCallback(self._keep_alive, interval * 1000)
            self._pinger.start()
        self._handle_frames()

    # ---- reading ---------------------------------------------------------------------------------
    def _read(self):
        if self._io.read():
            self._waiting = Waiting.READ
        else:  # (the client has left: the close callback comes)
            self._waiting = Waiting.END

    def _received(self, data):
        if self._waiting is Waiting.END:  # (by close meanwhile)
            return
        self._last_heard = time.monotonic()
        self._reader.receive(data)
        self._handle_frames()

    @property
    def unauthenticated_since(self):
        """When the client came, while it has not authenticated (and is not being closed), else None."""
        return None if self.session.authenticated or self._closing else self._opened

    def silent_for(self, now):
        """Seconds the client has not been heard while the bridge was ready to read it, or held its requests
        (behind ROS work that may never end: its link may be dead meanwhile); 0 while the bridge holds its
        frames back for its budget (a client over its budget is not silent)."""
        return now - self._last_heard if self._waiting in (Waiting.READ, Waiting.SESSION) else 0.0

    def _handle_frames(self):
        """Handles the frames received, one turn's worth at most; reads again once none is left."""
        self._turn_timer, self._waiting = None, None
        reader, budget, session = self._reader, self.budget, self.session
        try:
            while not self._io.closed():
                if session.holding:
                    self._waiting = Waiting.SESSION
                    return
                event = reader.next_event()
                if event is None:
                    if self._waiting is Waiting.END:  # (its unfinished message made way for another's meanwhile)
                        return
                    self._read()
                    if self._unfinished_timer is None and reader.unfinished_since is not None:
                        self._check_unfinished()
                    return
                kind, payload, size = event
                if kind == ws.TEXT:
                    if not self._closing:  # (after our close frame, only the client's close matters)
                        session.handle_text(payload)
                elif kind != ws.PART:
                    self._handle_other(kind, payload)
                    if self._waiting is Waiting.END:
                        return
                delay = budget.after_frame(size)
                if delay is not None:  # (0: the other clients' turn first)
                    self._waiting, self._turn_timer = Waiting.TURN, self._loop.call_later(delay, self._handle_frames)
                    return
        except ws.ProtocolError as error:
            self._waiting = Waiting.END
            if error.code == ws.TRY_AGAIN:
                self.bridge.log_refusal(
                    "unfinished",
                    f"a client refused: the unfinished messages of all clients "
                    f"hold their bound ({self.bridge.unfinished.limit} bytes)",
                )
            self.close(error.code, error.reason, then_drop=True)
        except Exception:  # a bug: this client is dropped, the others go on
            self._waiting = Waiting.END
            log_bug("reading a websocket client's frames")
            self._io.close()

    def _check_unfinished(self):
        """The message the client is sending must be whole within fragment_timeout of its first byte (a client
        that never ends one would hold it for good): checked then, and the connection closed if it is not."""
        self._unfinished_timer = None
        since = self._reader.unfinished_since if self._waiting is Waiting.READ else None
        if since is None:  # (whole, or the bridge holds the client's frames back: read again later)
            return
        left = since + self.bridge.settings.fragment_timeout - time.monotonic()
        if left > 0:
            self._unfinished_timer = self._loop.call_later(left, self._check_unfinished)
            return
        self._reader.close()  # (what it held goes now, not once the close is answered)
        self.drop(ws.POLICY, f"message not whole within fragment_timeout ({self.bridge.settings.fragment_timeout} s)")

    def _made_way(self):
        """The client's unfinished message made way for another client's, whose bytes came faster (SharedBound):
        the reader has let go of it; the connection ends."""
        self.bridge.log_refusal(
            "unfinished evicted",
            "a client dropped: its unfinished message made way for a "
            f"faster one (unfinished messages of all clients at {self.bridge.unfinished.limit} "
            "bytes)",
        )
        self.drop(
            ws.TRY_AGAIN, "unfinished messages of all clients at their bound, and yours came slowest: try again later"
        )

    def drop(self, code, reason):
        """Ends the connection, reading nothing more: our close frame, then the connection closed once it is
        written (or CLOSE_TIMEOUT later)."""
        if self._turn_timer is not None:
            self._loop.remove_timeout(self._turn_timer)
            self._turn_timer = None
        self._waiting = Waiting.END
        self.close(code, reason, then_drop=True)

    def _handle_other(self, kind, payload):
        if kind == ws.BINARY:
            if not self._closing:
                self.session.handle_binary(payload)
        elif kind == ws.PING:
            self._write_control(ws.control_frame(ws.PONG, payload))
        elif kind == ws.PONG:
            self._ping_sent = None
        elif kind == ws.CLOSE:  # answered (unless it answers ours), then the connection ends
            code, _ = payload
            self.close(None if code == ws.NO_STATUS else code, then_drop=True)

    # ---- what its session may ask (contract.SessionHost) ------------------------------------------
    def clock(self):
        return time.time()

    def call_later(self, delay, fn):
        return self._loop.call_later(delay, fn)

    def cancel_later(self, handle):
        self._loop.remove_timeout(handle)

    def wake(self):
        """The session has frames queued: they are written once the current delivery ends (write_turns)."""
        self.bridge.writes.wake(self._flush)

    def may_write_now(self):
        return (
            self._answered
            and not (
                self._awaiting_drain
                or self._closing
                or self._close_reason is not None
                or self.bridge.settings.delay_between_messages
            )
            and (  # (deflate's state: only a client that offered it has any)
                self._window_bits is None
                or (not (self._deflating or self._ready is not None) and self._sends_as_they_are())
            )
            and not self._io.writing()  # (a closed one writes nothing: write_now then lets the pool go at once)
        )

    def write_now(self, frames, size):
        big = self._write(frames)
        if self._io.writing():
            self._wait_for_drain(size)
        elif big:
            self._backed_up()  # (the socket took them all: the pool's holds on their big buffers go)

    def close_after_sending(self, reason):
        self._close_reason = reason
        self.wake()

    def resume_reading(self):
        """The session handles the client's requests again (it held them: _handle_frames)."""
        if self._waiting is Waiting.SESSION:
            self._loop.add_callback(self._handle_frames)

    def off_loop(self, fn, then):
        self.bridge.encoder.run(fn, then)

    @property
    def unfinished(self):
        """(the session's fragment ops count there too)"""
        return self.bridge.unfinished

    # ---- writing ---------------------------------------------------------------------------------
    def _flush(self):
        """Writes the Session's queued frames until the socket is backed up; _drained goes on from there (and
        _deflated, after a frame that had to be deflated off the loop)."""
        if self._awaiting_drain or self._deflating:
            return
        io = self._io
        one_at_a_time = bool(self.bridge.settings.delay_between_messages)
        big_sent = False  # (the Session's pool holds a big frame's bytes until it hears they left: _backed_up)
        while not self._closing and not io.closed():
            batch, size, emptied = [], 0, False
            while size < WRITE_BATCH_BYTES:
                frames = self._take(0 if one_at_a_time else WRITE_BATCH_BYTES - size)
                if not frames:
                    emptied = True
                    break
                batch += frames
                size += sum(map(len, frames))
                if one_at_a_time:
                    break
            if batch:
                big_sent = self._write(batch) or big_sent
                if io.writing():
                    self._wait_for_drain(size)
                    return
            if self._deflating:  # (_deflated goes on)
                return
            if emptied:  # the queue is empty: the next frame queued wakes us again
                if big_sent:
                    self._backed_up()
                if self._close_reason is not None:
                    self.close(ws.POLICY, self._close_reason)
                return
            if one_at_a_time:
                if big_sent:  # (the socket took it whole; the next turn knows nothing of it)
                    self._backed_up()
                self._loop.call_later(self.bridge.settings.delay_between_messages, self._flush)
                return

    def _take(self, most_bytes):
        """The next frames to write (session.take_frames; one deflated is a _Deflated), or none ([]): the Session's
        queue is empty, or the frame just taken is being deflated off the loop (_deflating)."""
        if self._ready is not None:
            ready, self._ready = self._ready, None
            return [ready]
        if self._sends_as_they_are():
            return self.session.take_frames(most_bytes)  # (_write encodes a str)
        every_message = self.bridge.settings.use_compression
        while True:  # one at a time: each may be deflated
            frames = self.session.take_frames(0)
            if not frames:
                return frames
            frame = _utf8(frames[0])
            if frame is not None:
                break
        if not sends_deflated(len(frame), every_message, self._link):
            return [frame]
        if len(frame) < DEFLATE_MIN_BYTES:  # (use_compression: made here, in well under a millisecond)
            return [_Deflated(frame, deflated_payload(frame, self._window_bits))]
        payload = deflated_payload(
            frame, self._window_bits, self.bridge.deflater.run, functools.partial(self._deflated, frame)
        )
        if payload is not None:  # (made already, for another client)
            return [_Deflated(frame, payload)]
        self._deflating = len(frame)
        self._backed_up()
        return []

    def _sends_as_they_are(self):
        """No frame of this client's is deflated now: it did not offer deflate, or the link is fast enough."""
        return self._window_bits is None or not deflates_some(self.bridge.settings.use_compression, self._link)

    def _wait_for_drain(self, size):
        """After a write of size bytes the socket did not take all of: _drained goes on once it has all gone."""
        self._write_waited = (time.monotonic(), size)
        self._await_drain()

    def _deflated(self, frame, payload):
        """A frame taken is deflated (payload None: that failed, and was logged; it goes as it is)."""
        self._deflating = 0
        if self._io.closed():
            return
        self._ready = frame if payload is None else _Deflated(frame, payload)
        self._backed_up()
        self._flush()

    def _backed_up(self):
        """Tells the Session whether the client's frames wait (each topic then keeps only what is fresh), and what
        was taken that has not left: the batch the socket has not taken, the frame being deflated."""
        in_flight = (self._write_waited[1] if self._write_waited is not None else 0) + self._deflating
        self.session.backed_up(self._awaiting_drain or self._deflating > 0, in_flight)

    def _await_drain(self):
        """Some of what was written waits for the socket: _drained once it has all gone, and the client dropped if
        the socket takes nothing of it for websocket_ping_timeout."""
        self._awaiting_drain = True
        self._backed_up()
        self._io.when_drained()
        self._waited_since = time.monotonic()
        if self._stall_timer is None:
            self._stall_timer = self._loop.call_later(self.bridge.settings.websocket_ping_timeout, self._check_stalled)

    def _check_stalled(self):
        self._stall_timer = None
        if not self._awaiting_drain or self._io.closed():
            return
        timeout = self.bridge.settings.websocket_ping_timeout
        progressed = max(self._waited_since, self._io.progressed_at or 0.0)
        left = progressed + timeout - time.monotonic()
        if left > 0:
            self._stall_timer = self._loop.call_later(left, self._check_stalled)
            return
        self.bridge.log_refusal(
            "stalled",
            f"a client dropped: it read nothing of what waited for it for websocket_ping_timeout ({timeout} s)",
        )
        self._io.close()  # (a close frame would wait behind what it does not read)

    def _drained(self):
        self._awaiting_drain = False
        if self._write_waited is not None:
            started, size = self._write_waited
            self._write_waited = None
            self._link.waited(size, time.monotonic() - started)
        self._backed_up()
        if self._pong is not None:
            pong, self._pong = self._pong, None
            self._write_control(pong)
        self._flush()

    def _write(self, batch):
        """Writes the frames (each as _take gives it) to the client: True if a big part went, which the Session's
        pool holds until it hears it left. Small ones are joined into one write; a big payload or part (an image)
        goes by reference, not copied: the same bytes for every client."""
        io, joined, big = self._io, [], False
        for frame in batch:
            kind = type(frame)
            if kind is bytes and (size := len(frame)) < BIG_BYTES:  # (binary, small: a Foxglove client's message)
                joined += (_SHORT_HEADERS[size] if size < ws.SHORT_PAYLOAD else ws.frame_header(size, ws.BINARY), frame)
                continue
            if kind is _Deflated:
                parts = (frame.payload,)
                joined.append(ws.frame_header(len(frame), _opcode(frame.frame), compressed=True))
                big = big or len(frame.frame) >= BIG_BYTES
            else:
                if kind is str and (frame := _utf8(frame)) is None:
                    continue
                parts = frame.parts if kind is SplicedFrame else (frame,)
                joined.append(ws.frame_header(len(frame), _opcode(frame)))
            for part in parts:
                if len(part) < BIG_BYTES:
                    joined.append(part)
                else:
                    big = True
                    io.write(b"".join(joined))
                    joined.clear()
                    io.write(part)
        io.write(b"".join(joined))
        return big

    def _write_control(self, frame):
        """A pong. While the socket is backed up only the latest ping's pong waits, and goes once it has drained
        (RFC 6455 5.5.3 lets a pong answer the latest ping only): a client that pings but never reads grows
        nothing here (each pong written to a backed-up stream cost a write future of Tornado's: 100 MB for
        the 170,000 pongs of the megabyte this once allowed)."""
        if self._closing or self._io.closed():
            return
        if self._awaiting_drain:
            self._pong = frame
            return
        self._io.write(frame)
        if self._io.writing():
            self._await_drain()

    # ---- keeping alive, closing ------------------------------------------------------------------
    def _keep_alive(self):
        """Every websocket_ping_interval: a ping; a client that has not answered the last one within
        websocket_ping_timeout is gone (a dropped link sends no FIN)."""
        if (
            self._ping_sent is not None
            and time.monotonic() - self._ping_sent > self.bridge.settings.websocket_ping_timeout
        ):
            self._io.close()
        else:
            self.ping()

    def ping(self):
        """A ping, unless one is still unanswered: a live client answers it (browsers do by themselves)."""
        if self._ping_sent is None and not self._closing and not self._io.closed():
            self._ping_sent = time.monotonic()
            self._io.write(ws.control_frame(ws.PING))

    def close(self, code=ws.NORMAL, reason="", then_drop=False):
        """Sends a close frame (code None: without a status) and stops sending anything else. The connection
        ends when the client answers it, or CLOSE_TIMEOUT later; with then_drop (the client closed, broke the
        protocol, or does not read), once the frame is written, and nothing more is read."""
        io = self._io
        if io.closed():
            return
        if then_drop:
            self._waiting = Waiting.END
        if not self._closing:
            self._closing = True
            io.write(ws.close_frame(code, reason))
            if then_drop:
                io.close_once_written()
        elif then_drop:
            io.close()
            return
        if self._drop_timer is None:
            self._drop_timer = self._loop.call_later(CLOSE_TIMEOUT, io.close)

    def _on_closed(self):
        for timer in (self._turn_timer, self._drop_timer, self._unfinished_timer, self._stall_timer):
            if timer is not None:
                self._loop.remove_timeout(timer)
        if self._pinger is not None:
            self._pinger.stop()
        self._waiting = Waiting.END
        self._reader.close()  # (what it holds goes now, not with the session: its share of the bound too)
        self._reader = None
        self.bridge.budgets.closed(self.peer, self.budget)
        self.session.closed()
        self.bridge.client_closed(self)


class _Deflated:
    """A frame taken, and the payload it goes as: deflated (permessage-deflate)."""

    __slots__ = ("frame", "payload")

    def __init__(self, frame, payload):
        self.frame, self.payload = frame, payload

    def __len__(self):
        return len(self.payload)


def _utf8(frame):
    """A frame as the session queued it, a str one encoded (None: it cannot be, a bug: it is skipped)."""
    if type(frame) is not str:
        return frame
    try:
        return Utf8Text(frame.encode())
    except UnicodeEncodeError:  # (dumps escapes what UTF-8 lacks)
        log_bug("encoding an outgoing frame")
        return None


def _opcode(frame):
    if isinstance(frame, SplicedFrame):
        return ws.TEXT if frame.text else ws.BINARY
    return ws.TEXT if isinstance(frame, Utf8Text) else ws.BINARY
