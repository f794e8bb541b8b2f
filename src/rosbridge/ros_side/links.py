"""The bridge's topic connections with other nodes, on the event loop: TCPROS (rosbridge.ros_side.tcpros) with no thread
per connection and no hand-off per message. The bridge reads its publishers on plain sockets the loop watches
(the path every message of a subscribed topic takes); its subscribers connect to a Tornado TCPServer.

rospy still does the rest of being a node: it registers the bridge's publishers and subscribers with the master
(rospy.Publisher / rospy.Subscriber, made on the worker), answers the other nodes' XML-RPC calls, and reports
the connections in getBusInfo (each link is a rospy Transport in its topic's list). TopicLinks joins in as the
first of rospy's protocol handlers: it makes the connections of the topics the bridge's clients use, and leaves
the node's own topics (/rosout, /client_count) to rospy's TCPROS handler."""

import collections
import datetime
import errno
import os
import socket
import time

import rosgraph.network
import rospy
import tornado.gen
import tornado.netutil
import tornado.tcpserver
import tornado.util
from tornado.iostream import StreamClosedError

from rosbridge.accepting import accept_connections
from rosbridge.borrowed import (
    INBOUND,
    OUTBOUND,
    ProtocolHandler,
    Transport,
    get_tcpros_handler,
    get_topic_manager,
    handle_connection,
    node_protocol_handlers,
)
from rosbridge.ros_side import tcpros
from rosbridge.ros_side.read_pace import ReadPace

TCPROS = "TCPROS"
CONNECT_TIMEOUT = 10.0  # seconds for a publisher to accept the bridge's connection and answer its header
CONNECT_RETRIES = (0.5, 1, 2, 4, 8, 16, 32, 32)  # seconds before each new try when connecting to a publisher
# fails, as rospy backs off; then the bridge gives up (the publisher is gone; a new one is announced anew)
HANDSHAKE_TIMEOUT = 10.0  # seconds for a subscriber to send its header once connected
READ_CHUNK = 1 << 16  # bytes read at once from a publisher (one wake of the loop for every message in them)
LINK_QUEUE_LIMIT = 10_000  # messages waiting for a slow subscriber when the topic's queue_size is 0 (unbounded)
LINK_QUEUE_BYTES = 32_000_000  # and bytes, whatever the queue_size (a client's: up to 2^63); the newest is kept


class FrameQueue:
    """Frames (str or bytes) waiting for the socket, at most max_frames of them and max_bytes in all (the
    newest frame is always kept). Counts what it drops so that the client can be told."""

    def __init__(self, max_frames, max_bytes):
        self.max_frames, self.max_bytes = max_frames, max_bytes
        self._frames = collections.deque()
        self.bytes = 0
        self.dropped = 0

    def __len__(self):
        return len(self._frames)

    def push(self, frame):
        frames = self._frames
        frames.append(frame)
        self.bytes += len(frame)
        while len(frames) > 1 and (len(frames) > self.max_frames or self.bytes > self.max_bytes):
            self.bytes -= len(frames.popleft())
            self.dropped += 1

    def pop(self):
        """The oldest frame, or None."""
        if not self._frames:
            return None
        frame = self._frames.popleft()
        self.bytes -= len(frame)
        return frame

    def take_all(self):
        """Every frame waiting, oldest first; the queue is then empty."""
        frames = list(self._frames)
        self.clear()
        return frames

    def take_dropped(self):
        dropped, self.dropped = self.dropped, 0
        return dropped

    def clear(self):
        self._frames.clear()
        self.bytes = 0


async def read_header(stream):
    return tcpros.decode_header(await stream.read_bytes(tcpros.header_size(await stream.read_bytes(4))))


class Link(Transport):
    """One connection, as rospy reports it (getBusInfo). close() may come from any thread (rospy closes a topic's
    connections when it is unregistered): it marks the link done, lets rospy forget it, and closes the socket on
    the loop. The socket is only touched on the loop."""

    transport_type = TCPROS

    def __init__(self, loop, direction, topic):
        super().__init__(direction, topic)
        self._loop = loop
        self.on_closed = None  # called on the loop once the socket is closed

    def close(self):
        if self.done:  # (rospy calls close again while forgetting the link)
            return
        super().close()
        self._loop.add_callback(self._closed)

    def _closed(self):
        self._close_socket()
        if self.on_closed is not None:
            self.on_closed(self)

    def get_transport_info(self):  # the format rosnode info parses
        return (
            f"{self.transport_type} connection on port {self.local_endpoint[1]} to "
            f"[{self.remote_endpoint[0]}:{self.remote_endpoint[1]} on socket {self._fileno()}]"
        )


