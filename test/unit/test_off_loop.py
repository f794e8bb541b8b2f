"""Work off the event loop: the service calls' threads (off_loop.CallThreads, used by ros_side.ServiceCalls)."""

import queue
import threading
import time

from rosbridge.off_loop import CallThreads
from rosbridge.ros_side.services import ServiceCalls

from fakes import Loop


class Rosapi:
    def __init__(self):
        self.threads = []

    def handles(self, service):
        return True

    def call(self, service, args):
        self.threads.append(threading.current_thread())
        return {"secs": 1, "nsecs": 0}


def test_calls_one_after_another_reuse_one_thread():
    """Starting a thread holds the loop until the OS has run it (0.1-0.4 s on a busy machine, for every
    client): the next call goes to the thread the last one ran on."""
    loop, rosapi = Loop(), Rosapi()
    calls = ServiceCalls(loop, rosapi, 16, 128, 1000)
    answers = []
    for _ in range(5):
        calls.call("session", "/rosapi/get_time", {}, None, None, lambda ok, values: answers.append((ok, values)))
        loop.run_one()
    assert answers == [(True, {"secs": 1, "nsecs": 0})] * 5
    assert len({id(thread) for thread in rosapi.threads}) == 1


def pool_threads(name):
    return [t for t in threading.enumerate() if t.name == name]


def test_a_blocked_call_holds_no_other_and_idle_threads_end():
    pool, release, ran = CallThreads("test pool", idle_s=0.2), threading.Event(), queue.SimpleQueue()
    pool.run(release.wait)  # (a silent service)
    for i in range(3):
        pool.run(lambda i=i: ran.put(i))
        assert ran.get(timeout=5) == i  # while the first still blocks
    assert len(pool_threads("test pool")) == 2
    release.set()
    deadline = time.monotonic() + 5
    while pool_threads("test pool") and time.monotonic() < deadline:
        time.sleep(0.05)
    assert pool_threads("test pool") == []


def test_calls_at_once_each_get_a_thread_and_the_caller_starts_none(monkeypatch):
    """Thread.start() waits for the OS to run the new thread (0.7 s once, beside a flood under load): the
    loop that hands over a call must not wait for that, not even for the first call or a burst."""
    pool, release, started = CallThreads("test burst", idle_s=0.2), threading.Event(), queue.SimpleQueue()
    starters, start = [], threading.Thread.start

    def recorded_start(thread):
        starters.append(threading.current_thread())
        start(thread)

    monkeypatch.setattr(threading.Thread, "start", recorded_start)

    def call():
        started.put(1)
        release.wait()

    for _ in range(10):
        pool.run(call)
    for _ in range(10):
        started.get(timeout=5)
    release.set()
    assert len(pool_threads("test burst")) == 10
    assert len(starters) == 10 and threading.current_thread() not in starters


def test_a_thread_the_os_refuses_once_does_not_stop_the_calls(monkeypatch):
    """Thread.start() raises RuntimeError when the OS has no thread to give (a process at its limit of tasks or
    memory): the call waits and is run once a thread can be had, and the calls after it too."""
    pool, ran = CallThreads("test refused", idle_s=0.2), queue.SimpleQueue()
    start, refusals = threading.Thread.start, []

    def refused_once(thread):
        if thread.name == "test refused" and not refusals:
            refusals.append(thread)
            raise RuntimeError("can't start new thread")
        start(thread)

    monkeypatch.setattr(threading.Thread, "start", refused_once)
    for i in range(3):
        pool.run(lambda i=i: ran.put(i))
    assert sorted(ran.get(timeout=5) for _ in range(3)) == [0, 1, 2]
    assert len(refusals) == 1
