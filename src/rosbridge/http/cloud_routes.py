"""The point clouds made small on the bridge (README, Point clouds), under the same access rules as the camera
streams (origins, authenticate, topics_glob, max_clients):

    GET /cloud?topic=/points&max_points=20000&after=SEQ

answers the topic's newest sensor_msgs/PointCloud2 as little-endian float32 triples (x, y, third: z, else
intensity, else 0), every k-th point so that at most max_points (default 20000, at most 200000) go
(cloud.decimate); headers X-Seq (the cloud's number, for `after`), X-Points, X-Points-Total, X-Third, X-Frame-Id,
X-Timestamp. With after=SEQ it waits (up to WAIT_S) for a cloud newer than SEQ and answers 204 if none came: a
page asks again after drawing, so it gets clouds at the topic's rate, never faster than it draws.

X-Frame-Id is the frame id percent-encoded (its UTF-8, as urllib.parse.quote does: decodeURIComponent gives it
back; the usual ids, letters, digits, `_-.~/`, are unchanged): a frame id may hold anything, a header neither
control characters nor more than Latin-1.

One subscription per topic through the bridge's backend (CloudTopic, a contract.Client), shared with the websocket
clients, kept LINGER seconds after its last request; MAX_TOPICS topics at once, more are refused (503). Only a
topic the master lists as a PointCloud2 is subscribed: a request for a name it does not list looks again every
WAIT_POLL seconds (topic_types.TopicTypes) and answers 204 if it never came within WAIT_S. (Each subscription
costs a master registration and graph updates on the ROS side: requests for names nobody publishes, each
subscribed, held the other clients' calls for seconds.)

Decimating is done off the loop (up to 0.4 s of CPU for a cloud of 300k padded rows), on one thread for all topics
(Clouds.decimator), one job per topic at a time: requests for what a job makes (the same cloud and stride,
cloud.stride_for) wait for it and share it, the others wait for their own; a topic's next job is queued behind
the other topics' jobs, so requests flooding one topic delay another by one job at most. What was made of each
topic's newest cloud is kept, CACHE_BYTES in all (cloud.Answers)."""

import asyncio
import collections
import functools
import random
import time
import urllib.parse

import rosgraph.names
import tornado.concurrent
import tornado.ioloop
import tornado.web

from rosbridge import globs as globs_module
from rosbridge.errors import ClientError
from rosbridge.http.access import EndpointHandler, query_text, refusal
from rosbridge.http.cloud import Answers, CloudError, decimate, point_count, read_cloud, stride_for
from rosbridge.http.no_op_client import NoOpClient
from rosbridge.http.stream_requests import BadRequest
from rosbridge.http.topic_types import WAIT_POLL, TopicTypes
from rosbridge.off_loop import EncodingThread

CLOUD = "sensor_msgs/PointCloud2"
DEFAULT_POINTS, MAX_POINTS = 20000, 200000
WAIT_S = 5.0
# each request waits WAIT_S give or take this share, at random, so that requests made together do not all end in
# one turn of the loop (900 at once held it 0.3 s)
WAIT_SPREAD = 0.1
LINGER = 5.0
MAX_TOPICS = 8  # topics subscribed for /cloud at once (the lingering ones included)
CACHE_BYTES = 16 << 20  # answers kept, all topics together: 8.4 MB for every stride of 2 to 15 of a 300k-point cloud
ANSWER_BYTES = 512  # what an answer kept costs beside its body and headers (its tuple, dict and keys)