class InboundLink(Link):
    """The bridge subscribed to one publisher of a topic. A plain non-blocking socket watched by the loop: each
    time it is readable (or once a millisecond while the publisher keeps sending fast: read_pace.py), one read, and
    the messages completed go to deliver(messages, latched_by) (this link if the publisher latches, else None) - no
    future or coroutine step per message, which a topic at a fixed rate would pay on every message."""

    def __init__(self, loop, topic, cls, publisher_uri, family, address, deliver):
        super().__init__(loop, INBOUND, topic)
        self.endpoint_id = publisher_uri
        self.remote_endpoint = address[:2]
        self._cls, self._family, self._address, self._deliver = cls, family, address, deliver
        self._tries = 0
        self._retry = None  # the timer of the next try to connect
        self._deadline = None  # the timer of the try under way
        self._sock = None
        self._poll = None  # the timer of the next read while the socket is polled, not watched

    def start(self):
        """On the loop: connect, send our header, then read."""
        self._retry = None
        if self.done:
            return
        self._unsent = None  # our header's bytes not yet written (None: not connected yet)
        self._sending = True  # until our header is written; then reading
        self._reader = tcpros.FrameReader(max_size=tcpros.MAX_HEADER)  # (the first frame is the reply header)
        self._latching = None  # the publisher's answer: None until its header is read
        self._pace = ReadPace()
        try:
            self._sock = socket.socket(self._family, socket.SOCK_STREAM)
            self._sock.setblocking(False)
            self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            error = self._sock.connect_ex(self._address)
            if error not in (0, errno.EINPROGRESS):
                raise OSError(error, os.strerror(error))
        except OSError as error:
            self._fail(error)
            return
        self._loop.add_handler(self._sock, self._on_events, self._loop.WRITE)
        self._deadline = self._loop.call_later(  # (until the publisher has answered)
            CONNECT_TIMEOUT, lambda: self._fail(TimeoutError(f"no answer in {CONNECT_TIMEOUT:g} s"))
        )

    def _on_events(self, fd, events):
        """One read (or the header's write): its complete messages delivered, then the next read when the socket is
        readable, or in a while (read_pace.py), unwatched meanwhile. (The read is written here, not in a method of
        its own: it is the one call every message of every topic pays.)"""
        space = None
        try:
            if self._sending:
                self._send_header()
                return
            space = self._reader.into()
            if space is not None:  # the rest of a big message: straight into its buffer
                count = self._sock.recv_into(space)
            else:
                chunk = self._sock.recv(READ_CHUNK)
                count = len(chunk)
            if not count:  # the publisher left
                if self._latching is None:
                    raise ConnectionResetError("the publisher closed the connection before answering")
                self.close()
                return
            self.stat_bytes += count
            # more may be waiting: it filled its chunk, or a big message is on its way
            more = space is not None or count == READ_CHUNK
            if space is not None:
                messages = self._reader.received(count)
            elif self._latching is not None:
                messages = self._reader.feed(chunk)
            elif self._read_reply(chunk):
                messages = self._reader.feed(b"")  # (what came with the answer)
            else:
                return
        except BlockingIOError:
            messages, more = (), False
        except (OSError, tcpros.TcprosError) as error:
            self._fail(error)
            return
        finally:
            if space is not None:
                space.release()
        if messages and not self.done:
            self.stat_num_msg += len(messages)
            self._deliver(messages, self if self._latching else None)
        if self.done or self._sock is None:
            return
        was_polling = self._pace.polling
        wait = self._pace.after_read(time.monotonic(), len(messages), more)
        if wait is not None:
            if not was_polling:
                self._loop.update_handler(self._sock, 0)
            self._poll = self._loop.call_later(wait, self._polled)
        elif was_polling:
            self._loop.update_handler(self._sock, self._loop.READ)

    def _polled(self):
        self._poll = None
        self._on_events(None, None)

    def _send_header(self):
        sock = self._sock
        if self._unsent is None:  # connected, or failed to
            error = sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
            if error:
                raise OSError(error, os.strerror(error))
            self.local_endpoint = sock.getsockname()[:2]
            self._unsent = tcpros.encode_header(tcpros.subscriber_header(self.name, self._cls, rospy.get_name()))
        try:
            self._unsent = self._unsent[sock.send(self._unsent) :]
        except BlockingIOError:
            return
        if not self._unsent:
            self._sending = False
            self._loop.update_handler(sock, self._loop.READ)

    def _read_reply(self, chunk):
        """The publisher's header, the first frame it sends: True once it is read and accepts us."""
        frames = self._reader.feed(chunk, most=1)
        if not frames:
            return False
        reply = tcpros.decode_header(frames[0])
        if "error" in reply:
            raise tcpros.TcprosError(f"the publisher refused: {reply['error']}")
        self._latching = reply.get("latching") == "1"
        self._reader.max_size = tcpros.MAX_MESSAGE
        self._loop.remove_timeout(self._deadline)
        self._deadline = None
        return True

    def _fail(self, error):
        """Connecting failed (tried again later, as rospy does) or the connection broke (closed, as rospy does);
        a refusal is final."""
        if self.done:
            return
        if self._latching is not None or isinstance(error, tcpros.TcprosError) or self._tries == len(CONNECT_RETRIES):
            rospy.logwarn("subscribing %s from %s: %s", self.name, self.endpoint_id, error)
            self.close()
            return
        if self._tries == 0:
            rospy.logwarn("subscribing %s from %s: %s; trying again", self.name, self.endpoint_id, error)
        self._close_socket()
        self._retry = self._loop.call_later(CONNECT_RETRIES[self._tries], self.start)
        self._tries += 1

    def _close_socket(self):
        for timer in (self._deadline, self._retry, self._poll):
            if timer is not None:
                self._loop.remove_timeout(timer)
        self._deadline = self._retry = self._poll = None
        if self._sock is not None:
            self._loop.remove_handler(self._sock)
            self._sock.close()
            self._sock = None

    def _fileno(self):
        return self._sock.fileno() if self._sock is not None else -1


