"""The rospy-free parts of the ROS side: who holds what, and the early replay's thread rules."""
from rosbridge.ros_side.holders import Holders
from rosbridge.ros_side.publishers import REPLAY_WINDOW, EarlyReplay


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


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_early_messages_are_replayed_to_a_subscriber_within_the_window():
    clock = Clock()
    replay = EarlyReplay(10, clock)
    replay.record("m1", lambda: 0)
    replay.record("m2", lambda: 1)  # someone was connected for this one: it got it
    got = []
    replay.peer_subscribe("/t", None, got.append)
    assert got == ["m1"]
    clock.now += REPLAY_WINDOW
    replay.record("m3", lambda: 0)
    replay.peer_subscribe("/t", None, got.append)
    assert got == ["m1"]


def test_no_replay_once_a_subscriber_left():
    replay = EarlyReplay(10, Clock())
    replay.record("m1", lambda: 0)
    replay.peer_unsubscribe("/t", 0)
    got = []
    replay.peer_subscribe("/t", None, got.append)
    assert got == []


def test_a_subscriber_leaving_while_a_message_is_recorded():
    """The interleaving that once ended a topic's publishing thread: peer_unsubscribe (a rospy thread) runs
    between the publishing thread's check of the buffer and its use of it."""
    replay = EarlyReplay(10, Clock())

    def connections():  # asked between the check and the use: the subscriber leaves right there
        replay.peer_unsubscribe("/t", 0)
        return 0
    replay.record("m1", connections)  # must not raise
    got = []
    replay.peer_subscribe("/t", None, got.append)
    assert got == []
