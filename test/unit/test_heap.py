"""heap.reuse_big_buffers: a big buffer freed and made again reuses the same pages (no fresh page faults).
heap.SharedBuffers: a buffer held by several counts once, until its last hold goes."""

import subprocess
import sys

from rosbridge.heap import SharedBuffers

CHILD = """
import resource, sys
sys.path.insert(0, {src!r})
from rosbridge.heap import reuse_big_buffers
if {reuse}:
    assert reuse_big_buffers()
image = bytes(1_200_000)  # a camera image's base64


def convert():  # buffers of one message at once (its bytes, its text, its frame), then freed together
    text, frame, copy = bytearray(image), bytearray(image), bytearray(image)


for _ in range(3):  # glibc's threshold adapts to the sizes seen
    convert()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(20):
    convert()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def faults(reuse):
    src = __file__.rsplit("/test/", 1)[0] + "/src"
    return int(subprocess.check_output([sys.executable, "-c", CHILD.format(src=src, reuse=reuse)], text=True))


def test_a_big_buffer_made_again_is_not_faulted_in_afresh():
    pages = 3 * 1_200_000 // 4096  # of one message
    assert faults(False) > 10 * pages  # glibc's default: the freed top is given back, faulted in again each time
    assert faults(True) < pages  # the same pages again


def test_a_buffer_held_by_several_counts_once_until_its_last_hold_goes():
    shared, picture, other = SharedBuffers(), bytes(100), bytes(30)
    shared.hold(picture)
    shared.hold(picture)
    shared.hold(other)
    assert shared.bytes == 130 and picture in shared and shared.holds(picture) == 2
    shared.release(picture)
    assert shared.bytes == 130 and shared.holds(picture) == 1
    shared.release(picture)
    assert shared.bytes == 30 and picture not in shared and shared.holds(picture) == 0
    assert bytes(100) not in shared  # (an equal buffer is another buffer)
    shared.release(other)
    assert shared.bytes == 0
