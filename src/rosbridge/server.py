"""The rosbridge_websocket node: a Tornado server whose "/" is both the rosbridge v2 websocket endpoint
(transport/connection.py) and the web page (web_root/index.html; other files of web_root are served by pages.py).

One IOLoop thread serves every client; rospy's threads and the service-call threads only hand work to it
(see ros_side/__init__.py)."""

import gc
import resource
import signal
import time
from pathlib import Path

import rosgraph
import rospkg
import rospy
import tornado.ioloop
import tornado.netutil
import tornado.web

from rosbridge import protocol
from rosbridge.accepting import BoundedHTTPServer, accept_connections
from rosbridge.auth import UrlMacs
from rosbridge.borrowed import end_registration_thread_at_shutdown, handle_connection, keep_rosout_setting_cached
from rosbridge.foxglove import Catalog
from rosbridge.globs import Globs, parse_globs
from rosbridge.heap import reuse_big_buffers
from rosbridge.http.access import host_checked
from rosbridge.http.bag_recorder import Recorder
from rosbridge.http.bag_routes import MAX_BODY, bag_routes
from rosbridge.http.cloud_routes import cloud_routes
from rosbridge.http.pages import PageFiles, missing_files
from rosbridge.http.stream_routes import stream_routes
from rosbridge.off_loop import EncodingThread
from rosbridge.ros_side import RosBackend
from rosbridge.ros_side.recovery import MasterWatch
from rosbridge.ros_side.rosapi import Rosapi
from rosbridge.settings import Settings
from rosbridge.transport.budget import Carryover
from rosbridge.transport.connection import unfinished_bound
from rosbridge.transport.deadman import DriverLeases
from rosbridge.transport.handshake import BridgeSocket
from rosbridge.transport.write_turns import WriteTurns

MAX_LOGGED_KINDS = 1000  # kinds of refusal remembered for rate limiting (refused origins are kinds)
IDLE_TIMEOUT = 10.0  # seconds
CLIENT_LINES_PER_SECOND = 20


class Bridge:
    """What every connection shares: the ROS side, the settings and the connection policy."""

    def __init__(self, backend, config, writes, allowed_origins=None, allowed_hosts=None):
        self.backend, self.config = backend, config  # config: a protocol.Config, what is derived from the settings
        self.settings = config.settings  # the one Settings object, which every layer reads
        self.writes = writes  # when the clients' queued frames are written (write_turns.py)
        self.encoder = EncodingThread(tornado.ioloop.IOLoop.current())  # big messages are encoded off the loop
        # big messages deflated for the clients whose link is slow (transport/slow_link.py): a thread apart from the
        # encoder's
        self.deflater = EncodingThread(tornado.ioloop.IOLoop.current(), name="rosbridge-deflate")
        self.allowed_origins = allowed_origins  # None: same host only (and clients that send no Origin)
        self.allowed_hosts = allowed_hosts  # None: this machine's names (and allowed_origins' sites)
        self.url_macs = UrlMacs(self.settings.auth_time_delta)  # the HTTP endpoints' rosauth (access.py)
        self.clients = set()
        self.unfinished = unfinished_bound(self.settings)  # what the messages clients have not finished hold, together
        # each client's budget (frames and bytes a second), kept for its address when it leaves
        self.budgets = Carryover(
            self.settings.max_frames_per_second, self.settings.max_bytes_per_second, time.monotonic
        )
        loop = tornado.ioloop.IOLoop.current()
        sim_now_ns = (lambda: rospy.Time.now().to_nsec()) if rospy.get_param("/use_sim_time", False) else None
        self.foxglove = Catalog(backend, config.globs, loop.call_later, loop.remove_timeout, sim_now_ns)
        self.session_id = str(time.time_ns())  # tells a Foxglove client whether it reconnects to the same bridge
        self._logged = {}
        self._lines_since, self._lines, self._unlogged = float("-inf"), 0, 0  # (_log_client)

    def client_opened(self, handler):
        self.clients.add(handler)
        self.backend.set_client_count(len(self.clients))
        self._log_client("connected", handler)

    def client_closed(self, handler):
        if handler in self.clients:
            self.clients.discard(handler)
            self.backend.set_client_count(len(self.clients))
            self._log_client("disconnected", handler)

    def _log_client(self, what, handler):
        """The reference's line for each client that comes and goes, with its protocol and address; at most
        CLIENT_LINES_PER_SECOND, then one line saying how many were not logged (a flood must not fill the disk)."""
        now = time.monotonic()
        if now - self._lines_since >= 1.0:
            if self._unlogged:
                rospy.loginfo("(%d client connections and disconnections not logged)", self._unlogged)
            self._lines_since, self._lines, self._unlogged = now, 0, 0
        if self._lines >= CLIENT_LINES_PER_SECOND:
            self._unlogged += 1
            return
        self._lines += 1
        rospy.loginfo(
            "Client %s (%s, %s). %d clients total.", what, handler.protocol_name, handler.peer, len(self.clients)
        )

    def log_refusal(self, kind, text, every=60.0):
        """Logs a refusal at most once a minute per kind (and of at most MAX_LOGGED_KINDS kinds)."""
        now = time.monotonic()
        if now - self._logged.get(kind, -every) < every or (
            kind not in self._logged and len(self._logged) >= MAX_LOGGED_KINDS
        ):
            return
        self._logged[kind] = now
        rospy.logwarn("%s", text)

    def refused_origin(self, origin, peer):
        listed = ", ".join([*(self.allowed_origins or []), origin])
        why = (
            "it is not in allowed_origins"
            if self.allowed_origins
            else (
                "a page opened from disk in a browser on another machine (or a sandboxed frame)"
                if origin == "null"
                else "only pages of this machine may connect by default"
            )
        )
        self.log_refusal(
            ("origin", origin),
            f"Refused a websocket from the web page at origin {origin} (browser at "
            f"{peer}): {why}. To allow it: roslaunch turtlesim rosbridge_websocket.launch "
            f'allowed_origins:="[{listed}]"',
        )


