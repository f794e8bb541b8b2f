"""The camera viewers, one a /stream or /snapshot request (Viewer): what it asks of its topic's frames, its
adaptation, and writing them on its own connection, detached from Tornado: StreamViewer the multipart stream, one
frame at a time, SnapshotViewer one JPEG. All of it runs on the loop; stream_routes.py says how they share the
topics and the room for the pictures being sent."""

import time

import tornado.concurrent
import tornado.iostream

from rosbridge.http import jpeg
from rosbridge.http.stream_requests import BadRequest
from rosbridge.http.stream_topics import PASS
from rosbridge.http.topic_types import WAIT_POLL
from rosbridge.origins import SECURITY_HEADERS
from rosbridge.transport.unsent import limit_unsent

BOUNDARY = "boundarydonotcross"  # web_video_server's
DEFAULT_QUALITY = 95  # web_video_server's, for a stream that does not adapt
SNAPSHOT_TIMEOUT = 5.0  # seconds a snapshot waits for the next frame
SNAPSHOT_GRACE = 2.0  # then seconds it may take to make the newest frame seen, if one was
MAX_DISCARDED = 64 * 1024  # bytes a viewer may send after its request before its stream is closed
NO_CACHE = "no-cache, no-store, must-revalidate, pre-check=0, post-check=0, max-age=0"


class Viewer:
    """One /stream or /snapshot viewer: what it asks, its topic once found, and its adaptation. until: when (a
    time.time()) its authentication ends (rosauth's `end`), at which it is ended (401); None: never."""

    def __init__(self, streams, request, topic_name, until):
        self.streams, self.request, self.topic_name = streams, request, topic_name
        self.topic = None
        self.pass_mode = None
        self.sent_seq = 0  # the last frame given to it
        self.ended = False  # it takes no more frames (what it was given may still be being written)
        self._stream = None  # its connection, once its answer is written (detached from Tornado)
        self.ladder = self.adaptation = None
        if request.adaptive:
            self.ladder = jpeg.Ladder(request.quality or jpeg.ADAPTIVE_QUALITY)
            self.adaptation = jpeg.Adaptation(len(self.ladder))
        self._level = 0  # the level of the last key asked
        self._poll = None
        self._expiry = None if until is None else streams.loop.call_later(max(0.0, until - time.time()), self._expired)
        streams.joined(self)

    def _expired(self):
        self._expiry = None
        self.fail(401, "authentication expired: the end given (rosauth's end) has passed")

    # ---- finding the topic
    def find(self, source):
        """Joins source's topic, or (None) looks for it every WAIT_POLL seconds until someone publishes it."""
        if self.ended:
            return
        if source is None:
            self._poll = self.streams.loop.call_later(WAIT_POLL, self._look)
            return
        try:
            self.topic = self.streams.topic_of(source)
        except BadRequest as error:
            self.fail(error.status, error.text)
            return
        self.pass_mode = source.pass_mode
        self.topic.add(self)
        self.joined()

    def _look(self):
        self._poll = None
        if not self.ended:
            self.streams.find_source(self.request, self.topic_name, self._found)

    def _found(self, source, error):
        if error is not None and error.status == 503:  # the master: try again
            source, error = None, None
        if error is not None:
            self.fail(error.status, error.text)
        else:
            self.find(source)

    def joined(self):
        """It has its topic."""

    # ---- frames
    def key_for(self, frame):
        """What it wants made of `frame`: PASS, or (size, quality, invert). Raises jpeg.ImageError."""
        request, picture = self.request, frame.read()
        if self.pass_mode is not None:
            content_type = jpeg.compressed_content_type(picture.format)
            if content_type == "image/jpeg" or (content_type and self.pass_mode == "any"):
                return PASS
        if self.ladder is None:
            size = jpeg.output_size(picture.size, request.width, request.height)
            return size, request.quality or DEFAULT_QUALITY, request.invert
        top_side = 0 if request.width or request.height else jpeg.ADAPTIVE_MAX_SIDE
        top = jpeg.output_size(picture.size, request.width, request.height, top_side)
        self._level = self.adaptation.level
        size, quality = self.ladder.level(self._level, top)
        return size, quality, request.invert

    def new_frame(self, frame):
        """A new frame of its topic."""

    def take(self, frame, made):
        """`frame` made as it asked: (content type, bytes), or a jpeg.ImageError."""

    # ---- ending
    def fail(self, status, text):
        self.end()

    def end(self):
        """It is gone: its connection closed, and what was being written to it no longer counts."""
        self._leave()
        if self._stream is not None and not self._stream.closed():
            self._stream.close()  # (Tornado drops what it had not written)
        self.streams.sent(self)

    def _leave(self):
        """It takes no more frames, nor counts among the viewers."""
        if self.ended:
            return
        self.ended = True
        self.streams.left(self)
        if self._expiry is not None:
            self.streams.loop.remove_timeout(self._expiry)
            self._expiry = None
        if self._poll is not None:
            self.streams.loop.remove_timeout(self._poll)
            self._poll = None
        if self.topic is not None:
            self.topic.remove(self)


