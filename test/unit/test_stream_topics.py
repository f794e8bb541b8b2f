"""http/stream_*.py without processes: a topic's frames made once per (frame, size, quality) for all its viewers, only
when a viewer wants them, one encoding job at a time with the newest frame winning, jobs bounded in pixels and
topics taking turns, a frame's variants bounded in bytes; the pictures being sent to the viewers bounded in bytes
(jpeg.Sending); the requests' parameters and which topic a request streams from."""

import concurrent.futures
import io
import socket

import pytest
from sensor_msgs.msg import Image as RosImage

from rosbridge.http import camera_encoder, jpeg, stream_requests, stream_topics, stream_viewers
from rosbridge.protocol.encoded import TopicRead

from fakes import Loop


class FakeEncoder:
    """Holds each job until the test finishes it; the JPEG of a key is a text naming the frame and the key."""

    def __init__(self):
        self.jobs = []

    def submit(self, picture, keys, done):
        self.jobs.append((picture, list(keys), done))

    def finish(self):
        picture, keys, done = self.jobs.pop(0)
        done({key: ("image/jpeg", f"{picture.frame.stamp:g} {key}".encode()) for key in keys})


class FakeBackend:
    def __init__(self):
        self.unsubscribed = []

    def unsubscribe(self, session, topic):
        self.unsubscribed.append(topic)


class FakeStreams:
    def __init__(self):
        self.loop, self.encoder, self.backend = Loop(), FakeEncoder(), FakeBackend()
        self.topics = {}


class FakeViewer:
    """A viewer whose link takes a frame when the test says (written())."""

    def __init__(self, topic, key=((64, 48), 80, False)):
        self.topic, self.key, self.sent_seq, self.writing, self.got, self.failed = topic, key, 0, False, [], None
        topic.add(self)

    def key_for(self, frame):
        frame.read()
        return self.key

    def new_frame(self, frame):
        if not self.writing:
            self.topic.want(self)

    def take(self, frame, made):
        assert not self.writing
        self.got.append((frame.seq, made))
        self.sent_seq, self.writing = frame.seq, True

    def written(self):
        self.writing = False
        self.topic.want(self)

    def fail(self, status, text):
        self.failed = (status, text)
        self.topic.remove(self)


def image_message(index, encoding="rgb8"):
    msg = RosImage(width=4, height=4, encoding=encoding, step=12, data=bytes(48))
    msg.header.stamp.secs = index
    out = io.BytesIO()
    msg.serialize(out)
    return TopicRead("/cam", RosImage, [out.getvalue()], 1000.0 + index)


@pytest.fixture
def topic():
    shared = FakeStreams()
    made = stream_topics.StreamTopic(shared, stream_requests.Source("/cam", jpeg.IMAGE))
    shared.topics["/cam"] = made
    return made


def encoder(topic):
    return topic._streams.encoder


def test_viewers_of_one_size_and_quality_share_one_encode_of_each_frame(topic):
    first, second = FakeViewer(topic), FakeViewer(topic)
    assert encoder(topic).jobs == []  # nothing is made before a frame comes
    topic.deliver(image_message(1))
    assert len(encoder(topic).jobs) == 1 and encoder(topic).jobs[0][1] == [((64, 48), 80, False)]
    encoder(topic).finish()
    assert first.got == second.got and first.got[0][1][1] is second.got[0][1][1]  # the very same bytes
    third = FakeViewer(topic)
    topic.want(third)  # a viewer joining later gets what is made already, without a new job
    assert third.got == first.got and encoder(topic).jobs == []


def test_different_sizes_are_made_in_one_job_each_once(topic):
    keys = [((64, 48), 80, False), ((32, 24), 80, False), ((64, 48), 50, False), ((64, 48), 80, True)]
    viewers = [FakeViewer(topic, key) for key in keys * 2]
    topic.deliver(image_message(1))
    assert len(encoder(topic).jobs) == 1 and sorted(encoder(topic).jobs[0][1]) == sorted(keys)
    encoder(topic).finish()
    assert all(viewer.got[0][1][1] == f"1 {viewer.key}".encode() for viewer in viewers)


def test_at_most_MAX_KEYS_PER_JOB_variants_a_job_the_rest_in_the_next(topic):
    viewers = [FakeViewer(topic, ((8 + i, 6), 80, False)) for i in range(stream_topics.MAX_KEYS_PER_JOB + 3)]
    topic.deliver(image_message(1))
    assert len(encoder(topic).jobs[0][1]) == stream_topics.MAX_KEYS_PER_JOB
    encoder(topic).finish()
    assert len(encoder(topic).jobs) == 1 and len(encoder(topic).jobs[0][1]) == 3
    encoder(topic).finish()
    assert all(len(viewer.got) == 1 for viewer in viewers)