def routes(bridge, web_root, recorder=None):
    """The route table: "/" is the websocket (and the page), /bags the bag recorder (bag_routes.py), /stream,
    /snapshot, /stream_viewer and /streams the camera streams (streams.py), /cloud the point clouds made small
    (cloud_routes.py), other paths are files of web_root; a request addressed to a Host not this bridge's is refused
    whatever its path (access.host_checked)."""
    index = Path(web_root) / "index.html" if web_root else None
    table = [
        (r"/", BridgeSocket, {"bridge": bridge, "index_page": index if index and index.is_file() else None}),
        *stream_routes(bridge),
        *bag_routes(bridge, recorder),
        *cloud_routes(bridge),
    ]
    if web_root:
        table.append((r"/(.+)", PageFiles, {"path": str(web_root)}))
    return host_checked(bridge, table)  # every request, by its Host (DNS rebinding)


def bind_foxglove_port(current, port):
    """The sockets of the second port (foxglove_port), or none: -1, the same as `port`, or taken (another
    Foxglove server runs here: a warning, and the bridge goes on with its own port, where Foxglove clients
    are served as well)."""
    if current.foxglove_port < 0 or (current.foxglove_port == current.port and current.port):
        return []
    try:
        return tornado.netutil.bind_sockets(current.foxglove_port, current.address or None)
    except OSError as error:
        rospy.logwarn(
            "foxglove_port %d: %s; Foxglove clients can still connect on port %d",
            current.foxglove_port,
            error.strerror,
            port,
        )
        return []