class OutboundLink(Link):
    """One subscriber of a topic the bridge publishes. Each message goes straight to the socket while the kernel
    takes it (no future, no further turn of the loop: what a topic at a fixed rate pays on every message); once
    the socket is backed up, the stream writes the rest and the next messages wait (at most queue_limit of them
    and LINK_QUEUE_BYTES, the oldest dropped first), then go out together."""

    def __init__(self, loop, topic, stream, callerid, queue_limit):
        super().__init__(loop, OUTBOUND, topic)
        self.stream, self.endpoint_id = stream, callerid
        self.local_endpoint = stream.socket.getsockname()[:2]
        self.remote_endpoint = stream.socket.getpeername()[:2]
        self._waiting = FrameQueue(queue_limit, LINK_QUEUE_BYTES)
        self._writing = False

    def _close_socket(self):
        self.stream.close()

    def _fileno(self):
        return -1 if self.stream.closed() else self.stream.fileno().fileno()

    def send(self, framed):
        self.stat_num_msg += 1
        if self._writing:
            self._waiting.push(framed)
            return
        sock = self.stream.socket
        if sock is None:  # the stream is closed: watch() closes the link
            return
        try:  # straight to the socket: no future and no further turn of the loop when the kernel takes it all
            sent = sock.send(framed)
        except BlockingIOError:
            sent = 0
        except OSError:
            self.close()
            return
        self.stat_bytes += sent
        if sent < len(framed):  # the rest through the stream, which waits for the socket to be writable
            self._write(memoryview(framed)[sent:])

    def _write(self, *messages):
        """The stream keeps big messages by reference: the waiting ones are not copied into one."""
        try:
            for data in messages:
                written = self.stream.write(data)
        except StreamClosedError:
            self.close()
            return
        self.stat_bytes += sum(map(len, messages))
        self._writing = True
        written.add_done_callback(self._written)

    def _written(self, written):
        self._writing = False
        if written.exception() is not None:
            self.close()
        elif len(self._waiting):
            self._write(*self._waiting.take_all())

    async def watch(self):
        """Until the subscriber leaves (it sends nothing after its header: anything it does send is dropped)."""
        try:
            while True:
                await self.stream.read_bytes(READ_CHUNK, partial=True)
        except StreamClosedError:
            pass
        finally:
            self.close()


