"""What the bridge sends: frames ready for the socket, each encoded once for every client it goes to (and deflated
once per window size for every client it goes to compressed: transport/slow_link.deflated_payload keeps those on
the frame)."""

import itertools

from rosbridge.codec import cbor, wrapping
from rosbridge.codec.json_values import dumps
from rosbridge.codec.ros_to_cbor import cbor_value
from rosbridge.codec.ros_to_json import SPLICE_MARK, joined, json_parts

COMPRESSIONS = ("none", "png", "cbor", "cbor-raw")


class Utf8Text(bytes):
    """A text frame already encoded to UTF-8, so that it is encoded once for all the clients it goes to."""

    deflated = None  # (no __slots__: a frame may keep its deflated payloads, see transport/slow_link.deflated_payload)


class SplicedFrame:
    """A frame whose payload is `parts` (bytes) one after another, written to the socket by reference: the big
    parts (an image's data, or its base64) are never copied into a frame of their own. text: UTF-8 text, else
    binary."""

    __slots__ = ("parts", "text", "_size", "deflated")

    def __init__(self, parts, text):
        self.parts, self.text, self._size = parts, text, sum(map(len, parts))
        self.deflated = None  # see transport/slow_link.deflated_payload

    def __len__(self):
        return self._size

    def __bytes__(self):
        return b"".join(self.parts)


def cbor_frame(obj):
    """The binary frame holding `obj` in CBOR (see codec.cbor.cbor_parts)."""
    return _binary_frame(cbor.cbor_parts(obj))


def _binary_frame(parts):
    return parts[0] if len(parts) == 1 else SplicedFrame(parts, text=False)


def status_frame(level, msg, request_id=None):
    frame = {"op": "status", "level": level, "msg": msg}
    if request_id is not None:
        frame["id"] = request_id
    return dumps(frame)


_fragment_ids = itertools.count(1)


def fragment_text(text, fragment_size):
    if fragment_size is None or len(text) <= fragment_size:
        return (text,)
    return tuple(dumps(f) for f in wrapping.fragments(text, fragment_size, f"fragment:{next(_fragment_ids)}"))


def text_frames(text, compression, fragment_size):
    """The JSON text of one op as the frames that carry it: inside a png op if asked, then in fragments."""
    if compression == "png":
        text = dumps({"op": "png", "data": wrapping.png_frame(text)})
    return tuple(Utf8Text(part.encode()) for part in fragment_text(text, fragment_size))


OFF_LOOP_BYTES = 1 << 20  # a message this big is encoded off the event loop (a map takes seconds as JSON)


class TopicRead:
    """What one read of a topic's publisher brought: the messages' bytes (`datas`, in order), which share their
    receipt time `stamp` (seconds); or one message a publisher latches. Their TopicMessages, which rosbridge
    clients encode, are made once, when a client first asks (`messages`): a Foxglove client sends the bytes as they
    came, and never does."""

    __slots__ = ("topic", "msg_class", "datas", "stamp", "_messages")

    def __init__(self, topic, msg_class, datas, stamp):
        self.topic, self.msg_class, self.datas, self.stamp = topic, msg_class, datas, stamp
        self._messages = None

    @property
    def messages(self):
        if self._messages is None:
            self._messages = [TopicMessage(self.topic, self.msg_class, data, self.stamp) for data in self.datas]
        return self._messages

    def last(self):
        """The read of its last message alone, the same TopicMessage: what a latching publisher gives a client
        that subscribes later."""
        if len(self.datas) == 1:
            return self
        last = TopicRead(self.topic, self.msg_class, self.datas[-1:], self.stamp)
        last._messages = self.messages[-1:]
        return last


class TopicMessage:
    """One ROS message from a topic, as rospy received it (msg_class: its genpy class; data: its serialized bytes),
    encoded lazily and at most once per encoding for all its subscribers. stamp: its receipt time in seconds (sent
    with cbor-raw). A big one (`big`) is encoded off the loop: frames_later."""

    __slots__ = ("topic", "msg_class", "data", "stamp", "_json", "_frames", "_waiting")

    def __init__(self, topic, msg_class, data, stamp):
        self.topic, self.msg_class, self.data, self.stamp = topic, msg_class, data, stamp
        self._json = None  # the frames of the usual case: plain JSON, not fragmented
        self._frames = None  # (compression, fragment_size) -> frames, for the others
        self._waiting = None  # (compression, fragment_size) -> callbacks waiting for an encoding off the loop

    @property
    def big(self):
        return len(self.data) >= OFF_LOOP_BYTES

    def frames_later(self, compression, fragment_size, off_loop, then):
        """Calls then(frames) on the loop once the frames are encoded: by off_loop(encode, done), which runs
        encode() on another thread and done(result) on the loop (result None: it failed, and was logged); once
        for every subscriber that asks meanwhile."""
        key = (compression, fragment_size)
        done = self._json if key == ("none", None) else (self._frames or {}).get(key)
        if done is not None:
            then(done)
            return
        if self._waiting is None:
            self._waiting = {}
        if key in self._waiting:
            self._waiting[key].append(then)
            return
        self._waiting[key] = [then]
        off_loop(lambda: self._encode(compression, fragment_size), lambda frames: self._encoded(key, frames))

    def _encoded(self, key, frames):
        if frames is not None:
            if key == ("none", None):
                self._json = frames
            else:
                if self._frames is None:
                    self._frames = {}
                self._frames[key] = frames
        for then in self._waiting.pop(key):
            then(frames)

    def frames(self, compression, fragment_size):
        """The frames (Utf8Text for text, bytes for binary, SplicedFrame for either) that carry this message with
        these options."""
        if compression == "none" and fragment_size is None:
            if self._json is None:
                self._json = self._encode(compression, fragment_size)
            return self._json
        if self._frames is None:
            self._frames = {}
        key = (compression, fragment_size)
        frames = self._frames.get(key)
        if frames is None:
            frames = self._frames[key] = self._encode(compression, fragment_size)
        return frames

    def _encode(self, compression, fragment_size):
        if compression == "cbor":
            msg = cbor_value(self.msg_class)(self.data)  # (straight from the bytes: no genpy message)
            return (cbor_frame({"op": "publish", "topic": self.topic, "msg": msg}),)
        if compression == "cbor-raw":
            return (_binary_frame(cbor.raw_publish_parts(self.topic, self.data, self.stamp)),)
        text, spliced = json_parts(self.msg_class)(self.data)
        text = '{"op":"publish","topic":%s,"msg":%s}' % (dumps(self.topic), text)
        if spliced and compression == "none" and fragment_size is None:
            pieces = text.encode().split(SPLICE_MARK.encode())
            return (SplicedFrame([*itertools.chain.from_iterable(zip(pieces, spliced)), pieces[-1]], text=True),)
        return text_frames(joined(text, spliced), compression, fragment_size)


def service_response_frames(service, call_id, ok, values, compression="none", fragment_size=None):
    frame = {"op": "service_response", "service": service, "values": values, "result": ok}
    if call_id is not None:
        frame["id"] = call_id
    if compression in ("cbor", "cbor-raw"):
        return (cbor_frame(frame),)
    return text_frames(dumps(frame), compression, fragment_size)
