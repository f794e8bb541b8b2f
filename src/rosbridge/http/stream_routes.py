"""Camera streams on the bridge's HTTP port, as web_video_server serves them (README, Camera streams):
`/stream` (MJPEG: multipart/x-mixed-replace), `/snapshot` (one JPEG), `/stream_viewer` (a page showing a stream)
and `/streams` (the image topics, as HTML or JSON). The same access rules as the websocket: origins,
authenticate (rosauth fields as query parameters), topics_glob; at most max_clients viewers at once.

What lives where: stream_requests.py reads a request (its parameters, the topic it streams from); topic_types.py
asks the master for the topics' types; stream_topics.py holds each topic's subscription (StreamTopic, a
contract.Client: one per topic through the bridge's RosBackend, shared with the websocket clients), its newest
frame and what was made of it; camera_encoder.py makes the pictures on its thread, with jpeg.py (pure: reading the
messages, decoding, resizing, JPEG, and the adaptation's ladder and policy); stream_viewers.py writes them to each
viewer (StreamViewer, SnapshotViewer). This file holds the requests (the handlers, thin) and what they share
(Streams: the topics, the viewers, the room for the pictures being sent).

Each viewer gets the newest frame and never a backlog: one frame is written to it at a time, and while its socket
has not taken it (the IOStream's write future not done; unsent.limit_unsent keeps the kernel's share small), newer
frames only replace the one it will get next. Each frame is made at most once per (size, quality, invert) for every
viewer, and only when a viewer wants it; what is made is kept with the frame up to stream_topics.MAX_VARIANT_BYTES
(Frame.trim). What is being written to the viewers, all topics together, is bounded in bytes (MAX_SENDING_BYTES,
jpeg.Sending: Streams.make_room): beyond it a stream viewer waits until a picture of its size has room, a snapshot
is refused (503), and viewers whose picture has not left for CROWDED_STALL are dropped if that makes room. A viewer
counts (max_clients, and its picture in those bytes) until its picture has left, and is dropped if it has not left
after websocket_ping_timeout; a snapshot is written on its own connection, as a stream is, not joined to its head by
Tornado (a copy).

Everything here runs on the event loop; the JPEGs are made on the encoder thread (camera_encoder.py, which says
who touches what)."""

import html
import json
import time
import urllib.parse

import rosgraph.names
import tornado.concurrent
import tornado.ioloop
import tornado.web

from rosbridge import globs as globs_module
from rosbridge.errors import ClientError
from rosbridge.http import access, jpeg
from rosbridge.http.camera_encoder import Encoder
from rosbridge.http.stream_requests import BadRequest, StreamRequest, choose_source
from rosbridge.http.stream_topics import StreamTopic
from rosbridge.http.stream_viewers import NO_CACHE, SnapshotViewer, StreamViewer
from rosbridge.http.topic_types import TopicTypes

MAX_SENDING_BYTES = 64 * 1024 * 1024  # the pictures being written to the viewers, all topics (jpeg.Sending)
CROWDED_STALL = 2.0  # seconds a viewer's picture may take to leave before the viewer is dropped for others' room


