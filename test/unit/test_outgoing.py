"""The Outbox: what waits for one websocket client, whole messages, small before big, each topic fresh while the
socket is backed up, bounded."""

import tracemalloc

from rosbridge.protocol.outbox import (
    FRESH_HORIZON,
    OWN_QUEUE_BYTES,
    SMALL_MESSAGE,
    TOPIC_BACKLOG_BYTES,
    Outbox,
    QueuePool,
)

from fakes import Clock


def outbox(max_frames=1000, max_bytes=64_000_000):
    clock = Clock(1000.0)
    return Outbox(max_frames, max_bytes, clock), clock


def small(name):
    return (name.encode(),)


def big(name, parts=1):
    return tuple(name.encode() + b"." + str(i).encode() + b" " * SMALL_MESSAGE for i in range(parts))


def drain(box):
    taken = []
    while (frame := box.take()) is not None:
        taken.append(bytes(frame).split(b" ")[0].decode())
    return taken


def test_a_client_that_keeps_up_gets_everything_in_order():
    box, _ = outbox()
    for i in range(500):
        box.push("/a", small(f"a{i}"))
        box.push("/b", small(f"b{i}"))
    assert drain(box) == [f"{t}{i}" for i in range(500) for t in "ab"]
    assert box.take_report() == ({}, {}, {}) and len(box) == 0 and box.bytes == 0


def test_small_messages_go_before_a_big_one_that_has_not_started():
    box, _ = outbox()
    box.push("/camera", big("picture"))
    box.push("/pose", small("pose1"))
    box.push(None, small("status"))
    assert drain(box) == ["pose1", "status", "picture.0"]


def test_a_started_fragmented_message_lets_small_ones_of_other_topics_between_its_fragments():
    box, _ = outbox()
    box.push("/map", big("map", parts=3))
    box.push("/camera", big("picture"))
    assert drain_one(box) == "map.0"
    box.push("/pose", small("pose1"))
    box.push("/map", small("map2"))  # the same topic: after the rest of the map
    assert drain(box) == ["pose1", "map.1", "map.2", "picture.0", "map2"]


def drain_one(box):
    return bytes(box.take()).split(b" ")[0].decode()


def test_a_topic_keeps_its_order_when_its_sizes_vary():
    box, _ = outbox()
    box.push("/path", small("p1"))
    box.push("/path", big("p2"))
    box.push("/path", small("p3"))
    box.push("/other", small("o1"))
    assert drain(box) == ["p1", "o1", "p2.0", "p3"]


def test_backed_up_a_camera_keeps_only_its_newest_picture_and_the_client_is_told():
    box, clock = outbox()
    box.backed_up = True
    for i in range(10):
        box.push("/camera", big(f"c{i}"))
        clock.now += 0.066
    assert drain(box) == ["c9.0"]
    skipped, dropped, refused = box.take_report()
    assert skipped == {"/camera": 9} and not dropped and not refused


def test_backed_up_a_small_topic_keeps_its_last_half_second_and_another_topic_loses_nothing():
    box, clock = outbox()
    box.backed_up = True
    for i in range(50):  # one second at 50 Hz
        box.push("/pose", small(f"p{i}"))
        if i == 0:
            box.push("/slow", small("s0"))
        clock.now += 0.02
    taken = drain(box)
    poses = [t for t in taken if t.startswith("p")]
    assert poses == [f"p{i}" for i in range(50 - len(poses), 50)]
    assert FRESH_HORIZON / 0.02 - 1 <= len(poses) <= FRESH_HORIZON / 0.02 + 1
    assert [t for t in taken if t.startswith("s")] == ["s0"]  # its one message waited a second: not behind


def test_backed_up_a_topic_keeps_at_most_its_backlog_bytes():
    box, _ = outbox()
    box.backed_up = True
    for i in range(10_000):  # all at once: within the horizon
        box.push("/fast", (b"%06d" % i + b" " * 94,))
    assert box.bytes <= TOPIC_BACKLOG_BYTES
    assert drain(box)[-1] == "009999"


