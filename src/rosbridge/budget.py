"""How much of the event loop one client may take: its frames are handled in turns with the other clients',
and beyond a rate (frames and bytes per second) its next frame waits, which leaves the rest in its socket
(backpressure) rather than in the bridge. Pure: the server turns a delay into a sleep of the reading task."""

FRAMES_PER_TURN = 8  # then the client's reading task yields, so the loop serves the others in between


class ClientBudget:
    """A token bucket per client; rates of 0 mean no limit. The bucket holds one second's worth (a burst)."""

    def __init__(self, frames_per_second, bytes_per_second, clock):
        self.frames_per_second, self.bytes_per_second, self._clock = frames_per_second, bytes_per_second, clock
        self._frames, self._bytes = float(frames_per_second), float(bytes_per_second)
        self._since_turn = 0
        self._last = clock()

    def after_frame(self, size):
        """Called after each frame the client sent: None to go on at once, else seconds to wait first (0: just
        give the others a turn)."""
        now = self._clock()
        elapsed, self._last = now - self._last, now
        delay = None
        if self.frames_per_second:
            self._frames = min(self.frames_per_second, self._frames + elapsed * self.frames_per_second) - 1
            if self._frames < 0:
                delay = -self._frames / self.frames_per_second
        if self.bytes_per_second:
            self._bytes = min(self.bytes_per_second, self._bytes + elapsed * self.bytes_per_second) - size
            if self._bytes < 0:
                delay = max(delay or 0.0, -self._bytes / self.bytes_per_second)
        self._since_turn += 1
        if delay is None and self._since_turn >= FRAMES_PER_TURN:
            delay = 0.0
        if delay is not None:
            self._since_turn = 0
        return delay
