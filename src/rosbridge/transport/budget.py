"""How much of the event loop one client may take: its frames are handled in turns with the other clients',
and beyond a rate (frames and bytes per second) its next frame waits, which leaves the rest in its socket
(backpressure) rather than in the bridge. Pure: connection.ClientConnection asks it after each frame it takes
and turns a delay into a timer before it takes the next (0 s: after the other clients' turns)."""

FRAMES_PER_TURN = 32  # then the client's turn ends, so the loop serves the others in between
BYTES_PER_TURN = 65536  # or after this many bytes, whichever comes first


class ClientBudget:
    """A token bucket per client, settled once per turn (not per frame: a frame must cost next to nothing);
    rates of 0 mean no limit. The bucket holds one second's worth (a burst), and starts full."""

    def __init__(self, frames_per_second, bytes_per_second, clock):
        self.frames_per_second, self.bytes_per_second, self._clock = frames_per_second, bytes_per_second, clock
        self._frames, self._bytes, self._last = float(frames_per_second), float(bytes_per_second), clock()
        self._turn_frames = self._turn_bytes = 0

    def after_frame(self, size):
        """Called after each frame the client sent: None to go on at once, else seconds to wait first (0: just
        give the others a turn)."""
        self._turn_frames += 1
        self._turn_bytes += size
        if self._turn_frames < FRAMES_PER_TURN and self._turn_bytes < BYTES_PER_TURN:
            return None
        return self._settle()

    def full(self):
        """Whether the bucket is full now, this turn's frames spent."""
        self._settle()
        return self._frames >= self.frames_per_second and self._bytes >= self.bytes_per_second

    def lower_to(self, other):
        """Keeps, of this bucket and `other` (both refilled to now), the lower level of each."""
        self._settle()
        other._settle()
        self._frames, self._bytes = min(self._frames, other._frames), min(self._bytes, other._bytes)

    def _settle(self):
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


class Carryover:
    """The budgets that the clients of each address left below full as they closed, so that a client that
    connects again starts with what its address's last one had left (refilled since), not a new second's burst:
    a client that reconnects in a loop (a compressed message unpacking past max_message_size, closed, again: each
    unpacked 8 MB with a full bucket) gets no more than one client that stays. Several closing at once: the
    emptiest bucket is kept. At most MAX_ADDRESSES are remembered, the oldest forgotten first."""

    MAX_ADDRESSES = 10_000

    def __init__(self, frames_per_second, bytes_per_second, clock):
        self.frames_per_second, self.bytes_per_second, self._clock = frames_per_second, bytes_per_second, clock
        self._left = {}  # address -> the ClientBudget its last client left, oldest first

    def __len__(self):
        return len(self._left)

    def budget(self, address):
        """The budget of a new client from `address`: the one its last client left, else a full one."""
        left = self._left.pop(address, None)
        return left if left is not None else ClientBudget(self.frames_per_second, self.bytes_per_second, self._clock)

    def closed(self, address, budget):
        """`budget`'s client has gone (and takes no more frames): its address keeps the budget unless it is full."""
        if budget.full():
            return
        earlier = self._left.pop(address, None)
        if earlier is not None:
            budget.lower_to(earlier)
        self._left[address] = budget
        if len(self._left) > self.MAX_ADDRESSES:
            del self._left[next(iter(self._left))]
