"""bag_bounds: a bag's size as rosbag writes it (checked against files rosbag.Bag writes), the folder's space with
its reservations, and the black box's bounds (its memory measured)."""

import gc
import random
import tracemalloc

import genpy
import pytest
import rosbag
from sensor_msgs.msg import Image
from std_msgs.msg import Empty, String

from rosbridge.http.bag_bounds import (
    CHUNK,
    CHUNK_CONNECTION,
    CHUNK_THRESHOLD,
    ENTRY_BYTES,
    FILE_HEADER,
    MESSAGE,
    BagSize,
    BlackBox,
    FolderSpace,
    connection_bytes,
)


def written(tmp_path, messages):
    """The size of the bag rosbag.Bag writes of messages [(topic, cls, data)], as bag_recorder.py writes them (raw)."""
    path = tmp_path / "check.bag"
    with rosbag.Bag(str(path), "w") as bag:
        for i, (topic, cls, data) in enumerate(messages):
            bag.write(topic, (cls._type, data, cls._md5sum, cls), genpy.Time.from_sec(1000 + i / 1000), raw=True)
    return path.stat().st_size


def counted(messages):
    size = BagSize()
    for topic, cls, data in messages:
        size.add(topic, cls, len(data))
    return size.total


def test_an_empty_message_costs_its_record_and_index_entry(tmp_path):
    one, thousand = [("/e", Empty, b"")], [("/e", Empty, b"")] * 1000
    assert written(tmp_path, thousand) - written(tmp_path, one) == 999 * MESSAGE
    assert (
        counted(one)
        == written(tmp_path, one)
        == FILE_HEADER + MESSAGE + 2 * connection_bytes("/e", Empty) + CHUNK + CHUNK_CONNECTION
    )


@pytest.mark.parametrize(
    "count, kinds",
    [
        (1000, [("/e", Empty, 0)]),
        (100_000, [("/e", Empty, 0)]),  # 6 chunks
        (20_000, [("/e", Empty, 0), ("/text", String, 300), ("/camér\u00e4", Image, 5000)]),  # (non-ASCII names too)
    ],
)
def test_the_size_is_the_file_s_when_every_chunk_holds_every_topic(tmp_path, count, kinds):
    rng = random.Random(count)
    messages = [
        (topic, cls, bytes(rng.randint(0, most))) for topic, cls, most in (rng.choice(kinds) for _ in range(count))
    ]
    assert counted(messages) == written(tmp_path, messages)


