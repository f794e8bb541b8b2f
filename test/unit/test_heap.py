"""heap.reuse_big_buffers: a big buffer freed and made again reuses the same pages (no fresh page faults)."""

import subprocess
import sys

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