def test_a_job_is_bounded_in_pixels_and_makes_each_size_once(topic):
    """A job's variants fit in JOB_PIXELS (one at least, up to jpeg.MAX_OUTPUT_PIXELS): a topic's turn at the
    encoder is short whatever sizes its viewers ask. Its keys come by size, so that a size is resized once."""
    big = ((4096, 2048), 100, False)  # (8.4 Mpx: the largest there is)
    small = [((640, 480), quality, False) for quality in (90, 80)] + [((320, 240), 80, False)]
    viewers = [FakeViewer(topic, key) for key in [big, small[0], ((4000, 2048), 100, False), *small[1:]]]
    topic.deliver(image_message(1))
    jobs = []
    while encoder(topic).jobs:
        jobs.append(encoder(topic).jobs[0][1])
        encoder(topic).finish()
    assert [big] in jobs  # (alone: it is more than JOB_PIXELS)
    for keys in jobs:
        assert len(keys) == 1 or sum(width * height for (width, height), _, _ in keys) <= stream_topics.JOB_PIXELS
        assert [size for size, _, _ in keys] == sorted(size for size, _, _ in keys)
    assert all(len(viewer.got) == 1 for viewer in viewers)


def test_topics_take_turns_at_the_encoder():
    """Two topics on one encoder: the second waits for one job of the first, however many of the first's viewers
    ask sizes of their own (it waited for 8 such variants before)."""
    shared = FakeStreams()
    flooded, other = (
        stream_topics.StreamTopic(shared, stream_requests.Source(name, jpeg.IMAGE)) for name in ("/flood", "/cam")
    )
    flood = [FakeViewer(flooded, ((4096 - 16 * index, 2048), 100, False)) for index in range(24)]
    viewer = FakeViewer(other)
    flooded.deliver(image_message(1))
    other.deliver(image_message(1))
    assert [len(keys) for _, keys, _ in shared.encoder.jobs] == [1, 1]
    shared.encoder.finish()
    shared.encoder.finish()
    assert viewer.got and sum(len(v.got) for v in flood) == 1


def test_the_variants_a_frame_keeps_are_bounded_in_bytes(topic, monkeypatch):
    """A frame keeps its newest variants, MAX_VARIANT_BYTES of them at most; every viewer still gets its own, and a
    viewer asking a forgotten one again has it made again."""
    monkeypatch.setattr(stream_topics, "MAX_VARIANT_BYTES", 250)
    keys = [((8 + index, 6), 80, False) for index in range(6)]
    viewers = [FakeViewer(topic, key) for key in keys]
    topic.deliver(image_message(1))
    _, asked, done = encoder(topic).jobs.pop()
    done({key: ("image/jpeg", bytes(100)) for key in asked})  # (600 bytes made)
    frame = topic.latest
    assert list(frame.variants) == keys[-2:]  # (the newest two: 200 bytes)
    assert all(len(viewer.got) == 1 for viewer in viewers)
    again = FakeViewer(topic, keys[0])
    topic.want(again)
    assert encoder(topic).jobs[0][1] == [keys[0]]


def test_one_job_at_a_time_and_the_newest_frame_wins(topic):
    viewer = FakeViewer(topic)
    topic.deliver(image_message(1))
    for index in (2, 3, 4):  # frames arriving while the first is being made: no job of their own
        topic.deliver(image_message(index))
    assert len(encoder(topic).jobs) == 1
    encoder(topic).finish()
    assert [seq for seq, _ in viewer.got] == [1]  # (made: it goes out at once)
    viewer.written()
    assert len(encoder(topic).jobs) == 1 and encoder(topic).jobs[0][0].frame.stamp == 4  # the newest, not 2
    encoder(topic).finish()
    assert [seq for seq, _ in viewer.got] == [1, 4]


def test_a_viewer_that_is_writing_gets_the_newest_frame_after_never_a_backlog(topic):
    slow, fast = FakeViewer(topic), FakeViewer(topic)
    for index in range(1, 6):
        topic.deliver(image_message(index))
        encoder(topic).finish()
        fast.written()
    assert [seq for seq, _ in fast.got] == [1, 2, 3, 4, 5]
    assert [seq for seq, _ in slow.got] == [1]  # still writing the first
    slow.written()
    assert [seq for seq, _ in slow.got] == [1, 5]  # already made for the fast one: no new job
    assert encoder(topic).jobs == []