class CloudTopic(NoOpClient):
    """One cloud topic: its subscription (this is its contract.Client), its newest cloud, the requests waiting for
    a newer one, and the answers asked of its clouds that are being made (`wanted`, in the order asked)."""

    def __init__(self, clouds, topic):
        self.clouds, self.topic = clouds, topic
        self.is_closed = False
        self.seq, self.latest = 0, None
        self.waiting = set()  # futures of requests waiting for a newer cloud
        self.wanted = collections.OrderedDict()  # (seq, stride) -> (message, max_points, futures of its requests)
        self.job = None  # the key in `wanted` being made on the decimator
        self.users = 0
        self._linger = None

    def hold(self):
        self.users += 1
        if self._linger is not None:
            self.clouds.loop.remove_timeout(self._linger)
            self._linger = None

    def release(self):
        self.users -= 1
        if self.users == 0 and not self.is_closed:
            self._linger = self.clouds.loop.call_later(LINGER, self.close)

    def close(self):
        self.is_closed = True
        self.clouds.topics.pop(self.topic, None)
        self.clouds.answers.forget(self.topic)
        self.clouds.backend.unsubscribe(self, self.topic)
        self._wake()

    def answer(self, max_points):
        """A future of (headers, body) of the newest cloud for max_points (its exception a CloudError); cancel it
        when its request is gone."""
        future = tornado.concurrent.Future()
        try:
            stride = stride_for(point_count(self.latest.data), max_points)
        except CloudError as error:
            future.set_exception(error)
            return future
        made = self.clouds.answers.get(self.topic, stride)
        if made is not None:
            _settle(future, made)
            return future
        key = (self.seq, stride)
        if key not in self.wanted:
            self.wanted[key] = (self.latest, max_points, [])
        self.wanted[key][2].append(future)
        self._next_job()
        return future

    def _next_job(self):
        while self.job is None and self.wanted:
            key, (message, max_points, futures) = next(iter(self.wanted.items()))
            if all(future.done() for future in futures):  # (their requests are gone)
                del self.wanted[key]
                continue
            self.job = key
            self.clouds.decimator.run(
                functools.partial(made_of, message, key[0], max_points), functools.partial(self._made, key)
            )

    def _made(self, key, made):
        """On the loop: `made`, what made_of returned (None: a bug, logged)."""
        self.job = None
        _, _, futures = self.wanted.pop(key)
        seq, stride = key
        if made is None:
            made = tornado.web.HTTPError(500, "decimating %s failed (a bug, logged)", self.topic)
        elif seq == self.seq and not self.is_closed:
            size = ANSWER_BYTES + (
                len(str(made))
                if isinstance(made, CloudError)
                else len(made[1]) + sum(len(k) + len(v) for k, v in made[0].items())
            )
            self.clouds.answers.put(self.topic, stride, made, size)
        for future in futures:
            _settle(future, made)
        self._next_job()

    def _wake(self):
        waiting, self.waiting = self.waiting, set()
        _wake_all(waiting)

    # ---- contract.Client
    def deliver(self, read):
        self.seq += len(read.datas)
        self.latest = read.messages[-1]
        self.clouds.answers.forget(self.topic)
        self._wake()

    def ros_refused(self, op, name, text):
        self.close()


def made_of(message, seq, max_points):
    """On the decimator thread, which reads only the message's bytes: (headers, body) of the message's cloud for
    max_points, or the CloudError."""
    try:
        cloud = read_cloud(message.data)
        body, kept, total, third = decimate(cloud, max_points)
    except CloudError as error:
        return error
    return {
        "X-Seq": str(seq),
        "X-Points": str(kept),
        "X-Points-Total": str(total),
        "X-Third": third,
        "X-Frame-Id": urllib.parse.quote(cloud.frame_id),
        "X-Timestamp": f"{cloud.stamp or message.stamp:.6f}",
    }, body


def _wake_all(futures):
    for future in futures:
        if not future.done():
            future.set_result(None)


def _settle(future, made):
    if future.done():  # (cancelled: its request is gone)
        return
    if isinstance(made, Exception):
        future.set_exception(made)
    else:
        future.set_result(made)


class Clouds:
    """What the /cloud requests share."""

    def __init__(self, bridge):
        self.bridge, self.backend = bridge, bridge.backend
        self.loop = tornado.ioloop.IOLoop.current()
        self.topics = {}
        self.types = TopicTypes(bridge.backend)
        self.decimator = EncodingThread(self.loop, "cloud decimator")
        self.answers = Answers(CACHE_BYTES)
        self.requests = 0
        self.unlisted = {}  # topic the master does not list -> futures of the requests waiting for it
        self._look = None  # the next look at the master for them (one for all, not one a request)

    def waiting_for(self, topic):
        """The set to add the future of a request waiting for the master to list topic: set once it does (or a
        look fails), looked at every WAIT_POLL seconds while some request waits."""
        if self._look is None:
            self._look = self.loop.call_later(WAIT_POLL, self._look_again)
        return self.unlisted.setdefault(topic, set())

    def _look_again(self):
        self.types.get(self._looked)

    def _looked(self, types, error):
        self._look = None
        for topic, waiting in list(self.unlisted.items()):
            if not waiting:  # (its requests have gone)
                del self.unlisted[topic]
            elif error is not None or types.get(topic):
                del self.unlisted[topic]
                _wake_all(waiting)
        if self.unlisted:
            self._look = self.loop.call_later(WAIT_POLL, self._look_again)

    def topic_of(self, topic):
        """The CloudTopic of topic, subscribed through the backend if new; raises BadRequest."""
        found = self.topics.get(topic)
        if found is None:
            if len(self.topics) >= MAX_TOPICS:
                watched = ", ".join(sorted(self.topics))
                self.bridge.log_refusal(
                    "cloud max topics",
                    f"Refused the point cloud {topic}: {MAX_TOPICS} topics watched already ({watched})",
                )
                raise BadRequest(
                    503,
                    f"too many point cloud topics watched at once (at most {MAX_TOPICS}: "
                    f"{watched}); each is let go {LINGER:g} s after its last request",
                )
            found = CloudTopic(self, topic)
            try:
                self.backend.subscribe(found, topic, CLOUD)
            except ClientError as error:
                raise BadRequest(404, str(error)) from None
            self.topics[topic] = found
        return found


