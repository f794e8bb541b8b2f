"""The rosbridge_websocket node: a Tornado server whose "/" is both the rosbridge v2 websocket endpoint and
the web page (web_root/index.html; other files of web_root are served as static files).

One IOLoop thread serves every client; rospy's threads and the service-call pool only hand work to it."""
import concurrent.futures
import fnmatch
import ipaddress
import socket
import struct
import time
import urllib.parse
from pathlib import Path

import rosgraph
import rospy
import tornado.httpserver
import tornado.ioloop
import tornado.iostream
import tornado.netutil
import tornado.web
import tornado.websocket

from rosbridge import protocol
from rosbridge.globs import Globs, parse_globs
from rosbridge.ros_side import RosBackend
from rosbridge.rosapi import Rosapi

DEFAULT_WEB_ROOT = Path(__file__).resolve().parents[2] / "web"
MAX_LOGGED_ORIGINS = 1000


class Bridge:
    """What every connection shares: the ROS side, the protocol settings and the connection policy."""

    def __init__(self, backend, config, allowed_origins=None, delay_between_messages=0.0, use_compression=False):
        self.backend, self.config = backend, config
        self.allowed_origins = allowed_origins  # None: this machine's pages only (see origin_allowed)
        self.delay_between_messages = delay_between_messages
        self.use_compression = use_compression
        self.clients = set()
        self.refused_origins = set()  # logged once each (at most MAX_LOGGED_ORIGINS: the log stays bounded)

    def log_refusal(self, origin, peer):
        if origin in self.refused_origins or len(self.refused_origins) >= MAX_LOGGED_ORIGINS:
            return
        self.refused_origins.add(origin)
        listed = ", ".join([*(self.allowed_origins or []), origin])
        why = "it is not in allowed_origins" if self.allowed_origins else (
            "a page opened from disk in a browser on another machine (or a sandboxed frame)" if origin == "null"
            else "only pages of this machine may connect by default")
        rospy.logwarn('Refused a websocket from the web page at origin %s (browser at %s): %s. To allow it: '
                      'roslaunch turtlesim rosbridge_websocket.launch allowed_origins:="[%s]"', origin, peer, why,
                      listed)

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
        peer = self.request.remote_ip
        if origin_allowed(origin, super().check_origin(origin), peer, self.bridge.allowed_origins):
            return True
        self.bridge.log_refusal(origin, peer)
        return False

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
        binary = not isinstance(frame, str) and not isinstance(frame, protocol.Utf8Text)
        if self.bridge.use_compression:
            return self.write_message(frame, binary=binary)
        payload = frame.encode() if isinstance(frame, str) else frame
        return conn.stream.write(websocket_frame(payload, 0x2 if binary else 0x1))


def origin_allowed(origin, same_origin, peer, patterns):
    """Whether a browser page of `origin` may open a websocket (clients that send no Origin are not browsers
    and are not asked). `same_origin`: the page came from this bridge (its Host); `peer`: the browser's address;
    `patterns`: the allowed_origins launch arg, None when empty.

    The bridge's own page, reached by a name of this machine, is always allowed. Otherwise allowed_origins
    decides when it is set; by default pages of this machine on any port (by localhost, its name or one of its
    addresses: a DNS-rebinding name is refused), and pages opened from disk (Origin "null") when the browser
    runs on this machine (README, Security: a sandboxed frame sends "null" too)."""
    origin = origin.lower()
    try:
        url = urllib.parse.urlsplit(origin)
    except ValueError:  # e.g. an unbalanced "[": no page has that origin
        return False
    if same_origin and is_this_machine(url.hostname or ""):
        return True
    if patterns is not None:
        return any(fnmatch.fnmatchcase(origin, pattern.lower()) for pattern in patterns)
    if origin == "null":
        return is_this_machine(peer)
    return url.scheme in ("http", "https") and is_this_machine(url.hostname or "")


