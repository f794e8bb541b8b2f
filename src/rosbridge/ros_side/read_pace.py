"""When the bridge reads one of its publishers (ros_side/links.py). Each read costs a wake of the event loop, a
system call each way and a write to every subscribed client, several times what converting the message costs:
read at every message, a queued rospy publisher (about 10,000 msg/s) cost the bridge 1.7-2.7x the CPU per message
of a bare Tornado server pushing the same messages (bench/README.md). So a publisher that keeps sending faster than
COALESCE_RATE is read once per COALESCE_WINDOW instead, everything that came meanwhile in one read, delivered and
written together: its messages wait up to COALESCE_WINDOW in the socket. A slower one (1 kHz and below: most robot
topics) is read at each message, as it comes. Pure: the link says what each read brought, and when."""

COALESCE_RATE = 2000  # messages/s that a publisher keeps up...
COALESCE_AFTER = 8  # ...over this many reads in a row (a short burst is read as it comes)
COALESCE_WINDOW = 1e-3  # s between reads meanwhile (the loop's timers wake to the millisecond anyway)
WINDOW_SHARE = COALESCE_RATE * COALESCE_WINDOW  # messages a read brings at least while that rate holds


class ReadPace:
    """One publisher's reads: when its socket is readable (watching), or every COALESCE_WINDOW (polling) from
    COALESCE_AFTER reads in a row that came less than 1 / COALESCE_RATE after the one before, until a read brings
    less than a window's share of messages (the publisher slowed down or stopped), or more may be waiting (a read
    that filled its buffer, a big message on its way: read on as it comes)."""

    __slots__ = ("polling", "_last", "_streak")

    def __init__(self):
        self.polling = False
        self._last = float("-inf")  # when a read last brought messages (watching)
        self._streak = 0  # reads in a row that came less than 1 / COALESCE_RATE after the one before

    def after_read(self, now, messages, more):
        """A read at `now` (seconds) brought `messages` (complete ones: 0 for a part of one, or nothing); `more`:
        more may be waiting. Returns the seconds until the next read, or None: once the socket is readable."""
        if self.polling:
            if messages >= WINDOW_SHARE and not more:
                return COALESCE_WINDOW
            self.polling, self._streak, self._last = False, 0, now
            return None
        if messages:
            self._streak = self._streak + 1 if now - self._last < 1 / COALESCE_RATE else 0
            self._last = now
            if self._streak >= COALESCE_AFTER and not more:
                self.polling = True
                return COALESCE_WINDOW
        return None
