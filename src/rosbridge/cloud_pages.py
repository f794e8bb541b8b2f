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

One subscription per topic through the bridge's backend (CloudTopic, a backend.Client), shared with the websocket
clients, kept LINGER seconds after its last request. Decimating is done off the loop (up to 0.4 s of CPU for a
cloud of 300k padded rows), on one thread for all topics (Clouds.decimator), one job per topic at a time: requests
for what a job makes (the same cloud and stride, cloud.stride_for) wait for it and share it, the others wait for
their own; a topic's next job is queued behind the other topics' jobs, so requests flooding one topic delay another
by one job at most. What was made of each topic's newest cloud is kept, CACHE_BYTES in all (cloud.Answers)."""
import asyncio
import collections
import functools
import time
import urllib.parse

import rosgraph.names
import tornado.concurrent
import tornado.gen
import tornado.ioloop
import tornado.web

from rosbridge import globs as globs_module
from rosbridge.cloud import Answers, CloudError, decimate, point_count, read_cloud, stride_for
from rosbridge.errors import ClientError
from rosbridge.http_access import EndpointHandler, query_text, refusal
from rosbridge.off_loop import EncodingThread
from rosbridge.streams import TopicTypes

CLOUD = "sensor_msgs/PointCloud2"
DEFAULT_POINTS, MAX_POINTS = 20000, 200000
WAIT_S = 5.0
LINGER = 5.0
CACHE_BYTES = 16 << 20  # answers kept, all topics together: 8.4 MB for every stride of 2 to 15 of a 300k-point cloud
ANSWER_BYTES = 512  # what an answer kept costs beside its body and headers (its tuple, dict and keys)


class CloudTopic:
    """One cloud topic: its subscription (this is its backend.Client), its newest cloud, the requests waiting for
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
            self.clouds.decimator.run(functools.partial(made_of, message, key[0], max_points),
                                      functools.partial(self._made, key))

    def _made(self, key, made):
        """On the loop: `made`, what made_of returned (None: a bug, logged)."""
        self.job = None
        _, _, futures = self.wanted.pop(key)
        seq, stride = key
        if made is None:
            made = tornado.web.HTTPError(500, "decimating %s failed (a bug, logged)", self.topic)
        elif seq == self.seq and not self.is_closed:
            size = ANSWER_BYTES + (len(str(made)) if isinstance(made, CloudError) else
                                   len(made[1]) + sum(len(k) + len(v) for k, v in made[0].items()))
            self.clouds.answers.put(self.topic, stride, made, size)
        for future in futures:
            _settle(future, made)
        self._next_job()

    def _wake(self):
        waiting, self.waiting = self.waiting, set()
        for future in waiting:
            if not future.done():
                future.set_result(None)

    # ---- backend.Client
    def deliver(self, message):
        self.seq += 1
        self.latest = message
        self.clouds.answers.forget(self.topic)
        self._wake()

    def ros_refused(self, op, name, text):
        self.close()

    def request_service(self, call_id, service, args):
        pass

    def status(self, level, msg, request_id=None):
        pass


def made_of(message, seq, max_points):
    """On the decimator thread, which reads only the message's bytes: (headers, body) of the message's cloud for
    max_points, or the CloudError."""
    try:
        cloud = read_cloud(message.data)
        body, kept, total, third = decimate(cloud, max_points)
    except CloudError as error:
        return error
    return {"X-Seq": str(seq), "X-Points": str(kept), "X-Points-Total": str(total), "X-Third": third,
            "X-Frame-Id": urllib.parse.quote(cloud.frame_id),
            "X-Timestamp": f"{cloud.stamp or message.stamp:.6f}"}, body


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

    def topic_of(self, topic):
        found = self.topics.get(topic)
        if found is None:
            found = CloudTopic(self, topic)
            self.backend.subscribe(found, topic, CLOUD)  # raises ClientError
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
        for key, default, low, high in (("max_points", DEFAULT_POINTS, 1, MAX_POINTS), ("after", 0, 0, 2 ** 62)):
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
        clouds = self.clouds
        looked = tornado.concurrent.Future()
        clouds.types.get(lambda types, error: looked.set_result((types, error)))
        types, error = await looked
        if error is not None:
            self.refuse(503, f"cannot ask the ROS master about {topic}: {error}")
            return
        kind = types.get(topic)
        if kind not in (None, CLOUD):
            self.refuse(404, f"topic {topic} is a {kind}, not a {CLOUD}")
            return
        try:
            cloud_topic = clouds.topic_of(topic)
        except ClientError as error:
            self.refuse(404, str(error))
            return
        cloud_topic.hold()
        try:
            deadline = time.monotonic() + WAIT_S
            while cloud_topic.latest is None or cloud_topic.seq <= after:
                left = deadline - time.monotonic()
                if left <= 0 or cloud_topic.is_closed or self.request.connection.stream.closed():
                    self.set_status(204)  # nothing newer: ask again
                    self.finish()
                    return
                self.waiting = tornado.concurrent.Future()
                cloud_topic.waiting.add(self.waiting)
                try:
                    await tornado.gen.with_timeout(clouds.loop.time() + left, self.waiting)
                except tornado.gen.TimeoutError:
                    pass
                finally:
                    cloud_topic.waiting.discard(self.waiting)
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

    def on_connection_close(self):
        if self.waiting is not None and not self.waiting.done():
            self.waiting.set_result(None)
        if self.answering is not None:
            self.answering.cancel()  # (its job is skipped if no other request waits for it)


def cloud_routes(bridge):
    return [(r"/cloud", CloudHandler, {"clouds": Clouds(bridge)})]
