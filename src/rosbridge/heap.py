"""The bridge's big buffers: how many bytes those shared by several holders take (SharedBuffers), and glibc's
malloc.

glibc's malloc by default maps a buffer of a few MB on its own and unmaps it when it is freed, or, once its adaptive
threshold has grown past that size, gives the heap's top back when a message's buffers are freed together. Either
way every camera image, cloud or map the bridge converts is written into fresh pages, which the kernel faults in one
at a time: 3,500 faults for a 4.8 MB cloud, more CPU than converting it (bench/README.md, "Where the time goes").
Kept in the heap instead, the same pages serve the next message. The cost is bounded: at most REUSE_BYTES of freed
memory kept per malloc arena (the loop's, and each encoding thread's), and a buffer bigger than that (a 16 MB map,
its 40 MB of JSON) still mapped and given back at once: with 32 MB, the map's buffers stayed in the heap too, and a
map sent again after clouds and maps peaked 13 % higher than the first (fragments of the kept memory did not fit
it)."""

import ctypes

REUSE_BYTES = 8 << 20  # a camera image, a 300k-point cloud and their JSON; not a map
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # mallopt's parameters (malloc.h)


def reuse_big_buffers(limit=REUSE_BYTES):
    """Asks glibc to serve buffers of up to `limit` bytes from the heap and to keep up to `limit` bytes freed at
    its top. True if it did; False with another C library (nothing changes)."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, limit)) and bool(mallopt(_M_TRIM_THRESHOLD, limit))


class SharedBuffers:
    """Buffers held by several holders at once (one picture sent to many clients), each counted once in `bytes`
    however many hold it, and kept until its last holder has released it. Pure: it knows nothing of holders."""

    def __init__(self):
        self.bytes = 0  # of the distinct buffers held
        self._held = {}  # id(buffer) -> [buffer, how many holds]; the buffer itself keeps its id from being reused

    def __contains__(self, buffer):
        return id(buffer) in self._held

    def holds(self, buffer):
        """How many holds `buffer` has (0 when nobody holds it)."""
        entry = self._held.get(id(buffer))
        return 0 if entry is None else entry[1]

    def hold(self, buffer):
        entry = self._held.get(id(buffer))
        if entry is None:
            self._held[id(buffer)] = [buffer, 1]
            self.bytes += len(buffer)
        else:
            entry[1] += 1

    def release(self, buffer):
        """One hold fewer; its bytes go with its last hold."""
        entry = self._held[id(buffer)]
        entry[1] -= 1
        if not entry[1]:
            del self._held[id(buffer)]
            self.bytes -= len(buffer)
