"""How much of the event loop one client may take: its frames are handled in turns with the other clients',
and beyond a rate (frames and bytes per second) its next frame waits, which leaves the rest in its socket
(backpressure) rather than in the bridge. Pure: connection.ClientConnection asks it after each frame it takes
and turns a delay into a timer before it takes the next (0 s: after the other clients' turns)."""

FRAMES_PER_TURN = 32  # then the client's turn ends, so the loop serves the others in between
BYTES_PER_TURN = 65536  # or after this many bytes, whichever comes first


class ClientBudget:
    """A token bucket per client, settled once per turn (not per frame: a frame must cost next to nothing);
    rates of 0 mean no limit. The bucket holds one second's worth (a burst)."""

    def __init__(self, frames_per_second, bytes_per_second, clock):
        self.frames_per_second, self.bytes_per_second, self._clock = frames_per_second, bytes_per_second, clock
        self._frames, self._bytes = float(frames_per_second), float(bytes_per_second)
        self._turn_frames = self._turn_bytes = 0
        self._last = clock()

    def after_frame(self, size):
        """Called after each frame the client sent: None to go on at once, else seconds to wait first (0: just
        give the others a turn)."""
        self._turn_frames += 1
        self._turn_bytes += size
        if self._turn_frames < FRAMES_PER_TURN and self._turn_bytes < BYTES_PER_TURN:
            return None
        now = self._clock()
        elapsed, self._last = now - self._last, now
        delay = 0.0
        if self.frames_per_second:
            self._frames = (
                min(self.frames_per_second, self._frames + elapsed * self.frames_per_second) - self._turn_frames
            )
            delay = max(delay, -self._frames / self.frames_per_second)
        if self.bytes_per_second:
            self._bytes = min(self.bytes_per_second, self._bytes + elapsed * self.bytes_per_second) - self._turn_bytes
            delay = max(delay, -self._bytes / self.bytes_per_second)
        self._turn_frames = self._turn_bytes = 0
        return delay
