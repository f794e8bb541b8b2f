"""One client's subscription to one topic: its subscribe requests merged, and the throttling they ask for."""

import collections

MAX_THROTTLE_RATE = 86_400_000  # ms: a day; beyond that a client means "never", which unsubscribe says better
BACKLOG_RETRY = 0.02  # s: how soon a throttled message waiting for a slow client looks again
MAX_BEHIND_ENCODING = 1000  # messages of a topic waiting behind a big one being encoded: beyond, the oldest go


class Subscription:
    """All of one client's subscribe requests to one topic, merged: lowest throttle_rate, lowest
    fragment_size, longest queue_length, the latest compression.

    With a throttle_rate, messages wait (at most queue_length of them and max_bytes encoded, the oldest
    dropped) and leave one per throttle period, and only while the client has read what it was sent before
    (backlogged() is false): so a slow client gets the newest message, not a growing backlog (a camera picture
    never lags behind). The latest is kept (not dropped as the reference does), so a throttled stream ends on
    the last value. send(frames) sends; clock() and call_later(delay, fn) come from the server.

    A big message (TopicMessage.big: a map) is encoded off the loop by off_loop (TopicMessage.frames_later), so that
    the other topics and clients go on meanwhile; the topic's next messages wait behind it, in order (at most
    MAX_BEHIND_ENCODING, the oldest dropped). off_loop None: everything is encoded at once (unit tests)."""

    __slots__ = (
        "requests",
        "throttle_rate",
        "queue_length",
        "fragment_size",
        "compression",
        "_last_sent",
        "_pending",
        "_pending_bytes",
        "_max_bytes",
        "_timer",
        "_send",
        "_clock",
        "_call_later",
        "_active",
        "_backlogged",
        "_off_loop",
        "_behind",
        "_encoding",
    )

    def __init__(self, send, clock, call_later, max_bytes, backlogged=lambda: False, off_loop=None):
        self._send, self._clock, self._call_later, self._max_bytes = send, clock, call_later, max_bytes
        self._backlogged, self._off_loop = backlogged, off_loop
        self._behind = collections.deque()  # messages waiting for a big one being encoded
        self._encoding = False
        self.requests = {}  # subscribe id (None when the client gave none) -> its options
        self._last_sent = float("-inf")
        self._pending = collections.deque()  # frames of one message each, oldest first
        self._pending_bytes = 0
        self._timer = False  # a flush is scheduled
        self._active = True

    def add(self, request_id, options):
        """options: throttle_rate (ms, 0..MAX_THROTTLE_RATE), queue_length, fragment_size, compression."""
        self.requests.pop(request_id, None)  # a repeated id moves to the end (latest compression)
        self.requests[request_id] = options
        self._merge()

    def remove(self, request_id):
        """Removes one request (all of them for None); False if there was no such request."""
        if request_id is None:
            self.requests.clear()
        elif self.requests.pop(request_id, False) is False:
            return False
        if self.requests:
            self._merge()
        return True

    def _merge(self):
        options = list(self.requests.values())
        self.throttle_rate = min(o["throttle_rate"] for o in options) / 1000.0
        self.queue_length = max(o["queue_length"] for o in options)
        sizes = [o["fragment_size"] for o in options if o["fragment_size"] is not None]
        self.fragment_size = min(sizes) if sizes else None
        self.compression = options[-1]["compression"]
        self._trim()

    def deliver(self, message):
        if self._encoding or (message.big and self._off_loop is not None):
            self._behind.append(message)
            if len(self._behind) > MAX_BEHIND_ENCODING:
                self._behind.popleft()
            if not self._encoding:
                self._encode_behind()
            return
        self._deliver(message.frames(self.compression, self.fragment_size))

    def _encode_behind(self):
        """Delivers the messages that waited, in order, until the next big one, which is encoded off the loop."""
        while self._behind and self._active:
            message = self._behind.popleft()
            if message.big:
                self._encoding = True
                message.frames_later(self.compression, self.fragment_size, self._off_loop, self._encoded)
                return
            self._deliver(message.frames(self.compression, self.fragment_size))

    def _encoded(self, frames):
        self._encoding = False
        if frames is not None and self._active:
            self._deliver(frames)
        self._encode_behind()

    def _deliver(self, frames):
        if not self.throttle_rate:
            self._send(frames)
            return
        self._pending.append(frames)
        self._pending_bytes += sum(map(len, frames))
        self._trim()
        if not self._timer:
            self._flush()

    def close(self):
        """The client left or unsubscribed: drop what waits (a pending timer then finds nothing)."""
        self._active = False
        self._behind.clear()
        self._pending.clear()
        self._pending_bytes = 0

    def _trim(self):
        pending = self._pending
        while len(pending) > 1 and (len(pending) > self.queue_length or self._pending_bytes > self._max_bytes):
            self._pending_bytes -= sum(map(len, pending.popleft()))

    def _flush(self):
        """Sends the oldest pending message if throttle_rate allows; otherwise comes back when it does."""
        self._timer = False
        if not self._active or not self._pending:
            return
        wait = self._last_sent + self.throttle_rate - self._clock()
        if wait <= 0 and self._backlogged():
            wait = max(self.throttle_rate, BACKLOG_RETRY)
        elif wait <= 0:
            frames = self._pending.popleft()
            self._pending_bytes -= sum(map(len, frames))
            self._send(frames)
            self._last_sent = self._clock()
            wait = self.throttle_rate
            if not self._pending:
                return
        self._timer = True
        self._call_later(wait, self._flush)
