"""What the bag recorder's bags take, counted as the disk counts them, and the bounds they are held to (pure: no
rosbag, no rospy, no tornado; bag_recorder.py does the recording).

Sizes follow rosbag's format 2.0 as rosbag.Bag writes it (uncompressed, unencrypted, its default chunks), so that
an empty message costs what it takes on disk: its record's header and its entry in its chunk's index, 58 bytes.
They are upper bounds: a bag's chunks are counted as if each held every connection."""

import array
import collections
import itertools

# "#ROSBAG V2.0\n", then the file header record, padded to 4096 bytes
FILE_HEADER = 13 + 4104
# per message: its data record's header (op, conn, time) and lengths, 46 bytes; its chunk index entry, 12
MESSAGE = 46 + 12
# per chunk: its header record (op, compression, size) and compressed size, 49 bytes; its chunk info record, 108
CHUNK = 49 + 108
# per connection in a chunk: its index data record (op, conn, ver, count), 55 bytes; its count in the chunk info, 8
CHUNK_CONNECTION = 55 + 8
CHUNK_THRESHOLD = 768 * 1024  # rosbag.Bag's default: a chunk ends once its records pass it


def _field(key, value_bytes):
    return 4 + len(key) + 1 + value_bytes


def connection_bytes(topic, cls):
    """A topic's connection record (op, topic, conn, then the header: topic, type, md5sum, message definition);
    cls: the topic's genpy message class. It is written twice: in the chunk of the first message, and in the
    index."""
    topic_bytes = len(topic.encode())
    header = _field("op", 1) + _field("topic", topic_bytes) + _field("conn", 4)
    description = (
        _field("topic", topic_bytes)
        + _field("type", len(cls._type.encode()))
        + _field("md5sum", 32)
        + _field("message_definition", len(cls._full_text.encode()))
    )
    return 4 + header + 4 + description


def bag_bytes(messages, payload, connections):
    """An upper bound of a bag's size on disk: `messages` messages of `payload` bytes in all, on connections
    (connection_bytes of each)."""
    in_chunks = payload + 46 * messages + sum(connections)  # (a chunk ends once these pass the threshold)
    chunks = in_chunks // (CHUNK_THRESHOLD + 1) + 1
    return (
        FILE_HEADER
        + payload
        + MESSAGE * messages
        + 2 * sum(connections)
        + chunks * (CHUNK + CHUNK_CONNECTION * len(connections))
    )


class BagSize:
    """A bag's size as its messages are written (bag_bytes)."""

    def __init__(self):
        self.messages, self.payload = 0, 0
        self._connections = {}  # topic -> connection_bytes

    @property
    def total(self):
        return bag_bytes(self.messages, self.payload, self._connections.values())

    def after(self, topic, cls, length):
        """The total once a message of `length` bytes on topic (of class cls) is written too."""
        connections = self._connections
        if topic not in connections:
            connections = {**connections, topic: connection_bytes(topic, cls)}
        return bag_bytes(self.messages + 1, self.payload + length, connections.values())

    def add(self, topic, cls, length):
        if topic not in self._connections:
            self._connections[topic] = connection_bytes(topic, cls)
        self.messages += 1
        self.payload += length


class FolderSpace:
    """The bag folder's bytes: its finished bags (as last scanned), and for each bag being written the room it
    reserved, which it must not outgrow. A bag reserves before it is written (a save: its whole size; a
    recording: as it grows), so that writes under way never add up past max_bytes."""

    def __init__(self, max_bytes):
        self.max_bytes = max_bytes
        self.on_disk = 0
        self._reserved = {}  # bag name -> bytes

    @property
    def used(self):
        return self.on_disk + sum(self._reserved.values())

    def scan(self, sizes):
        """sizes: {name: bytes} of the folder's bags; those being written count by their reservations."""
        self.on_disk = sum(size for name, size in sizes.items() if name not in self._reserved)

    def writing(self, name):
        return name in self._reserved

    def room(self, name):
        """The bytes bag `name` may take (what it reserved included)."""
        return self.max_bytes - self.used + self._reserved.get(name, 0)

    def reserve(self, name, size):
        """Sets name's reservation to size; False (and nothing reserved) if the folder has not the room."""
        if size > self.room(name):
            return False
        self._reserved[name] = size
        return True

    def release(self, name):
        """name is written (or failed): its file counts from the next scan on."""
        self._reserved.pop(name, None)