def test_a_frame_that_cannot_be_made_is_told_to_the_viewer(topic):
    viewer = FakeViewer(topic)
    topic.deliver(image_message(1, encoding="yuv422"))
    made = encoder(topic).jobs  # (the fake encoder makes anything: read what the real one does)
    picture, keys, done = made.pop()
    done(camera_encoder._encode(picture, keys))
    ((_, error),) = viewer.got
    assert isinstance(error, jpeg.UnsupportedEncoding)


def test_the_subscription_lingers_after_the_last_viewer_then_goes(topic):
    shared = topic._streams
    viewer = FakeViewer(topic)
    topic.remove(viewer)
    assert len(shared.loop.timers) == 1 and shared.loop.timers[0][0] == stream_topics.LINGER
    again = FakeViewer(topic)  # a reload within LINGER keeps it
    assert shared.loop.timers == []
    topic.remove(again)
    shared.loop.run_timers()
    assert topic.is_closed and shared.topics == {} and shared.backend.unsubscribed == ["/cam"]
    topic.deliver(image_message(1))  # (a message still on its way)
    assert encoder(topic).jobs == []


def test_a_refused_subscription_ends_its_viewers(topic):
    viewer = FakeViewer(topic)
    topic.ros_refused("subscribe", "/cam", "the topic is published as std_msgs/String")
    assert viewer.failed == (503, "the topic is published as std_msgs/String") and topic.is_closed


# ---- the pictures being sent -------------------------------------------------------------------------------------
def test_a_picture_sent_to_several_viewers_counts_once_until_its_last_has_it():
    sending = jpeg.Sending(limit=100, stall=2.0)
    shared, other = bytes(60), bytes(30)
    for viewer in ("a", "b", "c"):
        assert sending.crowding(shared, 0.0) == []
        sending.start(viewer, shared, 0.0)
    assert sending.used == 60 and len(sending) == 3
    assert sending.crowding(other, 0.0) == [] and sending.crowding(bytes(41), 0.0) is None
    assert sending.done("a") and sending.done("b") and sending.used == 60
    assert sending.done("c") and sending.used == 0 and not sending
    assert not sending.done("c")  # (a viewer gone after its picture left)


def test_beyond_the_limit_stalled_viewers_make_room_oldest_first_as_few_as_it_takes():
    """A picture that does not fit waits (None) until viewers whose picture has not left for `stall` seconds can be
    dropped to make room: the oldest first, only as many as it takes; a picture shared with a viewer that is not
    stalled frees nothing."""
    sending = jpeg.Sending(limit=100, stall=2.0)
    first, second = bytes(40), bytes(40)
    sending.start("old", first, 0.0)
    sending.start("shares", second, 1.0)
    sending.start("newer", second, 2.5)
    new = bytes(30)
    assert sending.crowding(new, 1.9) is None and not sending.room_for(30, 1.9)  # (nobody stalled for 2 s yet)
    assert sending.crowding(new, 2.1) == ["old"] and sending.room_for(30, 2.1)
    assert sending.crowding(bytes(70), 3.1) is None  # ("shares" stalled, but "newer" still takes its picture)
    assert sending.crowding(bytes(70), 4.6) == ["old", "shares", "newer"]
    assert sending.crowding(second, 0.0) == []  # (being sent already: no more bytes)


def test_one_picture_larger_than_the_limit_is_sent_alone():
    sending = jpeg.Sending(limit=100, stall=2.0)
    assert sending.crowding(bytes(500), 0.0) == []
    sending.start("big", bytes(500), 0.0)
    assert sending.crowding(bytes(1), 1.0) is None and sending.crowding(bytes(1), 2.5) == ["big"]


def test_the_viewers_whose_picture_stalled_oldest_first():
    sending = jpeg.Sending(limit=100, stall=2.0)
    for index, viewer in enumerate(("a", "b", "c")):
        sending.start(viewer, bytes(10), float(index))
    assert sending.stalled(11.5, 10.0) == ["a", "b"]
    sending.done("a")
    assert sending.stalled(11.5, 10.0) == ["b"]


# ---- a stream viewer refused room -------------------------------------------------------------------------------
class FakeConnection:
    """A stream viewer's detached connection: what is written is kept, nothing is ever read."""

    def __init__(self):
        self.socket, self._other = socket.socketpair()
        self.written = []

    def set_close_callback(self, callback):
        pass

    def set_nodelay(self, flag):
        pass

    def write(self, data):
        self.written.append(bytes(data))
        done = concurrent.futures.Future()
        done.set_result(None)
        return done

    def read_bytes(self, count, partial=False):
        return concurrent.futures.Future()

    def closed(self):
        return False

    def close(self):
        self.socket.close()
        self._other.close()


