"""transport/slow_link.py: whether a client's link is slow (LinkMeter), whether a message goes to it deflated,
and one deflated payload made for every client that gets a frame compressed."""

import zlib

import pytest

from rosbridge.protocol import encoded as frames
from rosbridge.transport import slow_link
from rosbridge.transport.slow_link import DEFLATE_MIN_BYTES, SLOW_LINK_BYTES_PER_SECOND, LinkMeter, sends_deflated

from fakes import OffLoop


# ---- LinkMeter: is a client's link slow enough that its big messages go deflated? ----------------------------
def test_a_link_is_not_judged_before_a_write_waited():
    meter = LinkMeter()
    assert meter.rate is None and not meter.slow


def test_a_camera_frame_that_drains_at_20_mbit_s_makes_the_link_slow():
    meter = LinkMeter()
    meter.waited(1_228_800, 0.52)  # one raw 640x480 frame as JSON through a 19 Mbit/s link
    assert meter.slow and 2e6 < meter.rate < 3e6


def test_loopback_is_fast_even_when_its_writes_wait():
    meter = LinkMeter()
    for _ in range(20):
        meter.waited(1_228_800, 0.004)  # the reader takes a frame in 4 ms (300 MB/s)
    assert not meter.slow
    meter.waited(1_228_800, 0.2)  # one pause of the reader (its machine busy) does not make it slow
    assert not meter.slow


def test_small_writes_that_waited_are_not_enough_to_judge_a_link():
    meter = LinkMeter()
    for _ in range(100):
        meter.waited(2_000, 0.013)  # a pose that waited for the kernel to drain what came before
    assert meter.rate < SLOW_LINK_BYTES_PER_SECOND and not meter.slow


def test_a_link_that_speeds_up_is_fast_again_within_a_few_big_writes():
    meter = LinkMeter()
    for _ in range(10):
        meter.waited(620_000, 0.26)  # deflated frames through 19 Mbit/s
    assert meter.slow
    writes = 0
    while meter.slow:
        meter.waited(1_228_800, 0.01)  # then a wired link
        writes += 1
    assert writes <= 4


def test_only_big_messages_go_deflated_to_a_slow_link_and_every_one_with_use_compression():
    slow, fast, unknown = LinkMeter(), LinkMeter(), LinkMeter()
    slow.waited(1_228_800, 0.52)
    fast.waited(1_228_800, 0.004)
    assert sends_deflated(DEFLATE_MIN_BYTES, False, slow) and not sends_deflated(DEFLATE_MIN_BYTES - 1, False, slow)
    assert not sends_deflated(1 << 20, False, fast) and not sends_deflated(1 << 20, False, unknown)
    assert all(sends_deflated(size, True, link) for size in (10, 1 << 20) for link in (slow, fast, unknown))


# ---- one deflated payload for every client that sends a frame compressed (slow_link.deflated_payload) ----------


@pytest.mark.parametrize(
    "frame",
    [
        frames.Utf8Text(b'{"op":"publish","msg":"' + b"ab" * 50_000 + b'"}'),
        frames.SplicedFrame([b'{"op":"publish","msg":{"data":"', b"QUJD" * 30_000, b'"}}'], text=True),
    ],
    ids=["text", "spliced"],
)
def test_a_big_frame_is_deflated_once_for_every_client_and_kept_with_it(frame):
    off_loop, got = OffLoop(), []
    for _client in range(3):
        assert slow_link.deflated_payload(frame, 15, off_loop, got.append) is None
    assert len(off_loop.jobs) == 1
    off_loop.run_all()
    assert len(got) == 3 and got[0] is got[1] is got[2]
    assert zlib.decompressobj(-15).decompress(got[0] + b"\x00\x00\xff\xff") == bytes(frame)
    assert slow_link.deflated_payload(frame, 15, off_loop, got.append) is got[0] and not off_loop.jobs  # a later client
    assert slow_link.deflated_payload(frame, 10, off_loop, got.append) is None  # another window: made for it
    off_loop.run_all()
    assert zlib.decompressobj(-10).decompress(got[-1] + b"\x00\x00\xff\xff") == bytes(frame)


def test_a_failed_deflate_is_told_and_tried_again_next_time():
    frame, off_loop, got = frames.Utf8Text(b"x" * 100_000), OffLoop(), []
    slow_link.deflated_payload(frame, 15, off_loop, got.append)
    ((fn, then),) = off_loop.jobs
    off_loop.jobs.clear()
    then(None)  # (what off_loop.EncodingThread gives when fn raised)
    assert got == [None]
    assert slow_link.deflated_payload(frame, 15, off_loop, got.append) is None and len(off_loop.jobs) == 1


def test_a_small_frame_is_deflated_at_once_and_a_plain_bytes_one_each_time():
    text = frames.Utf8Text(b'{"op":"status","level":"info","msg":"hello"}')
    packed = slow_link.deflated_payload(text, 15)
    assert slow_link.deflated_payload(text, 15) is packed
    binary = b"\xa2" + b"x" * 80_000
    off_loop = OffLoop()
    slow_link.deflated_payload(binary, 15, off_loop, lambda payload: None)
    slow_link.deflated_payload(binary, 15, off_loop, lambda payload: None)
    assert len(off_loop.jobs) == 2