# what a black box entry counts for besides its data: more than its record in a bag (MESSAGE), so that a full black
# box's bag is within max_bytes and its header and connections, and more than it takes in memory (its stamp, kind
# and end in arrays, 20 bytes: test_bag_bounds measures it); as much as an entry took as a tuple once, so that a
# full box holds as many messages as then (400,000 empty ones at the defaults), and a save takes as long
ENTRY_BYTES = 160
SEGMENT_ENTRIES, SEGMENT_BYTES = 4096, 1 << 20  # a segment of the black box is full at either


class _Segment:
    """Consecutive entries of the black box in arrays, appended to and never changed otherwise (a save reads them
    on another thread while the box goes on): stamps, kinds (indexes of (topic, cls)), and each entry's end in
    data, the entries' bytes one after the other (bytes once it is full). Entries before `start` have left the
    box."""

    __slots__ = ("stamps", "kinds", "ends", "data", "start")

    def __init__(self):
        self.stamps, self.kinds, self.ends = array.array("d"), array.array("I"), array.array("Q")
        self.data, self.start = bytearray(), 0

    def full(self):
        return len(self.stamps) >= SEGMENT_ENTRIES or len(self.data) >= SEGMENT_BYTES

    def close(self):
        self.data = bytes(self.data)  # its exact size: a bytearray that grew keeps up to 1/8 more

    def begin(self, index):
        return self.ends[index - 1] if index else 0

    def entries(self, start, stop, kinds):
        for index in range(start, stop):
            topic, cls = kinds[self.kinds[index]]
            yield self.stamps[index], topic, cls, bytes(self.data[self.begin(index) : self.ends[index]])


class BlackBox:
    """The black box's messages, oldest first: those of the last `seconds` before the newest, within max_bytes,
    each counted as its data's bytes and ENTRY_BYTES. Entries are (stamp, topic, cls, data), kept in segments of
    arrays (_Segment), not as an object each: the garbage collector's full collections, which a save's writing
    sets off, would otherwise walk hundreds of thousands of them while the loop waits. What has left the box is
    freed a segment at a time: at most SEGMENT_BYTES (or one message) more than `bytes` are held."""

    def __init__(self, seconds, max_bytes):
        self.seconds, self.max_bytes = seconds, max_bytes
        self.bytes = 0
        self._segments = collections.deque()
        self._kinds, self._kind_list = {}, []  # (topic, cls) -> its index in _kind_list
        self._length = 0
        self._payload = 0
        self._topics = collections.Counter()  # topic -> its entries
        self._classes = {}  # topic -> cls, for the connections of a bag

    def __len__(self):
        return self._length

    def add(self, stamp, topic, cls, data):
        kind = self._kinds.get((topic, cls))
        if kind is None:
            kind = self._kinds[topic, cls] = len(self._kind_list)
            self._kind_list.append((topic, cls))
        if not self._segments or self._segments[-1].full():
            if self._segments:
                self._segments[-1].close()
            self._segments.append(_Segment())
        segment = self._segments[-1]
        segment.data += data
        segment.stamps.append(stamp)
        segment.kinds.append(kind)
        segment.ends.append(len(segment.data))
        self._length += 1
        self._count(topic, cls, len(data), 1)
        horizon = stamp - self.seconds
        while self._length and (self._oldest() < horizon or self.bytes > self.max_bytes):
            self._drop_oldest()

    def _oldest(self):
        first = self._segments[0]
        return first.stamps[first.start]

    def _drop_oldest(self):
        first = self._segments[0]
        topic, cls = self._kind_list[first.kinds[first.start]]
        self._count(topic, cls, first.ends[first.start] - first.begin(first.start), -1)
        self._length -= 1
        first.start += 1
        if first.start == len(first.stamps):
            self._segments.popleft()

    def _count(self, topic, cls, length, sign):
        self.bytes += sign * (length + ENTRY_BYTES)
        self._payload += sign * length
        self._topics[topic] += sign
        if sign > 0:
            self._classes[topic] = cls
        elif not self._topics[topic]:
            del self._topics[topic], self._classes[topic]

    def entries(self):
        """The entries as they are now (for a save, which reads them on another thread while the box goes on),
        oldest first, each (stamp, topic, cls, data) made as it is read."""
        parts = [(segment, segment.start, len(segment.stamps)) for segment in self._segments]
        kinds = list(self._kind_list)
        return itertools.chain.from_iterable(segment.entries(start, stop, kinds) for segment, start, stop in parts)

    def bag_bytes(self):
        """What a bag of the entries takes on disk (an upper bound)."""
        return bag_bytes(
            self._length, self._payload, [connection_bytes(topic, cls) for topic, cls in self._classes.items()]
        )