def is_this_machine(host):
    """localhost, this machine's host name, or one of its addresses (loopback included)."""
    if host in ("localhost", socket.gethostname().lower()):
        return True
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        return False
    address = getattr(address, "ipv4_mapped", None) or address  # ::ffff:a.b.c.d from a dual-stack socket
    if address.is_loopback:
        return True
    family = socket.AF_INET if address.version == 4 else socket.AF_INET6
    with socket.socket(family, socket.SOCK_DGRAM) as probe:
        try:
            probe.bind((str(address), 0))  # only this machine's own addresses can be bound
        except OSError:
            return False
    return True


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


def _param(name, default):
    value = rospy.get_param("~" + name, default)
    return default if value in ("None", None) else value


def main():
    rospy.init_node("rosbridge_websocket")
    max_message_size = int(_param("max_message_size", protocol.DEFAULT_MAX_MESSAGE_SIZE))
    authenticate = bool(_param("authenticate", False))
    secret = None
    if authenticate:
        secret_file = _param("secret_file", "")
        if secret_file:
            secret = Path(secret_file).read_text().strip()
        else:
            rospy.logerr("authenticate is on but secret_file is not set: every client will be refused")
    globs = Globs.parse(str(_param("topics_glob", "")), str(_param("services_glob", "")),
                        str(_param("params_glob", "")))
    config = protocol.Config(max_message_size=max_message_size,
                             fragment_timeout=float(_param("fragment_timeout", 600)),
                             max_queue=int(_param("max_queue", 1000)),
                             globs=globs, authenticate=authenticate, auth_secret=secret,
                             auth_time_delta=float(_param("auth_time_delta", 5.0)))
    loop = tornado.ioloop.IOLoop.current()
    executor = concurrent.futures.ThreadPoolExecutor(max_workers=16, thread_name_prefix="rosbridge-call")
    rosapi = Rosapi(rosgraph.get_master_uri(), rospy.get_name(), globs, rospy.Time.now)
    backend = RosBackend(loop, executor, rosapi=rosapi,
                         unregister_timeout=float(_param("unregister_timeout", 10.0)))
    origins = parse_globs(str(_param("allowed_origins", "")))
    bridge = Bridge(backend, config, allowed_origins=origins,
                    delay_between_messages=float(_param("delay_between_messages", 0)),
                    use_compression=bool(_param("use_compression", False)))
    backend.set_client_count(0)

    web_root = str(rospy.get_param("~web_root", DEFAULT_WEB_ROOT))
    if web_root.lower() in ("", "none"):  # roslaunch drops an empty `web_root:=`, so "none" turns it off too
        web_root = ""
    settings = {
        # Tornado closes the socket on frames over its limit; ours answers an error and keeps it open
        "websocket_max_message_size": 4 * max_message_size or 1 << 30,
        "websocket_ping_interval": float(_param("websocket_ping_interval", 0)) or None,
        "websocket_ping_timeout": float(_param("websocket_ping_timeout", 30)),
    }
    app = tornado.web.Application(routes(bridge, web_root), **settings)
    ssl_options = None
    if _param("ssl", False):
        ssl_options = {"certfile": _param("certfile", ""), "keyfile": _param("keyfile", "")}
    address = str(_param("address", ""))
    sockets = tornado.netutil.bind_sockets(int(_param("port", 9090)), address or None)
    server = tornado.httpserver.HTTPServer(app, ssl_options=ssl_options, max_buffer_size=settings[
        "websocket_max_message_size"])
    server.add_sockets(sockets)
    port = sockets[0].getsockname()[1]
    rospy.set_param("~actual_port", port)
    scheme = "wss" if ssl_options else "ws"
    rospy.loginfo("Rosbridge WebSocket server started at %s://%s:%d (page: %s)", scheme, address or "0.0.0.0",
                  port, web_root or "off")

    # The kernel may deliver SIGINT to one of rospy's threads, which leaves the loop asleep in epoll: wake it
    # twice a second so that Python runs rospy's signal handler, and stop once rospy is shutting down.
    tornado.ioloop.PeriodicCallback(lambda: rospy.is_shutdown() and loop.stop(), 500).start()
    try:
        loop.start()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
        executor.shutdown(wait=False, cancel_futures=True)


if __name__ == "__main__":
    main()
