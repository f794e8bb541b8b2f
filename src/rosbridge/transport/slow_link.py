"""A client's slow link, for the transport: how fast its socket drains (LinkMeter), whether a message goes
to it deflated (sends_deflated), and the deflated payload, made once for every client that gets the frame
compressed (deflated_payload). Pure but for the hand-off to the deflate thread, which the caller gives."""

from rosbridge.protocol.encoded import SplicedFrame, Utf8Text
from rosbridge.protocol.outbox import SMALL_MESSAGE
from rosbridge.transport.rfc6455 import deflate_message, message_window_bits

# Deflating what a slow link carries (connection.ClientConnection, for a client that offered permessage-deflate):
# a message of DEFLATE_MIN_BYTES or more goes compressed when the client's link drains slower than
# SLOW_LINK_BYTES_PER_SECOND. Why that rate: zlib's level 1 takes a camera's 1.2 MB of JSON (base64) to 0.5-0.6
# of its size at 60-85 MB/s on this project's 2-core machine (15-20 ms, once for every slow client, off the loop).
# At 8 MB/s (64 Mbit/s: Wi-Fi, a phone) that is 60-75 ms less on the link per frame, four times what deflating
# costs; at faster links the saving shrinks towards the cost, and a wired or loopback client (tens to hundreds of
# MB/s) gets the bytes as they are, at no CPU.
DEFLATE_MIN_BYTES = SMALL_MESSAGE
SLOW_LINK_BYTES_PER_SECOND = 8_000_000
MEASURED_BYTES = 256 * 1024  # what the waits must have carried before a link is judged (one camera frame does)
DRAIN_MEMORY = 0.75  # the weight of the earlier waits against each new one: a link that changes shows in a few


class LinkMeter:
    """How fast one client's socket takes what is written to it, from the writes that had to wait for it (a write
    the socket takes at once says nothing of the link; the kernel holds little unsent, unsent.py, so one that
    waits drains at the link's pace). Bytes over the seconds until drained, each summed with a decay: a big write
    counts by its size, a reader's pause by its length. A write on loopback waits too (for the reader to take a
    megabyte), but drains at hundreds of MB/s. Pure: the server says what waited and how long."""

    __slots__ = ("bytes", "seconds")

    def __init__(self):
        self.bytes = self.seconds = 0.0

    def waited(self, size, seconds):
        """A write of `size` bytes waited `seconds` until the socket had taken it all."""
        self.bytes = self.bytes * DRAIN_MEMORY + size
        self.seconds = self.seconds * DRAIN_MEMORY + seconds

    @property
    def rate(self):
        """Bytes per second, or None before a write waited."""
        return self.bytes / self.seconds if self.seconds > 0 else None

    @property
    def slow(self):
        """Measured (from MEASURED_BYTES at least) below SLOW_LINK_BYTES_PER_SECOND."""
        return self.bytes >= MEASURED_BYTES and self.bytes < SLOW_LINK_BYTES_PER_SECOND * self.seconds


def sends_deflated(size, every_message, link):
    """Whether a message of `size` bytes goes deflated to a client that negotiated permessage-deflate: every one
    with use_compression (every_message), else one of DEFLATE_MIN_BYTES or more while its link (a LinkMeter) is
    slow."""
    return every_message or size >= DEFLATE_MIN_BYTES and link.slow


def deflates_some(every_message, link):
    """Whether some message may go deflated now (sends_deflated, whatever its size)."""
    return every_message or link.slow


def deflated_payload(frame, max_window_bits, off_loop=None, then=None):
    """The payload of `frame` (a Utf8Text, SplicedFrame or bytes) as one permessage-deflate message, with a window
    of at most max_window_bits (rfc6455.deflate_message: no context, so the same bytes for every client).
    Made once per window for every client that sends the frame compressed, and kept on the frame (in `deflated`:
    window bits -> the payload, or the callbacks waiting for it) as long as the frame lives, which is as long as
    a subscription, an Outbox or a write holds it; at most its size again, in practice half. A plain bytes frame
    (a binary one of one part) cannot keep it: it is deflated each time.

    Returns the payload if it is made, or makes it now if off_loop is None (a small message, on the loop).
    Else returns None, and then(payload) is called on the loop once off_loop(fn, done) has run fn on its thread
    (off_loop.EncodingThread.run; fn reads only the frame's bytes, which nothing changes, and only the loop
    touches `deflated`), for every client that asked meanwhile; payload None if it failed (a bug, logged)."""
    bits = message_window_bits(len(frame), max_window_bits)
    keeps = isinstance(frame, (Utf8Text, SplicedFrame))
    if keeps and frame.deflated is None:
        frame.deflated = {}
    made = frame.deflated.get(bits) if keeps else None
    if isinstance(made, bytes):
        return made
    parts = frame.parts if isinstance(frame, SplicedFrame) else (frame,)
    if off_loop is None:
        payload = deflate_message(parts, bits)
        if keeps and made is None:
            frame.deflated[bits] = payload
        return payload
    if made is not None:  # (being made: the callbacks waiting for it)
        made.append(then)
        return None
    waiting = [then]
    if keeps:
        frame.deflated[bits] = waiting
    off_loop(lambda: deflate_message(parts, bits), lambda payload: _deflated(frame, bits, waiting, payload))
    return None


def _deflated(frame, bits, waiting, payload):
    if isinstance(frame, (Utf8Text, SplicedFrame)):
        if payload is None:
            del frame.deflated[bits]
        else:
            frame.deflated[bits] = payload
    for then in waiting:
        then(payload)