class CloudHandler(EndpointHandler):
    """GET /cloud: thin; Clouds, CloudTopic and cloud.py do the work."""

    def initialize(self, clouds):
        self.clouds = clouds
        self.waiting = self.answering = None

    async def get(self):
        clouds = self.clouds
        refused = refusal(clouds.bridge, self.request, "a point cloud")
        if refused is not None:
            self.refuse(*refused)
            return
        try:
            topic, max_points, after = self.arguments()
        except ValueError as error:
            self.refuse(400, str(error))
            return
        patterns = clouds.bridge.config.globs.topics
        if not globs_module.allowed(topic, patterns):
            clouds.bridge.log_refusal(("cloud glob", topic), f"Refused the point cloud {topic}: not in topics_glob")
            self.refuse(403, f"topic {topic!r} is not allowed by topics_glob {patterns}")
            return
        if clouds.requests >= clouds.bridge.settings.max_clients:
            self.refuse(503, "too many point cloud requests (max_clients)")
            return
        clouds.requests += 1
        try:
            await self.serve(topic, max_points, after)
        finally:
            clouds.requests -= 1

    def arguments(self):
        args = self.request.query_arguments
        name = query_text(args, "topic") or ""
        topic = self.clouds.backend.resolve_name(name) if rosgraph.names.is_legal_name(name) and name else None
        if not topic:
            raise ValueError(f"topic must be a ROS topic name, e.g. ?topic=/points (got {name!r})")
        numbers = []
        for key, default, low, high in (("max_points", DEFAULT_POINTS, 1, MAX_POINTS), ("after", 0, 0, 2**62)):
            text = query_text(args, key)
            try:
                value = default if text in (None, "") else int(text)
            except ValueError:
                value = None
            if value is None or not low <= value <= high:
                raise ValueError(f"{key} must be an integer from {low} to {high}, got {text!r}")
            numbers.append(value)
        return topic, *numbers

    async def serve(self, topic, max_points, after):
        deadline = time.monotonic() + WAIT_S * random.uniform(1 - WAIT_SPREAD, 1 + WAIT_SPREAD)
        try:
            cloud_topic = await self.published(topic, deadline)
        except BadRequest as error:
            self.refuse(error.status, error.text)
            return
        if cloud_topic is None:
            self.finish_empty()
            return
        cloud_topic.hold()
        try:
            while cloud_topic.latest is None or cloud_topic.seq <= after:
                if cloud_topic.is_closed or not await self.wait(deadline, cloud_topic.waiting):
                    self.finish_empty()
                    return
            self.answering = cloud_topic.answer(max_points)
            try:
                headers, body = await self.answering
            except CloudError as error:
                self.refuse(422, f"{topic}: {error}")
                return
            except asyncio.CancelledError:  # (on_connection_close: nobody to answer)
                return
        finally:
            cloud_topic.release()
        for name, value in headers.items():
            self.set_header(name, value)
        origin = self.request.headers.get("Origin")
        if origin:
            self.set_header("Access-Control-Allow-Origin", origin)
            self.set_header("Access-Control-Expose-Headers", ", ".join(headers))
            self.set_header("Vary", "Origin")
        self.set_header("Content-Type", "application/octet-stream")
        self.finish(body)

    async def published(self, topic, deadline):
        """The topic's CloudTopic once the master lists it as a PointCloud2 (looked at every WAIT_POLL seconds until
        deadline), or None; raises BadRequest."""
        clouds = self.clouds
        while topic not in clouds.topics:
            looked = tornado.concurrent.Future()
            clouds.types.get(lambda types, error: looked.set_result((types, error)))
            types, error = await looked
            if error is not None:
                raise BadRequest(503, f"cannot ask the ROS master about {topic}: {error}")
            kind = types.get(topic) or None  # ("": a type the master does not know)
            if kind == CLOUD:
                break
            if kind is not None:
                raise BadRequest(404, f"topic {topic} is a {kind}, not a {CLOUD}")
            if not await self.wait(deadline, clouds.waiting_for(topic)):
                return None
        return clouds.topic_of(topic)

    async def wait(self, until, waiting):
        """Waits until `until` (a time.monotonic()), the connection closes, or a future added to the set `waiting`
        is set (a newer cloud, the topic listed): False, without waiting, when the request has gone or its time has
        come."""
        left = until - time.monotonic()
        if left <= 0 or self.request.connection.stream.closed():
            return False
        self.waiting = tornado.concurrent.Future()
        waiting.add(self.waiting)
        timer = self.clouds.loop.call_later(left, _wake_all, [self.waiting])
        try:
            await self.waiting
        finally:
            waiting.discard(self.waiting)
            self.clouds.loop.remove_timeout(timer)
        return True

    def finish_empty(self):
        self.set_status(204)  # nothing (newer): ask again
        self.finish()

    def on_connection_close(self):
        if self.waiting is not None and not self.waiting.done():
            self.waiting.set_result(None)
        if self.answering is not None:
            self.answering.cancel()  # (its job is skipped if no other request waits for it)


def cloud_routes(bridge):
    return [(r"/cloud", CloudHandler, {"clouds": Clouds(bridge)})]
