"""The Outbox: what waits for one websocket client, whole messages, small before big, each topic fresh while the
socket is backed up, bounded."""

import tracemalloc

from hypothesis import given, settings
from hypothesis import strategies as st

from rosbridge.protocol.encoded import SplicedFrame
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


def take(box):
    """The next frame, or None: the outbox's frames one at a time, as a client whose frames may be deflated takes
    them."""
    frames = box.take_frames(0)
    return frames[0] if frames else None


def drain(box):
    taken = []
    while (frame := take(box)) is not None:
        taken.append((frame.encode() if isinstance(frame, str) else bytes(frame)).split(b" ")[0].decode())
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
    return bytes(take(box)).split(b" ")[0].decode()


def test_a_topic_keeps_its_order_when_its_sizes_vary():
    box, _ = outbox()
    box.push("/path", small("p1"))
    box.push("/path", big("p2"))
    box.push("/path", small("p3"))
    box.push("/other", small("o1"))
    assert drain(box) == ["p1", "o1", "p2.0", "p3"]


def test_a_topic_keeps_its_order_after_a_fragmented_message_of_its_own():
    box, _ = outbox()
    box.push("/map", big("m0", parts=3))
    assert drain_one(box) == "m0.0"
    box.push("/map", small("m1"))  # behind the rest of m0...
    assert [drain_one(box), drain_one(box)] == ["m0.1", "m0.2"]
    box.push("/map", small("m2"))  # ...and this one behind m1, though m0 has gone meanwhile
    assert drain(box) == ["m1", "m2"]


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


def test_while_nothing_waits_and_the_socket_keeps_up_the_same_bounds_hold():
    """Small messages queued to a client that keeps up skip the lanes (Outbox._passing), not the bounds."""
    box, _ = outbox(max_frames=10)
    for i in range(25):
        box.push("/pose", small(f"p{i}"))
    assert len(box) == 10 and box.take_report()[1] == {"/pose": 15}
    assert drain(box) == [f"p{i}" for i in range(15, 25)]
    box, _ = outbox(max_bytes=100)
    for i in range(25):
        box.push("/pose", small(f"p{i:09}"))  # (10 bytes each)
    assert box.bytes == 100 and drain(box) == [f"p{i:09}" for i in range(15, 25)]
    # With a pool, what the socket was given and has not sent counts too: here all the client may hold.
    box = Outbox(1000, 64_000_000, Clock(), QueuePool(0))
    box.set_backed_up(False, in_flight=OWN_QUEUE_BYTES)
    box.push("/pose", small("p0"))
    assert len(box) == 0 and box.take_report()[1] == {"/pose": 1}


def test_frames_bypass_only_an_outbox_where_nothing_waits_or_is_to_be_told_and_within_its_bounds():
    """(OutboxSession then has the host write them at once: take_at_once gives their bytes.)"""
    box, _ = outbox(max_frames=2, max_bytes=100)
    assert box.take_at_once((b"ab", b"cde")) == 5
    assert box.take_at_once((b"a", b"b", b"c")) is None  # more frames than the bound
    assert box.take_at_once((b"x" * 101,)) is None  # more bytes
    box.push("/pose", small("p0"))
    assert box.take_at_once((b"ab",)) is None  # (it would pass the one waiting)
    drain(box)
    box.backed_up = True
    assert box.take_at_once((b"ab",)) is None
    box.backed_up = False
    box.skipped["/pose"] += 1
    assert box.take_at_once((b"ab",)) is None  # (the report goes first)
    box.take_report()
    assert box.take_at_once((b"ab",)) == 2
    box, _ = outbox()
    assert box.take_at_once((b"x" * SMALL_MESSAGE,)) == SMALL_MESSAGE  # (a big one too, without a pool)


def test_a_big_frame_taken_at_once_is_held_in_the_pool_until_the_socket_has_it():
    pool = QueuePool(3_000_000)
    box = Outbox(1000, 64_000_000, Clock(), pool)
    picture = b"P" * 1_000_000
    frames = (SplicedFrame((b"head", picture), text=False), b"x" * 10)
    assert box.take_at_once(frames) == 1_000_014 and pool.shared == len(picture)
    box.set_backed_up(True, in_flight=1_000_014)  # (the socket holds some of it: its own bytes are granted)
    assert pool.shared == len(picture) and pool.granted == 0
    box.set_backed_up(False)
    assert pool.shared == 0 and len(box) == 0 and box.take_report() == ({}, {}, {})
    # What does not fit the pool beside the other clients' buffers is not taken at once (then queued, it is dropped).
    other = Outbox(1000, 64_000_000, Clock(), pool)
    other.push(None, (b"O" * 2_500_000,))
    assert box.take_at_once((picture,)) is None and pool.shared == 2_500_000
    # Nor what is beyond the client's own bound.
    small_bound = Outbox(1000, 999_999, Clock(), QueuePool(3_000_000))
    assert small_bound.take_at_once((picture,)) is None


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
    for hog in hogs:
        hog.set_backed_up(True, in_flight=1_000_000)  # (an answer in its socket already)
        for _ in range(5):
            hog.push(None, (str("A" * 1_000_000),))  # (each a client's own: a str is encoded as it is taken)
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
    hogs[1].push(None, ("A" * 1_000_000,))  # (room again)
    assert hogs[1].bytes == 1_000_000 and pool.granted == 2_000_000 - OWN_QUEUE_BYTES
    hogs[1].clear()
    assert pool.granted == 0


