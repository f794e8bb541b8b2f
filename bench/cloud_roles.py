"""The point cloud benchmark's processes (bench/suite.py, section `cloud`), one role each:

  fetch  a client asking for a topic's clouds as the page's Cloud viewer does: GET /cloud?topic=T&max_points=N
         &after=SEQ again as soon as each answer is read, on one keep-alive connection; counts the clouds and
         bytes that arrive
  serve  the same-run ceiling for the bridge's /cloud: the least work such an endpoint does, and nothing else.
         One TCPROS connection to the topic's publisher (found through the master; no ROS node of its own),
         each message read straight into a buffer of its size (a thread: one blocking recv_into after another),
         the bridge's own decimation (rosbridge.http.cloud: read_cloud, decimate; once per cloud and max_points), and
         a bare Tornado HTTP server answering the same requests (the newest cloud, or wait up to 5 s for one newer
         than SEQ). A rospy subscriber is no ceiling here: its reading costs more than the whole bridge's does.

Same protocol with bench/suite.py as ros_roles.py: READY when ready, `RESULT <json>` at the end."""

import argparse
import asyncio
import http.client
import threading
import time
from urllib.parse import quote, urlsplit

import stats

WAIT_S = 5.0  # as the bridge's /cloud: how long a request waits for a newer cloud before it answers 204


def main():
    p = argparse.ArgumentParser()
    p.add_argument("role", choices=["fetch", "serve"])
    p.add_argument("--topic", required=True)
    p.add_argument("--url", help="fetch: the server, e.g. http://127.0.0.1:9090/")
    p.add_argument("--port", type=int, help="serve: the port to listen on (127.0.0.1)")
    p.add_argument("--max-points", type=int, default=20000, help="fetch: what it asks for (the page's figure)")
    p.add_argument("--count", type=int, default=50, help="fetch: clouds to wait for")
    p.add_argument("--idle", type=float, default=2.0, help="fetch: stop this long after the last cloud")
    p.add_argument("--timeout", type=float, default=120.0)
    a = p.parse_args()
    if a.role == "fetch":
        fetch(a)
    else:
        asyncio.run(serve(a))


def fetch(a):
    seen = stats.Arrivals()
    problems = []
    where = urlsplit(a.url)
    path = f"{where.path.rstrip('/')}/cloud?topic={quote(a.topic)}&max_points={a.max_points}&after="

    def ask():
        connection, after = http.client.HTTPConnection(where.hostname, where.port, timeout=WAIT_S + 10), 0
        while len(seen.seqs) < a.count:
            connection.request("GET", path + str(after))
            answer = connection.getresponse()
            body = answer.read()
            if answer.status == 200:
                after = int(answer.getheader("X-Seq"))
                seen.add(after, len(body))
            elif answer.status != 204:  # (204: none newer yet, ask again)
                problems.append(f"{answer.status} {body[:200]!r}")
                time.sleep(0.5)

    threading.Thread(target=ask, daemon=True).start()
    print("READY", flush=True)
    seen.wait(a.count, a.idle, a.timeout)
    stats.result(**seen.summary(), problems=problems[:5])


class Newest:
    """The newest cloud's raw bytes, its number, what was made of it (max_points -> (headers, body)) and the
    requests waiting for a newer one. Used on the Tornado loop only."""

    def __init__(self):
        self.seq, self.raw, self.made = 0, None, {}
        self.newer = asyncio.Event()

    def deliver(self, raw):
        self.seq, self.raw, self.made = self.seq + 1, raw, {}
        self.newer.set()
        self.newer = asyncio.Event()

    def answer(self, max_points):
        from rosbridge.http.cloud import decimate, read_cloud

        if max_points not in self.made:
            cloud = read_cloud(self.raw)
            body, kept, total, third = decimate(cloud, max_points)
            self.made[max_points] = (
                {
                    "X-Seq": str(self.seq),
                    "X-Points": str(kept),
                    "X-Points-Total": str(total),
                    "X-Third": third,
                    "X-Frame-Id": cloud.frame_id,
                    "X-Timestamp": f"{cloud.stamp:.6f}",
                },
                body,
            )
        return self.made[max_points]


def receive(topic, deliver, timeout):
    """Subscribes to topic's publisher over TCPROS and calls deliver(message bytes) for each message (a thread)."""
    import bare_tcpros
    from sensor_msgs.msg import PointCloud2

    from rosbridge.ros_side import tcpros

    sock = bare_tcpros.subscribe(topic, PointCloud2, "/cloud_ceiling", timeout)
    while True:
        (size,) = tcpros.LENGTH.unpack(bare_tcpros.read_exactly(sock, 4))
        deliver(bare_tcpros.read_exactly(sock, size))


async def serve(a):
    import tornado.web

    newest = Newest()
    loop = asyncio.get_running_loop()

    class CloudHandler(tornado.web.RequestHandler):
        async def get(self):
            max_points = int(self.get_query_argument("max_points", "20000"))
            after = int(self.get_query_argument("after", "0"))
            deadline = loop.time() + WAIT_S
            while newest.raw is None or newest.seq <= after:
                try:
                    await asyncio.wait_for(newest.newer.wait(), deadline - loop.time())
                except TimeoutError:
                    self.set_status(204)
                    return
            headers, body = newest.answer(max_points)
            for name, value in headers.items():
                self.set_header(name, value)
            self.set_header("Content-Type", "application/octet-stream")
            self.finish(body)

    tornado.web.Application([("/cloud", CloudHandler)]).listen(a.port, "127.0.0.1")
    threading.Thread(
        target=receive,
        args=(a.topic, lambda raw: loop.call_soon_threadsafe(newest.deliver, raw), a.timeout),
        daemon=True,
    ).start()
    print("READY", flush=True)
    await asyncio.Event().wait()


if __name__ == "__main__":
    main()
