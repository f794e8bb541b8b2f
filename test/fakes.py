"""Stand-ins for time, Tornado's IOLoop, a protocol session's connection and the ROS side in the unit tests of pure
parts: what a test moves by hand. Only these are faked; everything else the tests touch is the real code."""

import queue
import time


class Clock:
    """A clock(): the seconds `now`, which the test sets or advances."""

    def __init__(self, now=0.0):
        self.now = now

    def __call__(self):
        return self.now

    def advance(self, seconds):
        self.now += seconds


class Loop:
    """What the parts ask of the IOLoop, each run when the test says:
    - add_callback(fn, *args), from any thread: run_callbacks() or run_one();
    - call_soon(fn) (WriteTurns' hand-off): next_turn();
    - call_later(delay, fn) and remove_timeout(handle): run_timers() runs every timer set, whatever its delay."""

    def __init__(self):
        self._callbacks = queue.SimpleQueue()
        self.soon, self.timers = [], []

    def add_callback(self, fn, *args):
        self._callbacks.put((fn, args))

    def run_one(self, timeout=5.0):
        """Waits for the next callback (from another thread) and runs it."""
        fn, args = self._callbacks.get(timeout=timeout)
        fn(*args)

    def run_callbacks(self, count=0, timeout=10.0):
        """Runs the callbacks added so far, once at least `count` have come (waiting up to `timeout` s for them);
        returns how many ran."""
        ran, end = 0, time.monotonic() + timeout
        while True:
            try:
                wait = max(0.0, end - time.monotonic()) if ran < count else 0
                fn, args = self._callbacks.get(timeout=wait) if wait else self._callbacks.get_nowait()
            except queue.Empty:
                return ran
            fn(*args)
            ran += 1

    def call_soon(self, fn):
        self.soon.append(fn)

    def next_turn(self):
        soon, self.soon = self.soon, []
        for fn in soon:
            fn()

    def call_later(self, delay, fn):
        handle = [delay, fn]
        self.timers.append(handle)
        return handle

    def remove_timeout(self, handle):
        self.timers.remove(handle)

    def run_timers(self):
        timers, self.timers = self.timers, []
        for _, fn in timers:
            fn()


class OffLoop:
    """off_loop(fn, then), as an EncodingThread runs it: fn's result handed to then, when the test says
    (run_all); `count` of jobs given."""

    def __init__(self):
        self.jobs, self.count = [], 0

    def __call__(self, fn, then):
        self.jobs.append((fn, then))
        self.count += 1

    def run_all(self):
        jobs, self.jobs = self.jobs, []
        for fn, then in jobs:
            then(fn())


class Host:
    """A contract.SessionHost for a protocol session under test. Its clock is `now`; its timers wait in `timers`
    ([due, delay, fn], in the order set) until the test runs them (advance, run_next); it keeps what the session
    asked: `cancelled` timers, `close_reasons`, `resumes`. off_loop: an OffLoop or the like, else each job runs at
    once; unfinished: a shared bound (rfc6455.SharedBound), else none. With `writes_now` set, it writes what the
    session offers it at once (may_write_now, write_now) to `written` (the frames of each write), as a socket that
    keeps up, and never says they have left (backed_up); else all is queued."""

    def __init__(self, now=1000.0, off_loop=None, unfinished=None, writes_now=False):
        self.now, self.unfinished, self._off_loop, self.writes_now = now, unfinished, off_loop, writes_now
        self.timers, self.cancelled, self.close_reasons, self.resumes, self.written = [], [], [], 0, []

    def clock(self):
        return self.now

    def call_later(self, delay, fn):
        timer = [self.now + delay, delay, fn]
        self.timers.append(timer)
        return timer

    def cancel_later(self, handle):
        self.cancelled.append(handle)
        self.timers = [timer for timer in self.timers if timer is not handle]

    def wake(self):
        """(the test takes the session's frames when it wants)"""

    def may_write_now(self):
        return self.writes_now

    def write_now(self, frames, size):
        assert self.writes_now and size == sum(map(len, frames))
        self.written.append(list(frames))

    def close_after_sending(self, reason):
        self.close_reasons.append(reason)

    def resume_reading(self):
        self.resumes += 1

    def off_loop(self, fn, then):
        if self._off_loop is not None:
            self._off_loop(fn, then)
        else:
            then(fn())

    def advance(self, seconds):
        """Moves the clock on by `seconds`, running the timers due by then."""
        self.now += seconds
        due = [timer for timer in self.timers if timer[0] <= self.now]
        self.timers = [timer for timer in self.timers if timer[0] > self.now]
        for _, _, fn in due:
            fn()

    def run_next(self):
        """Runs the timer set first, the clock moved on by its delay."""
        _, delay, fn = self.timers.pop(0)
        self.now += delay
        fn()


def drain(session):
    """Every frame a protocol session has queued, in order, taken as its connection takes them (take_frames)."""
    out = []
    while taken := session.take_frames(1 << 16):
        out += taken
    return out


class BackendRecorder:
    """A stand-in for contract.Backend: records whatever a session asks; replies are kept for the test to give."""

    def __init__(self):
        self.calls, self.replies, self.watchers = [], [], []

    def __getattr__(self, name):
        def record(*args):
            self.calls.append((name, *args[1:]))
            if callable(args[-1]) and name not in ("watch_graph", "unwatch_graph"):
                self.replies.append(args[-1])

        return record

    def watch_graph(self, listener):
        self.watchers.append(listener)

    def unwatch_graph(self, listener):
        self.watchers.remove(listener)