class TopicLinks(ProtocolHandler):
    """TCPROS for the topics of the bridge's clients. Its tables are written on the worker (before the rospy
    object is made, after it is dropped) and read on rospy's threads and the loop (dict reads: atomic):
    - subscriptions: topic -> (genpy class, deliver(messages, latched_by) called on the loop);
    - publications: topic -> an object with `cls`, `latch`, `queue_size`, `closed` and `attach(link)` (loop).
    Other topics go to rospy's own handler (`fallback`)."""

    def __init__(self, loop, refusal_log):
        self._loop = loop
        self._fallback = get_tcpros_handler()
        self.subscriptions, self.publications = {}, {}
        self._server = _TopicServer(self)
        self._sockets = tornado.netutil.bind_sockets(0, rosgraph.network.get_bind_address())
        self._port = self._sockets[0].getsockname()[1]
        self._host = rosgraph.network.get_host_name()
        accept_connections(handle_connection(self._server), self._sockets, refusal_log, loop)
        node_protocol_handlers().insert(0, self)

    # rospy's ProtocolHandler interface: called on rospy's threads
    def supports(self, protocol):
        return protocol == TCPROS

    def get_supported(self):
        return [[TCPROS]]

    def shutdown(self):
        for sock in self._sockets:
            self._loop.add_callback(sock.close)

    def init_publisher(self, topic, protocol):
        if topic not in self.publications:
            return self._fallback.init_publisher(topic, protocol)
        return 1, f"ready on {self._host}:{self._port}", [TCPROS, self._host, self._port]

    def create_transport(self, topic, publisher_uri, params):
        subscription = self.subscriptions.get(topic)
        if subscription is None:
            return self._fallback.create_transport(topic, publisher_uri, params)
        if not isinstance(params, list) or len(params) != 3 or params[0] != TCPROS:
            return 0, f"ERROR: invalid TCPROS parameters {params}", 0
        _, host, port = params
        family = socket.AF_INET6 if rosgraph.network.use_ipv6() else socket.AF_INET  # (as rospy connects)
        try:  # (on rospy's connecting thread, not the loop: a name lookup may take long)
            address = socket.getaddrinfo(host, port, family, socket.SOCK_STREAM)[0][4]
        except OSError as error:
            return 0, f"ERROR: cannot resolve publisher {host}:{port}: {error}", 0
        impl = get_topic_manager().get_subscriber_impl(topic)
        if impl is None:
            return 0, f"ERROR: not subscribed to {topic}", 0
        cls, deliver = subscription
        link = InboundLink(self._loop, topic, cls, publisher_uri, family, address, deliver)
        if not impl.add_connection(link):
            return 0, f"ERROR: the subscriber of {topic} was closed meanwhile", 0
        self._loop.add_callback(link.start)
        return 1, f"connecting topic [{topic}] on the bridge's loop", port

    # on the loop
    async def handshake(self, stream):
        """A subscriber connected to the bridge's TCPROS port: answer its header, then send it the topic."""
        try:
            header = await tornado.gen.with_timeout(datetime.timedelta(seconds=HANDSHAKE_TIMEOUT), read_header(stream))
            topic = header.get("topic", "")
            publication = self.publications.get(topic)
            if publication is None or publication.closed:
                reply = {"error": f"[{rospy.get_name()}] is not a publisher of [{topic}]"}
            else:
                reply = tcpros.publisher_reply(header, topic, publication.cls, publication.latch, rospy.get_name())
            await stream.write(tcpros.encode_header(reply))
            impl = get_topic_manager().get_publisher_impl(topic)
            if "error" in reply or impl is None or publication.closed:
                stream.close()
                return
            stream.set_nodelay(tcpros.wants_nodelay(header))
            link = OutboundLink(
                self._loop, topic, stream, header["callerid"], publication.queue_size or LINK_QUEUE_LIMIT
            )
        except (StreamClosedError, OSError, tcpros.TcprosError, tornado.util.TimeoutError):
            stream.close()
            return
        impl.add_connection(link)  # (for getBusInfo; rospy itself never writes to it)
        publication.attach(link)
        await link.watch()


class _TopicServer(tornado.tcpserver.TCPServer):
    def __init__(self, links):
        super().__init__()
        self._links = links

    async def handle_stream(self, stream, address):
        await self._links.handshake(stream)
