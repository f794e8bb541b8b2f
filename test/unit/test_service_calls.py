"""ros_side.ServiceCalls' bounds against services that never answer: a call ends when its client leaves or its
timeout comes (its connection to the service closed), and clients whose calls hang cannot take every turn."""

import threading

from rosbridge.errors import RequestError
from rosbridge.ros_side.services import ServiceCalls

from fakes import Loop


class Proxy:
    """A ServiceProxy's connection to a service that never answers: a call through it waits until it is closed."""

    def __init__(self):
        self.closed = threading.Event()

    def close(self):
        self.closed.set()


HELD = threading.Semaphore(0)  # released by each call once it holds its proxy


def never_answers(call):
    """A call through a Proxy (what services._call_through does with rospy's)."""
    proxy = Proxy()
    call.hold(proxy)
    HELD.release()
    assert proxy.closed.wait(10), "never ended"
    raise RequestError("transport error completing service call: closed")


def started(calls, session, count, answers, timeout=None, running=None):
    """count calls of session that never answer, `running` of them (all by default) waited for until they hold
    their proxy."""
    for _ in range(count):
        calls.run(
            session,
            "call",
            never_answers,
            lambda ok, values: answers.append((session, ok, values)),
            timeout,
            "timed out",
            through_proxy=True,
        )
    for _ in range(count if running is None else running):
        assert HELD.acquire(timeout=10)


def test_the_calls_of_a_client_that_left_end_and_free_their_turns():
    """Before, a call to a silent service held its thread and its turn for good: 8 clients that called one 16
    times each and left took every turn (128), and no client's call ran again."""
    loop, answers = Loop(), []
    calls = ServiceCalls(loop, None, 2, 4, 10)
    started(calls, "hostile", 2, answers)
    calls.release("hostile")
    assert loop.run_callbacks(count=2) == 2  # (both threads returned)
    assert calls._total == 0 and answers == [("hostile", False, "transport error completing service call: closed")] * 2
    loop.run_timers()  # (nothing is closed again once the threads returned)
    assert loop.timers == []


def test_a_call_that_times_out_ends():
    loop, answers = Loop(), []
    calls = ServiceCalls(loop, None, 2, 4, 10)
    started(calls, "client", 1, answers, timeout=5.0)
    loop.run_timers()  # (the timeout)
    assert answers == [("client", False, "timed out")]
    assert loop.run_callbacks(count=1) == 1 and calls._total == 0
    assert answers == [("client", False, "timed out")]  # (answered once)


def test_clients_whose_calls_hang_leave_every_other_client_a_call():
    loop, answers = Loop(), []
    calls = ServiceCalls(loop, None, 2, 4, 10)
    for hostile in ("a", "b"):
        started(calls, hostile, 3, answers, running=2)  # (every turn in all taken)
    done = threading.Event()
    calls.run("victim", "get_time", lambda: "now", lambda ok, values: (answers.append(values), done.set()))
    loop.run_callbacks(count=1)
    assert done.is_set() and answers == ["now"]
    started(calls, "victim", 2, answers, running=1)  # (one runs beyond max_total, the other waits for a turn)
    assert calls._total == 5
    for session in ("a", "b", "victim"):
        calls.release(session)
    loop.run_callbacks(count=5)
    assert calls._total == 0