def test_a_big_buffer_that_many_clients_hold_counts_once_in_the_pool():
    """Ten clients that never read each hold the same 30 MB answer four times, one of them in their socket: the
    pool counts 30 MB, not 1.2 GB, and another client's pictures still fit."""
    pool, clock = QueuePool(128_000_000), Clock()
    mesh = b"M" * 30_000_000
    hoarders = [Outbox(1000, 64_000_000, clock, pool) for _ in range(10)]
    for i, hoarder in enumerate(hoarders):
        answers = [SplicedFrame((b"head %d.%d " % (i, n), mesh), text=False) for n in range(4)]
        hoarder.push(None, (answers[0],))
        assert take(hoarder) is answers[0]
        hoarder.set_backed_up(True, in_flight=len(answers[0]))
        for answer in answers[1:]:
            hoarder.push(None, (answer,))
    assert pool.shared == len(mesh) and pool.granted == 0  # (each keeps two waiting: 64 MB are its own bound)
    viewer = Outbox(1000, 64_000_000, clock, pool)
    viewer.set_backed_up(True, in_flight=300_000)
    for i in range(10):
        viewer.push("/camera", (bytes([i]) * 300_000,))
    assert viewer.take_report()[1] == {}


def test_a_taken_big_frame_is_held_until_the_socket_has_it():
    pool, clock = QueuePool(10_000_000), Clock()
    box = Outbox(1000, 64_000_000, clock, pool)
    picture = b"P" * 1_000_000
    box.push("/camera", (picture,))
    assert take(box) is picture and pool.shared == len(picture)
    box.set_backed_up(True, in_flight=len(picture) + 100)  # (the socket holds it and a small frame)
    assert pool.shared == len(picture) and pool.granted == 0
    box.set_backed_up(False)
    assert pool.shared == 0


def test_a_big_frame_that_does_not_fit_the_pool_makes_room_from_its_own_clients_older_ones_first():
    pool, clock = QueuePool(3_000_000), Clock()
    other = Outbox(1000, 64_000_000, clock, pool)
    other.push(None, (b"O" * 1_500_000,))
    box = Outbox(1000, 64_000_000, clock, pool)
    box.backed_up = True
    first, second = b"1" * 1_000_000, b"2" * 1_000_000
    box.push(None, (first,))
    box.push(None, (second,))  # (1.5 + 1 + 1 MB: the older one of its own goes)
    assert box.take_report()[1] == {None: 1} and drain(box) == ["2" * 1_000_000]
    box.push(None, (b"3" * 2_000_000,))  # (it cannot fit beside the other client's: refused)
    assert box.take_report()[1] == {None: 1} and len(box) == 0
    assert drain(other) == ["O" * 1_500_000]


def test_a_client_that_leaves_lets_go_of_every_buffer_it_held():
    pool, clock = QueuePool(100_000_000), Clock()
    box = Outbox(1000, 64_000_000, clock, pool)
    shared = b"S" * 1_000_000
    box.push("/map", (SplicedFrame((b"a", shared), text=False), SplicedFrame((b"b", shared), text=False)))
    take(box)
    box.set_backed_up(True, in_flight=1_000_001)
    box.push("/camera", (b"C" * 2_000_000,))
    box.push(None, ("x" * 500_000,))
    box.clear()
    assert (pool.shared, pool.granted) == (0, 0)


def test_the_unsent_fragments_of_a_message_stay_held_while_its_first_ones_have_left():
    """The socket drains between a big message's fragments: what has left is let go, the rest still counts."""
    pool = QueuePool(100_000_000)
    box = Outbox(1000, 64_000_000, Clock(), pool)
    fragments = tuple(bytes([i]) * 1_000_000 for i in range(3))
    box.push("/map", fragments)
    assert take(box) is fragments[0] and pool.shared == 3_000_000
    box.set_backed_up(False)
    assert pool.shared == 2_000_000
    assert take(box) is fragments[1]
    box.set_backed_up(True, in_flight=1_000_000)
    box.set_backed_up(False)
    assert pool.shared == 1_000_000
    box.clear()
    assert (pool.shared, pool.granted) == (0, 0)