# ---- what the endpoints share ------------------------------------------------------------------------------------
class Streams:
    """The stream endpoints' shared state: the topics watched, the viewers, the encoder, the type look-ups."""

    def __init__(self, bridge):
        self.bridge, self.backend = bridge, bridge.backend
        self.loop = tornado.ioloop.IOLoop.current()
        self.topics = {}  # source topic -> StreamTopic
        self.viewers = set()  # the /stream and /snapshot viewers (and requests being checked) now
        self.pending = 0  # requests holding a place while their topic is looked up
        self.encoder = Encoder(self.loop)
        self.types = TopicTypes(bridge.backend)
        self.sending = jpeg.Sending(MAX_SENDING_BYTES, CROWDED_STALL)
        self._room_waiters = {}  # stream viewer -> bytes of the picture it waits to have room for (in order)
        self._given_room = None  # the waiter given room last, until its picture is made and offered
        self._giving_room = False
        # a viewer whose frame has not left for websocket_ping_timeout is gone (a dead link sends no FIN)
        self.stalled = bridge.settings.websocket_ping_timeout
        # (only while there is something to watch: an idle bridge is not woken for it)
        self._writers_watch = tornado.ioloop.PeriodicCallback(
            self._look_at_writers, min(self.stalled / 6, CROWDED_STALL / 2) * 1000
        )

    def _look_at_writers(self):
        for viewer in self.sending.stalled(time.monotonic(), self.stalled):
            viewer.end()
        if self._room_waiters:  # (a picture stalled for CROWDED_STALL meanwhile may make room: no frame need come)
            self._give_room()
        if not (self.viewers or self.sending or self._room_waiters):  # (until a viewer comes again: joined)
            self._writers_watch.stop()

    # ---- the pictures being sent
    def make_room(self, viewer, data):
        """Whether `data` may be written to `viewer` now; it then counts among the bytes being sent (at most
        MAX_SENDING_BYTES) until sent(viewer). Viewers whose picture has not left for CROWDED_STALL are dropped if
        that makes room."""
        if viewer is self._given_room:  # (the next waiter's turn)
            self._given_room = None
            self._room_later()
        now = time.monotonic()
        crowd = self.sending.crowding(data, now)
        if crowd is None:
            self.bridge.log_refusal(
                "stream room",
                f"a camera picture of {len(data)} bytes waits or is refused: "
                f"{self.sending.used} bytes are being sent to camera viewers (at most "
                f"{MAX_SENDING_BYTES})",
            )
            return False
        if crowd:
            self.bridge.log_refusal(
                "stream crowded",
                f"dropped {len(crowd)} camera viewer(s) whose picture had not "
                f"left for {CROWDED_STALL:g} s: the pictures being sent reached {MAX_SENDING_BYTES}"
                " bytes",
            )
        for stalled in crowd:
            stalled.end()
        self.sending.start(viewer, data, now)
        return True

    def wait_for_room(self, viewer, size):
        """The (stream) viewer, refused room for a picture of `size` bytes, wants the newest frame again once one
        of that size would have room (not at each frame: each would be made only to wait)."""
        self._room_waiters[viewer] = size

    def waits_for_room(self, viewer):
        return viewer in self._room_waiters

    def sent(self, viewer):
        """What was being written to the viewer has left, or it is gone."""
        if self.sending.done(viewer) and self._room_waiters:
            self._room_later()

    def _room_later(self):
        if not self._giving_room:
            self._giving_room = True
            self.loop.add_callback(self._give_room)

    def _give_room(self):
        """The first waiter whose picture may have room wants the newest frame. One at a time: each would have its
        picture made for the same room, and all but one wait again."""
        self._giving_room = False
        if self._given_room is not None:
            return
        now = time.monotonic()
        for viewer, size in self._room_waiters.items():
            if self.sending.room_for(size, now):
                del self._room_waiters[viewer]
                self._given_room = viewer
                viewer.topic.want(viewer)
                return

    def joined(self, viewer):
        """A viewer came (its request is being checked): the writes are watched until no viewer is left, nor
        anything being written (a viewer that failed still writes its last part, dropped if it stalls)."""
        self.viewers.add(viewer)
        if not self._writers_watch.is_running():
            self._writers_watch.start()

    def left(self, viewer):
        """The viewer takes no more frames."""
        self.viewers.discard(viewer)
        self._room_waiters.pop(viewer, None)
        if viewer is self._given_room:
            self._given_room = None
            self._room_later()

    # ---- access
    def refusal(self, request):
        """(status, text) when the request is refused by the origin rules or authentication, else None."""
        return access.refusal(self.bridge, request, "a camera stream")

    def auth_end(self, request):
        """With authenticate, when the authentication of a request refusal() let through ends (its rosauth `end`,
        a time.time()), else None."""
        if not self.bridge.config.authenticate:
            return None
        return float(access.query_text(request.query_arguments, "end"))

    def checked_topic(self, request):
        """The request's topic as ROS names it (resolved in the bridge's namespace), if topics_glob allows it."""
        topic = self.backend.resolve_name(request.topic) if rosgraph.names.is_legal_name(request.topic) else None
        if not topic or not rosgraph.names.is_legal_name(topic):
            raise BadRequest(400, f"{request.topic!r} is not a ROS topic name")
        patterns = self.bridge.config.globs.topics
        if not globs_module.allowed(topic, patterns):
            self.bridge.log_refusal(("stream glob", topic), f"Refused a camera stream of {topic}: not in topics_glob")
            raise BadRequest(403, f"topic {topic!r} is not allowed by topics_glob {patterns}")
        return topic

    def has_room(self):
        limit = self.bridge.settings.max_clients
        if len(self.viewers) + self.pending < limit:
            return True
        self.bridge.log_refusal(
            "stream max_clients", f"a camera stream refused: {len(self.viewers)} viewers (max_clients {limit})"
        )
        return False

    # ---- topics
    def find_source(self, request, topic, callback):
        """callback(Source or None (not published yet), None) or callback(None, BadRequest), on the loop."""

        def answered(types, error):
            if error is not None:
                callback(None, BadRequest(503, f"cannot ask the ROS master about {topic}: {error}"))
                return
            try:
                source = choose_source(request, topic, types)
            except BadRequest as refused:
                callback(None, refused)
                return
            callback(source, None)

        self.types.get(answered)

    def topic_of(self, source):
        """The StreamTopic of source, subscribed through the backend if new."""
        topic = self.topics.get(source.topic)
        if topic is not None:
            if topic.type != source.type:
                raise BadRequest(409, f"{source.topic} is watched as a {topic.type}, not a {source.type}")
            return topic
        topic = StreamTopic(self, source)
        try:
            self.backend.subscribe(topic, source.topic, source.type)
        except ClientError as error:
            raise BadRequest(404, str(error)) from None
        self.topics[source.topic] = topic
        return topic