def test_the_size_is_an_upper_bound_otherwise(tmp_path):
    rng = random.Random(7)
    messages = [rng.choice([("/image", Image, bytes(300_000)), ("/text", String, bytes(30))]) for _ in range(300)]
    real = written(tmp_path, messages)  # (chunks of one or two images: some without /text)
    assert real <= counted(messages) <= real + CHUNK_CONNECTION * (real // CHUNK_THRESHOLD + 1)
    assert written(tmp_path, []) <= BagSize().total


def test_after_is_the_total_once_the_message_is_added():
    size = BagSize()
    for topic, cls, length in [("/a", Empty, 0), ("/a", Empty, 0), ("/b", String, 10)]:
        expected = size.after(topic, cls, length)
        size.add(topic, cls, length)
        assert size.total == expected


def test_reservations_add_up_within_the_bound():
    space = FolderSpace(100_000)
    space.scan({"old.bag": 30_000})
    assert space.reserve("save1.bag", 40_000) and not space.reserve("save2.bag", 40_000)  # 110 kB: refused
    assert space.used == 70_000 and not space.writing("save2.bag")
    assert space.room("recording.bag") == 30_000
    assert space.reserve("recording.bag", 10_000) and space.reserve("recording.bag", 30_000)  # (grows)
    assert not space.reserve("recording.bag", 30_001)
    space.scan({"old.bag": 30_000, "save1.bag": 12_345, "recording.bag": 999})  # being written: reserved counts
    assert space.used == 100_000
    space.release("save1.bag")
    space.scan({"old.bag": 30_000, "save1.bag": 39_000, "recording.bag": 999})  # written: the file counts
    assert space.used == 99_000 and space.room("recording.bag") == 31_000


def test_the_black_box_counts_each_message_and_keeps_the_newest():
    box = BlackBox(seconds=10, max_bytes=100 * ENTRY_BYTES)
    for i in range(1000):
        box.add(i / 1000, "/e", Empty, b"")
    assert len(box) == 100 and box.bytes == 100 * ENTRY_BYTES
    assert [entry[0] for entry in box.entries()] == [i / 1000 for i in range(900, 1000)]
    box.add(100.0, "/text", String, b"x" * 50)  # 10 s later: the others are past the horizon
    assert len(box) == 1 and box.bytes == ENTRY_BYTES + 50
    assert box.bag_bytes() == BagSize().after("/text", String, 50)


def test_a_black_box_bag_is_within_what_the_box_counts_and_its_connections(tmp_path):
    box = BlackBox(seconds=60, max_bytes=20_000)
    for i in range(5000):
        box.add(i / 1000, "/e", Empty, b"")
        box.add(i / 1000, "/text", String, bytes(i % 40))
    entries = [(topic, cls, data) for _, topic, cls, data in box.entries()]
    assert (
        written(tmp_path, entries)
        <= box.bag_bytes()
        <= FILE_HEADER
        + box.max_bytes
        + 2 * (connection_bytes("/e", Empty) + connection_bytes("/text", String))
        + CHUNK
        + 2 * CHUNK_CONNECTION
    )


@pytest.mark.parametrize("kind", [bytes, bytearray])
def test_an_entry_takes_some_20_bytes_of_memory_besides_its_data(kind):
    box, count, length = BlackBox(seconds=1e9, max_bytes=1 << 40), 20_000, 10
    source = bytes(range(length))
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for i in range(count):
            box.add(float(i), "/e", String, kind(source))  # (float(i): a stamp of its own, as a message has)
        taken = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert len(box) == count and taken / count <= 24 + length, taken / count  # (ENTRY_BYTES counts more: 160)


def test_the_black_box_gives_the_collector_nothing_to_walk_per_entry():
    """A full black box holds 400,000 entries at the defaults (Empty at 12.5 kHz): were each a tuple, every full
    collection the writer's allocations set off (a save) would walk them all, stalling the loop (517 ms measured)."""
    box = BlackBox(seconds=1e9, max_bytes=1 << 40)
    gc.collect()
    before = len(gc.get_objects())
    for i in range(20_000):
        box.add(float(i), "/e", String, bytes(10))
    copy = box.entries()
    assert len(gc.get_objects()) - before < 100
    assert sum(1 for _ in copy) == 20_000


def test_a_save_reads_the_entries_as_they_were_while_the_box_goes_on():
    """Entries span segments (full at 4096 entries or 1 MB); a copy taken for a save keeps what the box held then,
    oldest first, whatever the box takes in or lets go of afterwards."""

    def message(i):
        return ("/a", String, i.to_bytes(4, "little") * (i % 7)) if i % 3 else ("/b", Empty, b"")

    big = ("/big", Image, bytes(range(256)) * 12_000)  # 3 MB: a segment of its own
    box = BlackBox(seconds=1e9, max_bytes=10_000 * ENTRY_BYTES + 3_200_000)
    added = []
    for i in range(12_000):
        entry = big if i == 5000 else message(i)
        box.add(float(i), *entry)
        added.append((float(i), *entry))
    kept = added[-len(box) :]
    assert len(box) < 12_000 and kept[0][0] > 0 and box.bytes <= box.max_bytes
    copy = box.entries()
    for i in range(12_000, 30_000):  # (every entry of the copy leaves the box)
        box.add(float(i), *message(i))
    assert list(copy) == kept
    assert [entry[0] for entry in box.entries()] == [float(i) for i in range(30_000 - len(box), 30_000)]