class RoomlessStreams:
    """The viewers' shared room for pictures, always full: each viewer refused says how much room it waits for."""

    def __init__(self):
        self.loop, self.viewers, self.waiting = Loop(), set(), {}

    def joined(self, viewer):
        self.viewers.add(viewer)

    def make_room(self, viewer, data):
        return False

    def wait_for_room(self, viewer, size):
        self.waiting[viewer] = size


@pytest.mark.parametrize("query, level, waits_for", [("adaptive=1", 1, 500), ("width=64", None, 1000)])
def test_a_viewer_refused_room_waits_and_an_adaptive_one_steps_down_first(query, level, waits_for):
    """An adaptive viewer refused room steps down its ladder, as for a skipped frame, and waits for the room of
    about its next level's picture, half the bytes (it waited for the same full-size picture before); a viewer
    that does not adapt waits for room for the picture it was refused."""
    streams, connection = RoomlessStreams(), FakeConnection()
    request = stream_requests.StreamRequest(args(f"topic=/cam&{query}"))
    viewer = stream_viewers.StreamViewer(streams, request, "/cam", None, connection, [])
    try:
        viewer.take(None, ("image/jpeg", bytes(1000)))
        assert (viewer.adaptation and viewer.adaptation.level) == level
        assert streams.waiting == {viewer: waits_for}
    finally:
        connection.close()


# ---- requests ---------------------------------------------------------------------------------------------------
def args(query):
    import urllib.parse

    parsed = urllib.parse.parse_qs(query, keep_blank_values=True)
    return {name: [value.encode() for value in values] for name, values in parsed.items()}


def test_a_request_with_web_video_servers_defaults():
    request = stream_requests.StreamRequest(args("topic=/cam"))
    assert (
        request.topic,
        request.type,
        request.width,
        request.height,
        request.quality,
        request.invert,
        request.adaptive,
        request.transport,
    ) == ("/cam", "mjpeg", 0, 0, None, False, False, "raw")
    request = stream_requests.StreamRequest(args("topic=/cam&width=-1&height=200&quality=30&invert&adaptive=1"))
    assert (request.width, request.height, request.quality, request.invert, request.adaptive) == (
        0,
        200,
        30,
        True,
        True,
    )


@pytest.mark.parametrize(
    "query, text",
    [
        ("", "topic is required"),
        ("topic=/c&type=vp9", "not supported"),
        ("topic=/c&quality=x", "quality must be"),
        ("topic=/c&width=4097", "width must be an integer from 0 to 4096"),
        ("topic=/c&adaptive=2", "adaptive must"),
    ],
)
def test_bad_parameters(query, text):
    with pytest.raises(stream_requests.BadRequest, match=text) as refused:
        stream_requests.StreamRequest(args(query))
    assert refused.value.status == 400


TYPES = {
    "/cam": jpeg.IMAGE,
    "/cam/compressed": jpeg.COMPRESSED,
    "/jpeg_only": jpeg.COMPRESSED,
    "/text": "std_msgs/String",
    "/unknown": "",
}


@pytest.mark.parametrize(
    "query, topic, expected",
    [
        ("type=mjpeg", "/cam", ("/cam", jpeg.IMAGE, None)),
        ("type=ros_compressed", "/cam", ("/cam/compressed", jpeg.COMPRESSED, "any")),
        ("type=ros_compressed&adaptive=1", "/cam", ("/cam/compressed", jpeg.COMPRESSED, None)),
        ("default_transport=compressed", "/cam", ("/cam/compressed", jpeg.COMPRESSED, None)),
        ("type=mjpeg", "/jpeg_only", ("/jpeg_only", jpeg.COMPRESSED, "jpeg")),
        ("type=mjpeg&width=10", "/jpeg_only", ("/jpeg_only", jpeg.COMPRESSED, None)),
        ("type=mjpeg&quality=10", "/jpeg_only", ("/jpeg_only", jpeg.COMPRESSED, None)),
        ("type=ros_compressed", "/jpeg_only", ("/jpeg_only", jpeg.COMPRESSED, "any")),
        ("type=ros_compressed", "/nobody", None),
        ("type=mjpeg", "/unknown", None),
    ],
)
def test_which_topic_a_request_streams_from(query, topic, expected):
    source = stream_requests.choose_source(stream_requests.StreamRequest(args(f"topic={topic}&{query}")), topic, TYPES)
    assert (source.topic, source.type, source.pass_mode) == expected if expected else source is None


def test_a_topic_of_another_type_is_404():
    with pytest.raises(stream_requests.BadRequest, match="topic /text is a std_msgs/String, not an image") as refused:
        stream_requests.choose_source(stream_requests.StreamRequest(args("topic=/text")), "/text", TYPES)
    assert refused.value.status == 404