# ---- handlers ----------------------------------------------------------------------------------------------------
class _Handler(access.EndpointHandler):
    CACHE_CONTROL = NO_CACHE  # (web_video_server's)

    def initialize(self, streams):
        self.streams = streams

    def allowed_origin_headers(self):
        origin = self.request.headers.get("Origin")
        return [("Access-Control-Allow-Origin", origin), ("Vary", "Origin")] if origin else []

    def checked(self):
        """The request (StreamRequest) and its topic, or None once refused."""
        refusal = self.streams.refusal(self.request)
        if refusal is not None:
            self.refuse(*refusal)
            return None
        try:
            request = StreamRequest(self.request.query_arguments)
            return request, self.streams.checked_topic(request)
        except BadRequest as error:
            self.refuse(error.status, error.text)
            return None

    async def viewer_source(self):
        """(request, topic, Source or None) for a new viewer, or None once refused (its rules, no room, bad)."""
        checked = self.checked()
        if checked is None:
            return None
        request, topic = checked
        if not self.streams.has_room():
            self.refuse(503, "too many camera stream viewers (max_clients)")
            return None
        try:
            return request, topic, await self.source(request, topic)
        except BadRequest as error:
            self.refuse(error.status, error.text)
            return None

    async def source(self, request, topic):
        """The request's Source (None: nobody publishes the topic yet); raises BadRequest. A place among the
        viewers is held meanwhile."""
        future = tornado.concurrent.Future()
        self.streams.pending += 1
        try:
            self.streams.find_source(
                request,
                topic,
                lambda source, error: future.set_exception(error) if error is not None else future.set_result(source),
            )
            return await future
        finally:
            self.streams.pending -= 1


class StreamHandler(_Handler):
    """GET /stream?topic=...: multipart/x-mixed-replace JPEGs (type=mjpeg), or the CompressedImage's own pictures
    (type=ros_compressed)."""

    async def get(self):
        found = await self.viewer_source()
        if found is None:
            return
        request, topic, source = found
        viewer = StreamViewer(
            self.streams,
            request,
            topic,
            self.streams.auth_end(self.request),
            self.detach(),
            self.allowed_origin_headers(),
        )
        viewer.find(source)