class StreamViewer(Viewer):
    """A /stream viewer on its own (detached) connection: the multipart response, one frame at a time."""

    def __init__(self, streams, request, topic_name, until, stream, extra_headers):
        super().__init__(streams, request, topic_name, until)
        self._stream = stream
        self._writing = None  # (when, level) of the frame being written, or None
        self._arrived = 0  # frames that arrived while it was being written
        self._discarded = 0
        self.skipped = 0
        stream.set_close_callback(self.end)
        try:
            limit_unsent(stream.socket)
            stream.set_nodelay(True)
            stream.write(
                _head(f"multipart/x-mixed-replace;boundary={BOUNDARY}", extra_headers) + f"--{BOUNDARY}\r\n".encode()
            )
        except tornado.iostream.StreamClosedError:
            self.end()
            return
        self._read()

    def _read(self):
        """Reads what the client sends (nothing, normally) so that its leaving is seen at once."""
        try:
            self._stream.read_bytes(4096, partial=True).add_done_callback(self._discard)
        except tornado.iostream.StreamClosedError:
            self.end()

    def _discard(self, read):
        if read.cancelled() or read.exception() is not None:
            self.end()
            return
        self._discarded += len(read.result())
        if self._discarded > MAX_DISCARDED:
            self._stream.close()
        else:
            self._read()

    def joined(self):
        if self.topic.latest is not None:  # the newest frame at once (a reload shows the picture again)
            self.topic.want(self)

    def new_frame(self, frame):
        if self._writing is not None:
            self._arrived += 1
            if self._arrived > 1:  # the frame that waited is replaced
                self.skipped += 1
                if self.adaptation is not None:
                    self.adaptation.skipped(self._writing[1], time.monotonic())
            return
        if not self.streams.waits_for_room(self):
            self.topic.want(self)

    def take(self, frame, made):
        if self.ended or self._writing is not None:
            return
        if isinstance(made, jpeg.ImageError):
            self.streams.bridge.log_refusal(
                ("stream frame", self.topic.topic), f"camera stream of {self.topic.topic}: {made}"
            )
            self.fail(415, f"{self.topic.topic}: {made}")
            return
        content_type, data = made
        if not self.streams.make_room(self, data):
            size = len(data)
            if self.adaptation is not None:
                # a smaller picture may have room, and leaves more to the others: stepped down as for a frame
                # skipped, it waits for the room of about its next level's (half the bytes)
                level = self.adaptation.level
                self.adaptation.skipped(self._level, time.monotonic())
                if self.adaptation.level > level:
                    size //= 2
            self.streams.wait_for_room(self, size)
            return
        self.sent_seq = frame.seq
        head = (
            f"Content-Type: {content_type}\r\nContent-Length: {len(data)}\r\nX-Timestamp: {frame.stamp:.6f}\r\n\r\n"
        ).encode()
        stream = self._stream
        try:
            stream.write(head)
            stream.write(data)
            written = stream.write(f"\r\n--{BOUNDARY}\r\n".encode())
        except tornado.iostream.StreamClosedError:
            self.end()
            return
        self._writing, self._arrived = (time.monotonic(), self._level), 0
        written.add_done_callback(self._written)

    def _written(self, written):
        if written.cancelled() or written.exception() is not None:
            self.end()
            return
        if self.ended:
            return  # (it failed meanwhile: its picture counts until its last part has left too)
        started, level = self._writing
        self._writing = None
        self.streams.sent(self)
        if self.adaptation is not None:
            now = time.monotonic()
            self.adaptation.taken(level, now - started, self.topic.interval.seconds, now)
        self.topic.want(self)

    def fail(self, status, text):
        """Ends the stream with a last part holding the text (its headers are long sent), then closes it."""
        if self.ended:
            return
        self._leave()
        body = f"{text}\n".encode()
        part = (
            f"Content-Type: text/plain; charset=UTF-8\r\nContent-Length: {len(body)}\r\n\r\n".encode()
            + body
            + f"\r\n--{BOUNDARY}--\r\n".encode()
        )
        if self._writing is None:  # (counted as a picture is: dropped if it does not leave)
            self.streams.sending.start(self, part, time.monotonic())
        try:
            self._stream.write(part).add_done_callback(lambda _: self.end())
        except tornado.iostream.StreamClosedError:
            self.end()


