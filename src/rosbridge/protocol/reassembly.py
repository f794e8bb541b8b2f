"""Incoming messages that arrive in pieces: `fragment` ops put back together, and `png` ops unpacked. Pure."""

import base64
import io

from PIL import Image

from rosbridge.codec.wrapping import png_unframe
from rosbridge.errors import RequestError

PART_OVERHEAD = 128  # bytes a stored part is counted beyond its text: what it costs (its number and its slot in the
# set, about 85 bytes measured with tracemalloc) with room to spare, so that empty parts fill the budget too


class Fragments:
    """One client's unfinished fragmented messages, bounded in number and in bytes (max_bytes 0: no byte
    bound), each dropped fragment_timeout seconds after its first part arrived (expire: the Session's timer).
    What they hold also counts against `shared` (rfc6455.SharedBound, if given: the unfinished messages
    of every client together): a part that would go beyond it is refused, its message dropped; and when another
    client's message needs the room and came faster, all of them are dropped (evict) and evicted(count) says
    how many."""

    MAX_SETS = 100

    def __init__(self, max_bytes, timeout, shared=None, evicted=None):
        self.max_bytes, self.timeout, self._shared, self._evicted = max_bytes, timeout, shared, evicted
        self._sets = {}  # fragment id -> [total, {num: data}, deadline]
        self.bytes = 0

    def add(self, frag_id, num, total, data, now):
        """Stores one part; returns the whole text once every part is in, else None."""
        limit = self.max_bytes
        if total < 1 or not 0 <= num < total or (limit and total > limit):
            raise RequestError(f"fragment: num {num} / total {total} out of range")
        entry = self._sets.get(frag_id)
        if entry is None:
            if len(self._sets) >= self.MAX_SETS:
                raise RequestError(f"fragment: too many unfinished fragmented messages ({self.MAX_SETS})")
            entry = self._sets[frag_id] = [total, {}, now + self.timeout]
        if entry[0] != total:
            raise RequestError(f"fragment {frag_id!r}: total changed from {entry[0]} to {total}")
        previous = entry[1].get(num)
        growth = len(data) - (len(previous) if previous is not None else -PART_OVERHEAD)
        if limit and self.bytes + growth > limit:
            self._drop(frag_id)
            raise RequestError(f"fragment {frag_id!r}: reassembled message over max_message_size ({limit} bytes)")
        if self._shared is not None and not self._shared.hold(self, self.bytes + growth):
            self._drop(frag_id)
            raise RequestError(
                f"fragment {frag_id!r}: dropped, the unfinished messages of all clients are at their "
                f"bound ({self._shared.limit} bytes): try again later"
            )
        self.bytes += growth
        entry[1][num] = data
        if len(entry[1]) < total:
            return None
        parts = entry[1]
        self._drop(frag_id)
        return "".join(parts[i] for i in range(total))

    def expire(self, now):
        """Drops the sets past their deadline; yields (id, parts received, total) of each."""
        for frag_id, entry in list(self._sets.items()):
            if entry[2] <= now:
                self._drop(frag_id)
                yield frag_id, len(entry[1]), entry[0]

    def next_deadline(self):
        """When the next set is dropped if it is not whole by then, or None."""
        return min((entry[2] for entry in self._sets.values()), default=None)

    def ids(self):
        return list(self._sets)

    def clear(self):
        self._sets.clear()
        self.bytes = 0
        if self._shared is not None:
            self._shared.hold(self, 0)

    def evict(self):
        """The shared bound took back what these hold, for another client's message that came faster."""
        count = len(self._sets)
        self.clear()
        if self._evicted is not None:
            self._evicted(count)

    def _drop(self, frag_id):
        entry = self._sets.pop(frag_id)
        self.bytes -= sum(len(part) + PART_OVERHEAD for part in entry[1].values())
        if self._shared is not None:
            self._shared.hold(self, self.bytes)


def unpack_png(data, max_bytes):
    """The JSON text inside a png op's base64 `data`, refusing images over max_bytes (0: no limit) unpacked."""
    try:
        with Image.open(io.BytesIO(base64.b64decode(data))) as image:  # reads the header only
            size = image.width * image.height * 3
        if max_bytes and size > max_bytes:  # a small PNG can unpack to gigabytes
            raise RequestError(f"png: image holds {size} bytes, over max_message_size ({max_bytes} bytes)")
        return png_unframe(data)
    except (ValueError, OSError) as error:  # bad base64, not a PNG, not UTF-8
        raise RequestError(f"png: cannot read the image: {error}") from None
