"""bags.Writer, the bag writer thread's queue: bounded in jobs as well as in bytes, so that empty messages (a few
bytes each) cannot pile up hundreds of thousands of jobs behind a slow disk; and what a bag being written holds in
memory (bags.write_message)."""

import threading
import tracemalloc

import genpy
import pytest
import rosbag
from std_msgs.msg import Empty

from rosbridge.http.bag_bounds import MESSAGE
from rosbridge.http.bag_recorder import WRITER_QUEUE_BYTES, WRITER_QUEUE_JOBS, Writer, raw, write_message

from fakes import Loop


@pytest.fixture
def held():
    """A writer whose thread is held (a slow disk) until the test sets the event it yields (or it ends)."""
    loop, event = Loop(), threading.Event()
    writer = Writer(loop)
    assert writer.submit(event.wait)
    yield loop, writer, event
    event.set()


def test_the_queue_is_bounded_in_jobs_as_well_as_in_bytes(held):
    loop, writer, go = held
    offered = WRITER_QUEUE_JOBS + 1000
    accepted = sum(writer.submit(lambda: None, MESSAGE) for _ in range(offered))
    assert accepted == WRITER_QUEUE_JOBS - 1 and MESSAGE * offered < WRITER_QUEUE_BYTES  # (the bytes alone: all)
    assert writer.submit(lambda: None)  # an open, close or save is never refused
    go.set()
    assert loop.run_callbacks(accepted + 2) == accepted + 2
    assert writer.waiting_jobs == writer.waiting_bytes == 0
    assert writer.submit(lambda: None, MESSAGE)
    assert loop.run_callbacks(1) == 1


def test_a_big_message_fills_it_by_its_bytes(held):
    loop, writer, go = held
    assert writer.submit(lambda: None, WRITER_QUEUE_BYTES - 10)
    assert not writer.submit(lambda: None, 11) and writer.submit(lambda: None, 10)
    go.set()
    assert loop.run_callbacks(3) == 3


def test_a_bag_being_written_does_not_hold_an_index_entry_per_message(tmp_path):
    path, count = tmp_path / "empty.bag", 50_000
    message = raw(Empty, b"")
    tracemalloc.start()
    try:
        with rosbag.Bag(str(path), "w") as bag:
            before = tracemalloc.get_traced_memory()[0]
            for i in range(count):
                write_message(bag, "/empty", message, genpy.Time(1000, i))
            held = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert held / count < 100, held / count  # (rosbag's own: 226 bytes a message; a chunk's index stays, 12 kB)
    with rosbag.Bag(str(path)) as bag:
        assert bag.get_message_count() == count
        assert sum(1 for _ in bag.read_messages(raw=True)) == count