def test_a_fragmented_message_leaves_nothing_counted_once_sent_with_or_without_a_pool():
    for pool in (None, QueuePool(100_000_000)):
        box = Outbox(1000, 64_000_000, Clock(), pool)
        fragments = tuple(b"f%d " % i + b"." * SMALL_MESSAGE for i in range(3))
        box.push("/map", fragments)
        box.push("/map", fragments)
        box.backed_up = True
        assert drain(box) == ["f0", "f1", "f2"] * 2
        box.set_backed_up(False)
        assert (len(box), box.bytes, box._own) == (0, 0, 0)
        if pool is not None:
            assert (pool.shared, pool.granted) == (0, 0)


OPS = st.lists(
    st.tuples(st.sampled_from(["small", "big", "fragmented", "take", "backed up", "drained"]), st.sampled_from("ab")),
    max_size=120,
)


@settings(max_examples=300, deadline=None)
@given(ops=OPS)
def test_whatever_is_queued_and_taken_each_topic_keeps_its_order_and_the_counts_come_back_to_zero(ops):
    box, clock = outbox()
    pushed, taken = [], []
    for op, topic in ops:
        clock.now += 0.01
        if op == "take":
            if len(box):
                taken.append(drain_one(box))
        elif op in ("backed up", "drained"):
            box.set_backed_up(op == "backed up")
        else:
            name = f"{topic}{len(pushed)}"
            pushed.append(name)
            box.push(topic, small(name) if op == "small" else big(name, 3 if op == "fragmented" else 1))
    box.set_backed_up(False)
    taken += drain(box)
    messages = [name.split(".")[0] for name in taken]
    for topic in "ab":
        order = [int(name[1:]) for name in dict.fromkeys(messages) if name[0] == topic]
        assert order == sorted(order)
    if not any(op == "backed up" for op, _ in ops):  # (nothing is skipped: everything arrives, whole)
        assert sorted(dict.fromkeys(messages)) == sorted(pushed)
        frames = {"small": 1, "big": 1, "fragmented": 3}
        assert len(taken) == sum(frames.get(op, 0) for op, _ in ops)
    assert (len(box), box.bytes) == (0, 0)


def test_take_frames_takes_the_next_frame_and_more_while_under_the_bytes_asked():
    box, _ = outbox()
    box.push_each("/a", [b"0123456789"] * 10)
    assert len(box.take_frames(0)) == 1  # (one at least, whatever is asked)
    assert len(box.take_frames(25)) == 3  # (10, 20: under 25, one more)
    assert len(box.take_frames(1 << 16)) == 6 and box.take_frames(1 << 16) == []
    assert (len(box), box.bytes, box._own) == (0, 0, 0)
    box.push("/map", big("m", parts=2))  # (not passing: a unit's frames, one at a time)
    assert len(box.take_frames(1 << 16)) == 1 and len(box.take_frames(1 << 16)) == 1 and box.take_frames(0) == []


RUN_OPS = st.lists(
    st.tuples(st.sampled_from(["run", "big", "take", "backed up", "drained"]), st.integers(1, 12)), max_size=80
)


@settings(max_examples=300, deadline=None)
@given(
    ops=RUN_OPS,
    max_frames=st.sampled_from([6, 40, 1000]),
    max_bytes=st.sampled_from([60, 64_000_000]),
    most_bytes=st.sampled_from([0, 12, 1 << 16]),
    pooled=st.booleans(),
)
def test_a_run_pushed_and_taken_in_one_go_is_its_messages_pushed_and_taken_one_by_one(
    ops, max_frames, max_bytes, most_bytes, pooled
):
    """push_each and take_frames, which a Foxglove client's messages go by, keep every rule of push and take:
    the same frames in the same order, the same counts, the same skipped and dropped."""
    clock = Clock(1000.0)
    in_one_go, one_by_one = (
        Outbox(max_frames, max_bytes, clock, QueuePool(64_000_000) if pooled else None) for _ in range(2)
    )
    pushed = 0
    for op, count in ops:
        clock.now += 0.05
        if op == "run":
            frames = [f"r{pushed + n:03}".encode() for n in range(count)]  # (5 bytes each)
            pushed += count
            in_one_go.push_each("/a", frames)
            for frame in frames:
                one_by_one.push("/a", (frame,))
        elif op == "big":
            for box in (in_one_go, one_by_one):
                box.push("/b", big(f"b{pushed}"))
            pushed += 1
        elif op == "take":
            taken = in_one_go.take_frames(most_bytes)
            if taken:
                assert taken == [take(one_by_one) for _ in taken]
            else:
                assert take(one_by_one) is None
        else:
            for box in (in_one_go, one_by_one):
                box.set_backed_up(op == "backed up")
        assert (len(in_one_go), in_one_go.bytes, in_one_go._own) == (len(one_by_one), one_by_one.bytes, one_by_one._own)
    assert in_one_go.take_report() == one_by_one.take_report()
    for box in (in_one_go, one_by_one):
        box.set_backed_up(False)
    assert [bytes(f) for f in iter(lambda: take(in_one_go), None)] == [
        bytes(f) for f in iter(lambda: take(one_by_one), None)
    ]
