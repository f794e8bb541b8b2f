"""The rosbridge_websocket node: a Tornado server whose "/" is both the rosbridge v2 websocket endpoint and
the web page (web_root/index.html; other files of web_root are served as static files).

One IOLoop thread serves every client; rospy's threads and the service-call pool only hand work to it."""
import fnmatch
import ipaddress
import socket
import struct
import time
import urllib.parse
from pathlib import Path

import rosgraph
import rospkg
import rospy
import tornado.httpserver
import tornado.ioloop
import tornado.iostream
import tornado.netutil
import tornado.web
import tornado.websocket

from rosbridge import protocol
from rosbridge.frames import Utf8Text
from rosbridge.globs import Globs, parse_globs
from rosbridge.ros_side import RosBackend
from rosbridge.rosapi import Rosapi
from rosbridge.settings import Settings

class Bridge:
    """What every connection shares: the ROS side, the protocol settings and the connection policy."""

    def __init__(self, backend, config, allowed_origins=None, delay_between_messages=0.0, use_compression=False):
        self.backend, self.config = backend, config
        self.allowed_origins = allowed_origins  # None: same host only (and clients that send no Origin)
        self.delay_between_messages = delay_between_messages
        self.use_compression = use_compression
        self.clients = set()

    def client_opened(self, handler):
        self.clients.add(handler)
        self.backend.set_client_count(len(self.clients))

    def client_closed(self, handler):
        if handler in self.clients:
            self.clients.discard(handler)
            self.backend.set_client_count(len(self.clients))


class BridgeSocket(tornado.websocket.WebSocketHandler):
    """One rosbridge client; a plain HTTP GET of the same URL gets the index page instead."""

    def initialize(self, bridge, index_page=None):
        self.bridge, self.index_page = bridge, index_page
        self.session = None
        self._close_reason = None

    async def get(self, *args, **kwargs):
        if self.request.headers.get("Upgrade", "").lower() != "websocket" and self.index_page is not None:
            self.set_header("Content-Type", "text/html; charset=UTF-8")
            self.finish(self.index_page.read_bytes())
            return
        await super().get(*args, **kwargs)

    def check_origin(self, origin):
        patterns = self.bridge.allowed_origins
        if patterns is not None:
            return any(fnmatch.fnmatchcase(origin.lower(), pattern.lower()) for pattern in patterns)
        # Default: a page served by this bridge (same host as the socket's), and reached by an address or by
        # this machine's own name: a page of another name that DNS re-points here (DNS rebinding) is refused.
        return super().check_origin(origin) and is_local_name(urllib.parse.urlparse(origin).hostname or "")

    def get_compression_options(self):
        return {} if self.bridge.use_compression else None

    def open(self, *args):
        loop = tornado.ioloop.IOLoop.current()
        peer = f"{self.request.remote_ip}"
        self.session = protocol.Session(self.bridge.backend, self.bridge.config, time.time, loop.call_later,
                                        self._wake, self._close_after_sending, name=peer)
        self.set_nodelay(True)
        self.bridge.client_opened(self)

    def on_message(self, message):
        if isinstance(message, bytes):
            self.session.handle_binary(message)
        else:
            self.session.handle_text(message)

    def on_close(self):
        if self.session is not None:
            self.session.closed()
        self.bridge.client_closed(self)

    def _wake(self):
        tornado.ioloop.IOLoop.current().add_callback(self._flush)

    def _close_after_sending(self, reason):
        self._close_reason = reason
        self._wake()

    def _flush(self):
        """Writes the session's queued frames until the socket is backed up, then resumes when it has
        drained: a slow client's backlog stays in the session's bounded queue, not in Tornado's buffer."""
        conn, session = self.ws_connection, self.session
        while conn is not None and not conn.is_closing():
            frame = session.take_frame()
            if frame is None:
                if self._close_reason is not None:
                    self.close(1008, self._close_reason)
                return
            try:
                written = self._write(conn, frame)
            except (tornado.iostream.StreamClosedError, tornado.websocket.WebSocketClosedError):
                return
            if conn.stream.writing():
                written.add_done_callback(self._drained)
                return
            if self.bridge.delay_between_messages:
                tornado.ioloop.IOLoop.current().call_later(self.bridge.delay_between_messages, self._flush)
                return

    def _drained(self, written):
        if not written.cancelled() and written.exception() is None:
            self._flush()

    def _write(self, conn, frame):
        """Sends one frame; returns the stream's write future. Without permessage-deflate the frame goes
        straight to the stream: the same bytes for every client, and none of the Task that write_message
        wraps around each write."""
        binary = not isinstance(frame, str) and not isinstance(frame, Utf8Text)
        if self.bridge.use_compression:
            return self.write_message(frame, binary=binary)
        payload = frame.encode() if isinstance(frame, str) else frame
        return conn.stream.write(websocket_frame(payload, 0x2 if binary else 0x1))


