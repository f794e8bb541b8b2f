"""When the clients that have frames to send write them. A client's frames are queued by whatever runs on the loop
(a ROS message delivered, a status, a service's answer) and written later, together, so that a burst is one
write: at the end of the delivery under way, if one is (the messages one read of a publisher brought, which
ros_side/subscribers.py delivers DELIVERY_BATCH at a time inside the WriteTurns, the context a delivery runs in:
they are written in the same turn of the loop as the read, one turn a message at 1 kHz instead of two), else in
the loop's next turn. Pure: the server gives it the loop's call_soon. Loop thread only."""

from rosbridge.errors import log_bug


class WriteTurns:
    def __init__(self, call_soon):
        self._call_soon = call_soon
        self._woken = []  # the flush of each client woken since the last writes
        self._scheduled = False  # the writes are asked of the loop's next turn
        self._delivering = 0  # deliveries under way (nested: a delivery may deliver)

    def wake(self, flush):
        """flush() writes a client's queued frames: called once the delivery under way, or this turn, is over."""
        self._woken.append(flush)
        if not self._delivering and not self._scheduled:
            self._scheduled = True
            self._call_soon(self._write)

    def __enter__(self):
        """A delivery of messages begins: the clients it wakes write once it ends."""
        self._delivering += 1

    def __exit__(self, *_):
        self._delivering -= 1
        if not self._delivering and self._woken:
            self._write()

    def _write(self):
        self._scheduled = False
        while self._woken:  # (a write may wake another client: a close, a status)
            woken, self._woken = self._woken, []
            for flush in woken:
                try:
                    flush()
                except Exception:  # a bug: that client misses this write, the others go on
                    log_bug("writing to a client")