class SnapshotViewer(Viewer):
    """A /snapshot viewer: the next frame (or, if none comes within SNAPSHOT_TIMEOUT, the newest one seen), made as
    it asks, then written on its connection (send). It counts among the viewers (max_clients), and its picture among
    the bytes being sent, until that has left. result: a Future of (stamp, content type, bytes), not of the frame (the
    frame goes when its topic's next one comes), or of a BadRequest."""

    def __init__(self, streams, request, topic_name, until):
        super().__init__(streams, request, topic_name, until)
        self.result = tornado.concurrent.Future()
        self._timer = streams.loop.call_later(SNAPSHOT_TIMEOUT, self._timed_out)
        self._grace = False

    def joined(self):
        latest = self.topic.latest
        if latest is None:
            return
        if any(message is latest.message for message in self.streams.backend.latched_messages(self.topic.topic)):
            self.topic.want(self)  # a latched picture: what a new subscriber would be given at once
        else:
            self.sent_seq = latest.seq  # (the next one)

    def new_frame(self, frame):
        if not self.result.done():
            self.topic.want(self)

    def take(self, frame, made):
        if self.ended or self.result.done():
            return
        if isinstance(made, jpeg.ImageError):
            self.fail(415, f"{self.topic.topic}: {made}")
            return
        content_type, data = made
        if not self.streams.make_room(self, data):
            self.fail(
                503,
                f"the pictures being sent to camera viewers are at the bridge's bound "
                f"({self.streams.sending.limit >> 20} MB): try again",
            )
            return
        self.sent_seq = frame.seq
        self._stop_timer()
        self.result.set_result((frame.stamp, content_type, data))

    def send(self, stream, extra_headers):
        """Writes the answer on the request's connection, detached from Tornado (which would join the picture to its
        head: a copy of it), then ends."""
        self._stream = stream
        if self.ended or stream.closed():
            self.end()
            return
        stamp, content_type, data = self.result.result()
        stream.set_close_callback(self.end)
        head = _head(content_type, [("Content-Length", len(data)), ("X-Timestamp", f"{stamp:.6f}"), *extra_headers])
        try:
            limit_unsent(stream.socket)
            stream.write(head)
            stream.write(data).add_done_callback(lambda _: self.end())
        except tornado.iostream.StreamClosedError:
            self.end()

    def _timed_out(self):
        self._timer = None
        if self.ended:
            return
        if self.topic is not None and self.topic.latest is not None and not self._grace:
            self.sent_seq, self._grace = 0, True  # the newest frame seen will do
            self._timer = self.streams.loop.call_later(SNAPSHOT_GRACE, self._timed_out)
            self.topic.want(self)
            return
        what = (
            f"no frame from {self.topic_name} within {SNAPSHOT_TIMEOUT:g} s"
            if self.topic is not None
            else f"nobody publishes {self.topic_name} (waited {SNAPSHOT_TIMEOUT:g} s)"
        )
        self.fail(504, what)

    def _stop_timer(self):
        if self._timer is not None:
            self.streams.loop.remove_timeout(self._timer)
            self._timer = None

    def fail(self, status, text):
        """Refuses the request, unless its answer is being written already (it then ends once that has left)."""
        if not self.result.done():
            self.result.set_exception(BadRequest(status, text))
            self.end()

    def end(self):
        self._stop_timer()
        if not self.result.done():  # (its client left)
            self.result.set_exception(BadRequest(503, "the snapshot's client left"))
        super().end()


def _head(content_type, headers):
    """The head of a 200 answer written on a detached connection (closed after it): never cached, the page's security
    headers, and `headers`, (name, value) pairs."""
    lines = [
        "HTTP/1.1 200 OK",
        "Connection: close",
        "Server: rosbridge_websocket",
        f"Cache-Control: {NO_CACHE}",
        "Pragma: no-cache",
        f"Content-Type: {content_type}",
        *(f"{name}: {value}" for name, value in (*SECURITY_HEADERS.items(), *headers)),
    ]
    return ("\r\n".join(lines) + "\r\n\r\n").encode()