def test_messages_without_a_topic_are_never_skipped():
    box, clock = outbox()
    box.backed_up = True
    for i in range(300):
        box.push(None, small(f"r{i}"))
        clock.now += 0.01
    assert drain(box) == [f"r{i}" for i in range(300)]


def test_the_bound_drops_whole_oldest_messages_big_first_and_says_so():
    box, _ = outbox(max_frames=10)
    box.push("/pose", small("p0"))
    box.push("/map", big("m1", parts=4))
    box.push("/map", big("m2", parts=4))
    box.push("/pose", small("p1"))
    box.push("/pose", small("p2"))  # 11 frames: the oldest big message goes, whole
    assert drain(box) == ["p0", "p1", "p2", "m2.0", "m2.1", "m2.2", "m2.3"]
    assert box.take_report()[1] == {"/map": 1}


def test_a_message_larger_than_the_whole_bound_is_refused_not_cut():
    box, _ = outbox(max_bytes=3 * SMALL_MESSAGE)
    box.push("/map", big("map", parts=5))
    box.push("/pose", small("p"))
    assert drain(box) == ["p"]
    assert box.take_report()[2] == {"/map": 1}


def test_a_client_that_never_reads_costs_a_bounded_amount():
    box, clock = outbox()
    box.backed_up = True
    tracemalloc.start()
    try:
        for i in range(100_000):
            box.push("/fast", small(f"x{i}"))
            box.push("/camera", big("c"))
            clock.now += 0.001
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 4 * TOPIC_BACKLOG_BYTES + 4 * SMALL_MESSAGE + 1_000_000


def test_a_message_skipped_or_taken_leaves_no_trace():
    box, _ = outbox()
    box.backed_up = True
    for i in range(100):
        box.push(f"/t{i}", small("x"))
        box.push(f"/t{i}", small("y"))
    drain(box)
    assert (len(box), box.bytes) == (0, 0)
    box.push("/t1", small("z"))
    assert drain(box) == ["z"]


def test_the_outboxes_of_every_client_share_one_bound_beyond_their_own_bytes():
    """Beyond OWN_QUEUE_BYTES each, what waits for the clients, and what their sockets were given but have not sent,
    must be granted by one QueuePool: clients that never read hold at most the pool together (beyond it whole
    messages are dropped, the newest too), a client with a small backlog is never touched, and an outbox that
    drains, or whose client leaves, gives its share back."""
    pool, clock = QueuePool(3_000_000), Clock()
    hogs = [Outbox(1000, 64_000_000, clock, pool) for _ in range(3)]
    answer = (b"A" * 1_000_000,)
    for hog in hogs:
        hog.set_backed_up(True, in_flight=1_000_000)  # (an answer in its socket already)
        for _ in range(5):
            hog.push(None, answer)
    assert pool.granted == pool.limit
    assert [hog.bytes for hog in hogs] == [2_000_000, 0, 0]  # (with the one in flight: the pool and its own)
    assert [hog.take_report()[1][None] for hog in hogs] == [3, 5, 5]
    victim = Outbox(1000, 64_000_000, clock, pool)
    victim.set_backed_up(True, in_flight=30_000)
    for i in range(100):
        victim.push(None, small(f"v{i}" + "." * 1000))
    assert len(victim) == 100 and victim.take_report() == ({}, {}, {})
    first = hogs[0]
    first.set_backed_up(False)
    assert pool.granted == 2_000_000 - OWN_QUEUE_BYTES
    assert drain(first) == ["A" * 1_000_000] * 2 and pool.granted == 0
    hogs[1].push(None, answer)  # (room again)
    assert hogs[1].bytes == 1_000_000 and pool.granted == 2_000_000 - OWN_QUEUE_BYTES
    hogs[1].clear()
    assert pool.granted == 0
