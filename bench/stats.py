"""Small measuring tools shared by the benchmark roles and the suite (standard library only)."""

import asyncio
import bisect
import json
import statistics
import sys
import threading
import time


def wait_until(predicate, timeout, what, fail=True, interval=0.02):
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            if fail:
                raise SystemExit(f"timed out after {timeout}s waiting for {what}")
            return False
        time.sleep(interval)
    return True


def result(**values):
    """The one line a role reports back to the suite."""
    print("RESULT " + json.dumps(values), flush=True)


def cue():
    """A future that completes when the suite writes a line on stdin (read in a daemon thread, so a process
    that is told to stop is never held up by a pending read)."""
    loop = asyncio.get_running_loop()
    done = loop.create_future()

    def read():
        sys.stdin.readline()
        loop.call_soon_threadsafe(lambda: done.done() or done.set_result(None))

    threading.Thread(target=read, daemon=True).start()
    return done


class Arrivals:
    """Counts received messages by sequence number and when the first and last arrived."""

    def __init__(self):
        self.n = 0
        self.bytes = 0
        self.first = self.last = None
        self.seqs = set()

    def add(self, seq, size=0):
        now = time.monotonic()
        if self.first is None:
            self.first = now
        self.last = now
        self.n += 1
        self.bytes += size
        self.seqs.add(seq)

    def wait(self, expected, idle, timeout):
        """Until `expected` messages came, or none came for `idle` seconds after the first, or `timeout`."""
        deadline = time.monotonic() + timeout
        while self.n < expected and time.monotonic() < deadline:
            if self.last is not None and time.monotonic() - self.last > idle:
                break
            time.sleep(0.02)

    def summary(self):
        span = (self.last - self.first) if self.n > 1 else 0.0
        return {
            "received": self.n,
            "unique": len(self.seqs),
            "seconds": span,
            "rate": (self.n - 1) / span if span > 0 else 0.0,
            "bytes": self.bytes,
        }


def latency_summary(rtts, sent):
    """Round-trip times (seconds) -> p50/p99 in milliseconds, and how many pings got no echo."""
    if not rtts:
        return {"sent": sent, "echoed": 0, "p50_ms": None, "p99_ms": None}
    q = statistics.quantiles(rtts, n=100, method="inclusive")
    return {"sent": sent, "echoed": len(rtts), "p50_ms": statistics.median(rtts) * 1e3, "p99_ms": q[98] * 1e3}


def median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def count_between(times, t0, t1):
    """How many of the ascending `times` fall in [t0, t1)."""
    return bisect.bisect_left(times, t1) - bisect.bisect_left(times, t0)


def commands(handlers):
    """Serves the lines of stdin until `quit` or its end: each is a command word and its arguments; the handler
    of that word returns the values the `RESULT` line reports. (Blocks: an asyncio role runs it in a thread.)"""
    for line in sys.stdin:
        words = line.split()
        if not words:
            continue
        if words[0] == "quit":
            return
        result(**handlers[words[0]](*words[1:]))


def percentile(values, q):
    """The q-quantile (0-1) of values, the nearest rank; None if there are none."""
    if not values:
        return None
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q * (len(values) - 1))))]


class CpuWindow:
    """CPU seconds a process spends from now on (proc_stat: a harness.ProcStat): the sum of its threads' own
    counts (the scheduler's, to the microsecond, where /proc/<pid>/stat counts 10 ms ticks), or the ticks if a
    thread ended meanwhile (it took its count with it)."""

    def __init__(self, proc_stat):
        self.proc_stat = proc_stat
        self.threads, self.ticks = proc_stat.thread_cpu(), proc_stat.cpu_seconds()

    def seconds(self):
        threads, ticks = self.proc_stat.thread_cpu(), self.proc_stat.cpu_seconds()
        if set(self.threads) - set(threads):
            return ticks - self.ticks
        return sum(t - self.threads.get(tid, 0.0) for tid, t in threads.items())