def raise_fd_limit():
    """Lets the bridge use every file descriptor the hard limit allows (one per client, more for rospy)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != hard:
        resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))


def main():
    rospy.init_node("rosbridge_websocket", disable_signals=True)  # (the loop takes them: stop_on_signals)
    keep_rosout_setting_cached()
    try:
        current = Settings(lambda name: rospy.get_param("~" + name, None))
        globs = Globs.parse(current.topics_glob, current.services_glob, current.params_glob)
        origins, hosts = parse_globs(current.allowed_origins), parse_globs(current.allowed_hosts)
    except ValueError as error:
        rospy.logfatal("%s", error)
        raise SystemExit(1) from None
    raise_fd_limit()
    reuse_big_buffers()
    secret = None
    if current.authenticate:
        if current.secret_file:
            secret = Path(current.secret_file).read_text().strip()
        else:
            rospy.logerr("authenticate is on but secret_file is not set: every client will be refused")
    config = protocol.Config(current, globs, auth_secret=secret)
    loop = tornado.ioloop.IOLoop.current()
    rosapi = Rosapi(rosgraph.get_master_uri(), rospy.get_name(), globs, rospy.Time.now)
    writes = WriteTurns(loop.add_callback)
    leases = DriverLeases(current.deadman_timeout) if current.deadman_timeout > 0 else None
    backend = RosBackend(
        loop,
        writes,
        rosapi=rosapi,
        unregister_timeout=current.unregister_timeout,
        stop_drivers_leaving=current.deadman_timeout > 0,
        driving_began=leases.driving_began if leases is not None else lambda: None,
    )
    bridge = Bridge(backend, config, writes, allowed_origins=origins, allowed_hosts=hosts)
    backend.set_client_count(0)
    if leases is not None:
        leases.serve(bridge)

    web_root = current.web_root or str(Path(rospkg.RosPack().get_path("turtlesim")) / "web")
    if web_root.lower() == "none":
        web_root = ""
    if web_root and (missing := missing_files(web_root)):
        rospy.logwarn(
            "The page in %s lacks %s (its vendor/ folder): run bash tools/setup in the turtlesim source "
            "folder, which installs them from npm",
            web_root,
            ", ".join(missing),
        )
    recorder = None
    if current.bag_folder:
        recorder = Recorder(
            backend,
            loop,
            Path(current.bag_folder).expanduser(),
            current.bag_max_bytes,
            current.blackbox_seconds,
            current.blackbox_max_bytes,
            topic_globs=globs.topics,
        )
    app = tornado.web.Application(routes(bridge, web_root, recorder))
    ssl_options = {"certfile": current.certfile, "keyfile": current.keyfile} if current.ssl else None
    sockets = tornado.netutil.bind_sockets(current.port, current.address or None)
    foxglove_sockets = bind_foxglove_port(current, sockets[0].getsockname()[1])
    # a connection that sends no request within IDLE_TIMEOUT is closed: idle sockets must not hold descriptors
    server = BoundedHTTPServer(
        app,
        MAX_BODY,
        current.max_connections_per_address,
        bridge.log_refusal,
        ssl_options=ssl_options,
        idle_connection_timeout=IDLE_TIMEOUT,
    )
    accept_connections(
        handle_connection(server), sockets + foxglove_sockets, lambda text: bridge.log_refusal("fds", text), loop
    )
    port = sockets[0].getsockname()[1]
    ports = {"~actual_port": port}
    if foxglove_sockets:
        ports["~actual_foxglove_port"] = foxglove_sockets[0].getsockname()[1]

    def say_ports():
        for name, value in ports.items():
            rospy.set_param(name, value)

    say_ports()
    MasterWatch(after_recovery=say_ports)
    scheme = "wss" if ssl_options else "ws"
    rospy.loginfo(
        "Rosbridge WebSocket server started at %s://%s:%d (page: %s)%s",
        scheme,
        current.address or "0.0.0.0",
        port,
        web_root or "off",
        f"; Foxglove WebSocket clients also on port {ports['~actual_foxglove_port']}" if foxglove_sockets else "",
    )

    stop_on_signals(loop)
    # what start-up made lives as long as the node: the garbage collector's full collections (a black box save's
    # writing sets them off) need not walk it each time (the loop's stalls during a save: 25-35 ms -> 5-9 ms)
    gc.freeze()
    try:
        loop.start()
    finally:
        for sock in sockets + foxglove_sockets:
            sock.close()


def stop_on_signals(loop):
    """SIGINT and SIGTERM shut rospy down on the loop, between two of its callbacks (asyncio's handler wakes it
    through its own pipe, whichever thread the kernel chose), and the loop stops once rospy shuts down, for
    whatever reason. rospy's own handler ran in the middle of what the loop was doing: within one of its calls to
    the master, the shutdown's own call waited for the lock that call held, for ever."""
    for number in (signal.SIGINT, signal.SIGTERM):
        loop.asyncio_loop.add_signal_handler(number, rospy.signal_shutdown, f"signal {number.name}")
    rospy.on_shutdown(lambda: loop.add_callback(loop.stop))
    end_registration_thread_at_shutdown()


if __name__ == "__main__":
    main()
