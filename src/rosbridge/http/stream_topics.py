"""Each camera topic that viewers watch (StreamTopic): its subscription (one per topic through the bridge's
RosBackend, shared with the websocket clients; StreamTopic is its contract.Client), its newest frame (Frame) and
what was made of it, and the jobs it gives the encoder thread (camera_encoder.py says how topics take turns there).
A frame is made at most once per (size, quality, invert) for every viewer, and only when a viewer wants it. All of
it runs on the loop."""

import functools
import time

from rosbridge.http import jpeg
from rosbridge.http.no_op_client import NoOpClient

LINGER = 5.0  # seconds a topic's subscription outlives its last viewer (a reload or the next snapshot reuses it)
MAX_KEYS_PER_JOB = 8  # variants one encoding job makes; more wait for the next job (the topic's next turn)
JOB_PIXELS = 4_000_000  # and pixels in all (one variant at least): a topic's turn at the encoder, ~0.1 s here
MAX_VARIANT_BYTES = 16 * 1024 * 1024  # the variants a frame keeps, newest first (older ones are made again if asked)
PASS = "pass"  # the key of a CompressedImage sent as it is


class Frame:
    """One message of a topic, and what was made of it for its viewers (on the loop): variants, key -> (content
    type, bytes) or the jpeg.ImageError that making it raised, oldest first, at most MAX_VARIANT_BYTES of them
    (trim)."""

    __slots__ = ("seq", "type", "message", "variants", "picture", "_read")

    def __init__(self, seq, type_name, message):
        self.seq, self.type, self.message = seq, type_name, message
        self.variants = {}
        self.picture = None  # its jpeg.Picture, made for its first encoding job (then used by the encoder only)
        self._read = None

    def read(self):
        """The message read in place (jpeg.RawImage or CompressedFrame); raises jpeg.ImageError."""
        if self._read is None:
            try:
                self._read = jpeg.read_frame(self.type, self.message.data)
            except jpeg.ImageError as error:
                self._read = error
        if isinstance(self._read, jpeg.ImageError):
            raise self._read
        return self._read

    def trim(self):
        """Forgets the oldest variants beyond MAX_VARIANT_BYTES (the newest too if larger alone, once its viewers
        have it): a viewer asking one again has it made again."""
        kept = 0
        for key in reversed(list(self.variants)):
            made = self.variants[key]
            if key != PASS and isinstance(made, tuple):  # (PASS is the message's own bytes, an error is small)
                kept += len(made[1])
                if kept > MAX_VARIANT_BYTES:
                    del self.variants[key]

    @property
    def stamp(self):
        """Its header stamp, or when the bridge received it if the stamp is unset (X-Timestamp)."""
        try:
            return self.read().stamp or self.message.stamp
        except jpeg.ImageError:
            return self.message.stamp


class StreamTopic(NoOpClient):
    """One topic that viewers watch: its subscription (this object is its contract.Client), its newest frame and
    the viewers waiting for it to be made as they ask."""

    def __init__(self, streams, source):
        self._streams, self.topic, self.type = streams, source.topic, source.type
        self.viewers = set()
        self.latest = None
        self.interval = jpeg.FrameInterval()
        self.is_closed = False
        self._seq = 0
        self._waiting = {}  # viewers waiting for the newest frame to be made as they ask (in order)
        self._job = None  # the frame being encoded
        self._linger = None
        self._offering = False  # a new frame is being offered to every viewer: one job for all of them after

    def add(self, viewer):
        if self._linger is not None:
            self._streams.loop.remove_timeout(self._linger)
            self._linger = None
        self.viewers.add(viewer)

    def remove(self, viewer):
        self.viewers.discard(viewer)
        self._waiting.pop(viewer, None)
        if not self.viewers and not self.is_closed and self._linger is None:
            self._linger = self._streams.loop.call_later(LINGER, self.close)

    def close(self):
        if self.is_closed:
            return
        self.is_closed = True
        self._linger = None
        if self._streams.topics.get(self.topic) is self:
            del self._streams.topics[self.topic]
        self.latest, self._waiting = None, {}
        self._streams.backend.unsubscribe(self, self.topic)
        for viewer in list(self.viewers):
            viewer.fail(503, f"the subscription to {self.topic} ended")

    # ---- contract.Client
    def deliver(self, read):
        for message in read.messages:
            self._arrived(message)

    def _arrived(self, message):
        if self.is_closed:
            return
        self._seq += 1
        frame, old = Frame(self._seq, self.type, message), self.latest
        self.latest = frame
        if old is not None:
            old.picture = None  # (a job still making it holds its own reference)
        self.interval.arrived(time.monotonic())
        self._offering = True
        try:
            for viewer in list(self.viewers):
                viewer.new_frame(frame)
        finally:
            self._offering = False
        self._kick()

    def ros_refused(self, op, name, text):
        for viewer in list(self.viewers):
            viewer.fail(503, text)
        self.close()

    # ---- making frames for viewers
    def want(self, viewer):
        """The viewer (not writing) wants the newest frame it has not had, made as it asks."""
        frame = self.latest
        if self.is_closed or frame is None or frame.seq <= viewer.sent_seq:
            return  # (the next frame will be offered to it)
        if self._serve(viewer, frame) is None:
            self._waiting.pop(viewer, None)
        else:
            self._waiting[viewer] = None
            self._kick()

    def _serve(self, viewer, frame):
        """Gives the viewer `frame` if what it wants of it is made (or cannot be); else returns its key."""
        try:
            key = viewer.key_for(frame)
            if key == PASS and PASS not in frame.variants:
                compressed = frame.read()
                frame.variants[PASS] = (jpeg.compressed_content_type(compressed.format), compressed.data)
        except jpeg.ImageError as error:
            viewer.take(frame, error)
            return None
        made = frame.variants.get(key)
        if made is None:
            return key
        viewer.take(frame, made)
        return None

    def _kick(self):
        """Starts an encoding job for the waiting viewers, of the newest frame, unless one runs."""
        if self._job is not None or not self._waiting or self.is_closed or self._offering:
            return
        frame, keys, pixels = self.latest, [], 0
        for viewer in list(self._waiting):
            if viewer not in self._waiting:  # (it left as another was served)
                continue
            if frame.seq <= viewer.sent_seq:
                del self._waiting[viewer]
                continue
            key = self._serve(viewer, frame)
            if key is None:
                self._waiting.pop(viewer, None)
            elif key not in keys and len(keys) < MAX_KEYS_PER_JOB:
                area = key[0][0] * key[0][1]
                if not keys or pixels + area <= JOB_PIXELS:
                    keys.append(key)
                    pixels += area
        if not keys:
            return
        keys.sort(key=lambda key: key[0])  # (the qualities of one size one after the other: resized once)
        if frame.picture is None:
            frame.picture = jpeg.Picture(frame.read())
        self._job = frame
        self._streams.encoder.submit(frame.picture, keys, functools.partial(self._encoded, frame))

    def _encoded(self, frame, results):
        self._job = None
        if self.is_closed:
            return
        frame.variants.update(results)
        if frame is not self.latest:
            frame.picture = None
        for viewer in list(self._waiting):
            if viewer in self._waiting and frame.seq > viewer.sent_seq and self._serve(viewer, frame) is None:
                self._waiting.pop(viewer, None)
        frame.trim()
        self._kick()
