"""The rospy-free parts of the ROS side: who holds what, and the early replay's thread rules."""

from rosbridge.ros_side.holders import Holders
from rosbridge.ros_side.publishers import REPLAY_BYTES, REPLAY_WINDOW, EarlyReplay

from fakes import Clock


def test_the_first_holder_makes_and_the_last_one_releases():
    holders = Holders()
    assert holders.add("/t", "a") is True
    assert holders.add("/t", "b") is False
    assert holders.add("/t", "a") is False
    assert holders.discard("/t", "a") is False
    assert holders.holds("/t", "b") and not holders.holds("/t", "a")
    assert holders.discard("/t", "c") is False  # never held
    assert holders.discard("/t", "b") is True
    assert holders.holders("/t") == () and holders.discard("/t", "b") is False


def test_names_of_a_holder():
    holders = Holders()
    for name in ("/a", "/b"):
        holders.add(name, "x")
    holders.add("/c", "y")
    assert sorted(holders.names_of("x")) == ["/a", "/b"]


def test_early_messages_are_replayed_to_a_subscriber_within_the_window_after_registering():
    """The window starts when the master knows the publisher, however long the worker took to register it (it
    started at the advertise: beside a CPU hog, a page's first Twist was lost)."""
    clock = Clock(100.0)
    replay = EarlyReplay(10, clock)
    replay.record("m1")
    clock.now += 5 * REPLAY_WINDOW  # (the worker, busy)
    replay.record("m2")
    replay.registered()
    clock.now += REPLAY_WINDOW / 2
    assert replay.replay() == ("m1", "m2")
    clock.now += REPLAY_WINDOW / 2
    replay.record("m3")
    assert replay.replay() == ()


def test_no_replay_once_a_subscriber_left():
    replay = EarlyReplay(10, Clock(100.0))
    replay.record("m1")
    replay.end()
    replay.record("m2")
    assert replay.replay() == ()


def test_early_replay_keeps_the_newest_messages():
    replay = EarlyReplay(2, Clock(100.0))
    for n in range(5):
        replay.record(b"%d" % n)
    assert replay.replay() == (b"3", b"4")


def test_early_replay_keeps_the_newest_messages_within_replay_bytes():
    """Before, it kept queue_size messages of any size: a client advertising new topics and publishing 8 MB
    messages at once on each held 620 MB in 5 s."""
    replay = EarlyReplay(100, Clock(100.0))
    for n in range(5):
        replay.record(bytes([n]) * (REPLAY_BYTES // 3))
    assert [m[0] for m in replay.replay()] == [2, 3, 4]
    replay.record(bytes(REPLAY_BYTES + 1))  # (too big to keep)
    assert [m[0] for m in replay.replay()] == [2, 3, 4]