def is_local_name(host):
    """An IP address, localhost, or this machine's host name."""
    try:
        ipaddress.ip_address(host)
        return True
    except ValueError:
        return host.lower() in ("localhost", socket.gethostname().lower())


def websocket_frame(payload, opcode):
    """An unmasked, unfragmented server-to-client websocket frame (RFC 6455 section 5.2)."""
    length = len(payload)
    if length < 126:
        header = struct.pack("!BB", 0x80 | opcode, length)
    elif length <= 0xFFFF:
        header = struct.pack("!BBH", 0x80 | opcode, 126, length)
    else:
        header = struct.pack("!BBQ", 0x80 | opcode, 127, length)
    return header + payload


def routes(bridge, web_root):
    """The route table: "/" is the websocket (and the page), other paths are files of web_root."""
    index = Path(web_root) / "index.html" if web_root else None
    table = [(r"/", BridgeSocket, {"bridge": bridge, "index_page": index if index and index.is_file() else None})]
    if web_root:
        table.append((r"/(.+)", tornado.web.StaticFileHandler, {"path": str(web_root)}))
    return table


def main():
    rospy.init_node("rosbridge_websocket")
    try:
        current = Settings(lambda name: rospy.get_param("~" + name, None))
        globs = Globs.parse(current.topics_glob, current.services_glob, current.params_glob)
        origins = parse_globs(current.allowed_origins)
    except ValueError as error:
        rospy.logfatal("%s", error)
        raise SystemExit(1)
    secret = None
    if current.authenticate:
        if current.secret_file:
            secret = Path(current.secret_file).read_text().strip()
        else:
            rospy.logerr("authenticate is on but secret_file is not set: every client will be refused")
    config = protocol.Config(max_message_size=current.max_message_size, fragment_timeout=current.fragment_timeout,
                             max_queue=current.max_queue, globs=globs, authenticate=current.authenticate,
                             auth_secret=secret, auth_time_delta=current.auth_time_delta)
    loop = tornado.ioloop.IOLoop.current()
    rosapi = Rosapi(rosgraph.get_master_uri(), rospy.get_name(), globs, rospy.Time.now)
    backend = RosBackend(loop, rosapi=rosapi, unregister_timeout=current.unregister_timeout)
    bridge = Bridge(backend, config, allowed_origins=origins,
                    delay_between_messages=current.delay_between_messages, use_compression=current.use_compression)
    backend.set_client_count(0)

    web_root = current.web_root or str(Path(rospkg.RosPack().get_path("turtlesim")) / "web")
    if web_root.lower() == "none":
        web_root = ""
    max_frame = 4 * current.max_message_size or 1 << 30
    app = tornado.web.Application(
        routes(bridge, web_root),
        # Tornado closes the socket on frames over its limit; ours answers an error and keeps it open
        websocket_max_message_size=max_frame,
        websocket_ping_interval=current.websocket_ping_interval or None,
        websocket_ping_timeout=current.websocket_ping_timeout)
    ssl_options = {"certfile": current.certfile, "keyfile": current.keyfile} if current.ssl else None
    sockets = tornado.netutil.bind_sockets(current.port, current.address or None)
    server = tornado.httpserver.HTTPServer(app, ssl_options=ssl_options, max_buffer_size=max_frame)
    server.add_sockets(sockets)
    port = sockets[0].getsockname()[1]
    rospy.set_param("~actual_port", port)
    scheme = "wss" if ssl_options else "ws"
    rospy.loginfo("Rosbridge WebSocket server started at %s://%s:%d (page: %s)", scheme,
                  current.address or "0.0.0.0", port, web_root or "off")

    # The kernel may deliver SIGINT to one of rospy's threads, which leaves the loop asleep in epoll: wake it
    # twice a second so that Python runs rospy's signal handler, and stop once rospy is shutting down.
    tornado.ioloop.PeriodicCallback(lambda: rospy.is_shutdown() and loop.stop(), 500).start()
    try:
        loop.start()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()


if __name__ == "__main__":
    main()
