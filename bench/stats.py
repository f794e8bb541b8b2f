"""Small measuring tools shared by the benchmark roles and the suite (standard library only)."""
import asyncio
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
        return {"received": self.n, "unique": len(self.seqs), "seconds": span,
                "rate": (self.n - 1) / span if span > 0 else 0.0, "bytes": self.bytes}


def latency_summary(rtts, sent):
    """Round-trip times (seconds) -> p50/p99 in milliseconds, and how many pings got no echo."""
    if not rtts:
        return {"sent": sent, "echoed": 0, "p50_ms": None, "p99_ms": None}
    q = statistics.quantiles(rtts, n=100, method="inclusive")
    return {"sent": sent, "echoed": len(rtts), "p50_ms": statistics.median(rtts) * 1e3, "p99_ms": q[98] * 1e3}


def median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None