class SnapshotHandler(_Handler):
    """GET /snapshot?topic=...: one JPEG of the topic's next frame."""

    async def get(self):
        found = await self.viewer_source()
        if found is None:
            return
        request, topic, source = found
        if source is not None and source.pass_mode == "any":
            source.pass_mode = "jpeg"  # (a snapshot is a JPEG)
        viewer = self._viewer = SnapshotViewer(self.streams, request, topic, self.streams.auth_end(self.request))
        viewer.find(source)
        try:
            await viewer.result
        except BadRequest as error:
            self.refuse(error.status, error.text)
            return
        viewer.send(self.detach(), self.allowed_origin_headers())

    def on_connection_close(self):
        viewer = getattr(self, "_viewer", None)
        if viewer is not None:
            viewer.end()


class StreamViewerPage(_Handler):
    """GET /stream_viewer?topic=...: a page showing the stream (web_video_server's)."""

    def get(self):
        checked = self.checked()
        if checked is None:
            return
        _, topic = checked
        query = html.escape(self.request.query, quote=True)
        title = html.escape(topic)
        self.set_header("Content-Type", "text/html; charset=UTF-8")
        self.finish(
            f'<!DOCTYPE html><html><head><meta charset="utf-8"><title>{title}</title></head><body>'
            f'<h1>{title}</h1><img src="stream?{query}" alt="{title}"></body></html>'
        )


class StreamListHandler(_Handler):
    """GET /streams: the image topics (sensor_msgs/Image and CompressedImage) that topics_glob allows, as HTML
    with links (web_video_server's list at "/"), or ?format=json: {"topics": [{"topic", "type"}, ...]}."""

    async def get(self):
        refusal = self.streams.refusal(self.request)
        if refusal is not None:
            self.refuse(*refusal)
            return
        fmt = access.query_text(self.request.query_arguments, "format") or "html"
        if fmt not in ("html", "json"):
            self.refuse(400, f"format must be html or json, got {fmt!r}")
            return
        future = tornado.concurrent.Future()
        self.streams.types.get(lambda types, error: future.set_result((types, error)))
        types, error = await future
        if error is not None:
            self.refuse(503, f"cannot ask the ROS master for its topics: {error}")
            return
        images = sorted((topic, kind) for topic, kind in types.items() if kind in jpeg.IMAGE_TYPES)
        for name, value in self.allowed_origin_headers():
            self.set_header(name, value)
        if fmt == "json":
            self.set_header("Content-Type", "application/json")
            self.finish(json.dumps({"topics": [{"topic": topic, "type": kind} for topic, kind in images]}))
            return
        auth = "".join(
            f"&{name}={urllib.parse.quote(access.query_text(self.request.query_arguments, name) or '')}"
            for name in access.AUTH_FIELDS
            if self.streams.bridge.config.authenticate
        )
        items = []
        for topic, kind in images:
            query = html.escape(f"topic={urllib.parse.quote(topic)}{auth}", quote=True)
            name = html.escape(topic)
            items.append(
                f'<li><a href="stream_viewer?{query}">{name}</a> ({html.escape(kind)}) '
                f'(<a href="stream?{query}">Stream</a>) (<a href="snapshot?{query}">Snapshot</a>)</li>'
            )
        self.set_header("Content-Type", "text/html; charset=UTF-8")
        self.finish(
            '<!DOCTYPE html><html><head><meta charset="utf-8"><title>ROS Image Topic List</title></head>'
            "<body><h1>Available ROS Image Topics:</h1><ul>" + "".join(items) + "</ul></body></html>"
        )


def stream_routes(bridge):
    """The stream endpoints' routes (server.routes puts them before the page's files)."""
    streams = Streams(bridge)
    options = {"streams": streams}
    return [
        (r"/stream", StreamHandler, options),
        (r"/snapshot", SnapshotHandler, options),
        (r"/stream_viewer", StreamViewerPage, options),
        (r"/streams", StreamListHandler, options),
    ]
