"""Accepting connections without failing in a loop when file descriptors run short: used for the websocket
clients (server.py) and for the subscribers of the bridge's topics (ros_side/links.py); and the bounds of the
HTTP server (BoundedHTTPServer: request bodies, connections per address)."""

import errno
import http
import resource
import sys

import tornado.gen
import tornado.httpserver
import tornado.httputil
import tornado.ioloop
import tornado.iostream

FDS_KEPT_FREE = 64  # file descriptors kept for what is not accepted here (rospy's, service calls)
BODY_TIMEOUT = 10.0  # seconds a request's body may take to come, from its headers
LINGER = 2.0  # seconds a refused body is read and dropped, at most, before its connection is closed
SWEEP_EVERY = 1000  # connections accepted between two sweeps of the addresses that have none open


def accept_connections(handle_connection, sockets, log, loop):
    """Accepts clients like Tornado's TCPServer.add_sockets, but when file descriptors run short (EMFILE,
    ENFILE, or fewer than FDS_KEPT_FREE left) it stops listening for a while instead of failing in a loop:
    the pending clients wait in the kernel's backlog."""
    soft_limit = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    # The kernel gives a new descriptor the lowest number free: an accepted one numbered this high or more means
    # fewer than FDS_KEPT_FREE are left below the limit. (Counting /proc/self/fd instead took time in proportion
    # to the connections open, at every accept: most of the loop's time under a connection flood.)
    short_from = float("inf") if soft_limit == resource.RLIM_INFINITY else soft_limit - FDS_KEPT_FREE

    def pause(sock, text):
        log(f"not accepting connections for a second: {text}")
        loop.remove_handler(sock)
        loop.call_later(1.0, lambda: loop.add_handler(sock, lambda fd, events: accept(sock), loop.READ))

    def accept(sock):
        for _ in range(128):  # then let the loop serve the clients it has
            try:
                connection, address = sock.accept()
            except BlockingIOError:
                return
            except OSError as error:
                if error.errno == errno.ECONNABORTED:
                    continue
                if error.errno in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM):
                    pause(sock, error.strerror)
                    return
                raise
            handle_connection(connection, address)  # (TCPServer's own per-connection set-up)
            if connection.fileno() >= short_from:
                pause(sock, f"file descriptors near the limit ({soft_limit})")
                return

    for sock in sockets:
        loop.add_handler(sock, lambda fd, events, sock=sock: accept(sock), loop.READ)


class BoundedHTTPServer(tornado.httpserver.HTTPServer):
    """Tornado's HTTPServer held to what an endpoint open to the network can afford (Tornado's defaults take bodies
    of 100 MB, read whole before any handler sees them, with no time limit):

    - a request whose Content-Length is over max_body is answered 413 at its headers, none of its body kept (what
      the client sends meanwhile is read and dropped for up to LINGER seconds, so that it reads the answer); a body
      sent in chunks is answered so once past max_body, and a body must be whole within BODY_TIMEOUT;
    - one address holds at most per_address connections at once (HTTP requests, websockets and streams alike; and
      a quarter of the file descriptors at most), so that one peer cannot take them all: beyond, a connection is
      answered 503 and closed at once.
    log(kind, text): a refusal, to be logged at most now and then."""

    def initialize(self, app, max_body, per_address, log, **options):
        # (bounded by _BodyBound as the body comes: Tornado's own bound would answer a chunked one a bare 400)
        super().initialize(
            _BodyBound(app, max_body, log), max_body_size=sys.maxsize, body_timeout=BODY_TIMEOUT, **options
        )
        soft_limit = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
        if soft_limit != resource.RLIM_INFINITY:  # (and a quarter of the descriptors at most)
            per_address = min(per_address, max(1, (soft_limit - FDS_KEPT_FREE) // 4))
        self.per_address, self._log = per_address, log
        self._open = {}  # address -> its streams (the closed ones dropped as it connects again, or at a sweep)
        self._accepted = 0

    def handle_stream(self, stream, address):
        peer = address[0] if isinstance(address, tuple) else str(address)
        streams = [open_stream for open_stream in self._open.get(peer, ()) if not open_stream.closed()]
        self._accepted += 1
        if self._accepted % SWEEP_EVERY == 0:  # (the connections closed since, of every address)
            self._open = {
                other: still
                for other, kept in self._open.items()
                if (still := [open_stream for open_stream in kept if not open_stream.closed()])
            }
        if len(streams) >= self.per_address:
            self._open[peer] = streams
            self._log(
                ("connections", peer),
                f"Refused a connection from {peer}: it has {len(streams)} open "
                "already, the most one address may hold (max_connections_per_address)",
            )
            if not isinstance(stream, tornado.iostream.SSLIOStream):  # (a TLS answer would need a handshake)
                stream.write(
                    _answer(
                        503,
                        f"too many connections from {peer} at once (at most {self.per_address}: "
                        "max_connections_per_address)",
                    )
                )
            stream.close()
            return
        self._open[peer] = [*streams, stream]
        super().handle_stream(stream, address)


class _BodyBound(tornado.httputil.HTTPServerConnectionDelegate):
    """The application's requests, each refused at its headers when its Content-Length is over max_body."""

    def __init__(self, app, max_body, log):
        self.app, self.max_body, self.log = app, max_body, log

    def start_request(self, server_conn, request_conn):
        return _BodyBoundRequest(self.app.start_request(server_conn, request_conn), request_conn, self)

    def on_close(self, server_conn):
        self.app.on_close(server_conn)


class _BodyBoundRequest(tornado.httputil.HTTPMessageDelegate):
    def __init__(self, delegate, connection, bound):
        self.delegate, self.connection, self.bound = delegate, connection, bound
        self._path = ""
        self._received = 0  # bytes of its body so far

    def headers_received(self, start_line, headers):
        self._path = start_line.path
        length = headers.get("Content-Length", "")
        if not (length.isdigit() and int(length) > self.bound.max_body):
            return self.delegate.headers_received(start_line, headers)
        self._log(f"{length} bytes")
        stream = self.connection.detach()  # (Tornado then reads nothing more of this request)
        tornado.ioloop.IOLoop.current().add_callback(
            _refuse,
            stream,
            _answer(413, f"request body too large: {length} bytes, at most {self.bound.max_body} are taken"),
        )
        return None

    def data_received(self, chunk):
        self._received += len(chunk)
        if self._received <= self.bound.max_body:
            return self.delegate.data_received(chunk)
        # a body sent in chunks, past the bound: refused, then closed (Tornado's next read of it then ends the
        # connection, and tells the application that it closed)
        self._log(f"more than {self.bound.max_body} bytes in chunks")
        return _refuse(
            self.connection.stream,
            _answer(
                413,
                f"request body too large: more than {self.bound.max_body} bytes sent in chunks, at most "
                f"{self.bound.max_body} are taken",
            ),
        )

    def _log(self, size):
        peer = self.connection.context.remote_ip
        self.bound.log(
            ("body", peer),
            f"Refused a request body of {size} from {peer} for {self._path[:200]}: no endpoint takes more than "
            f"{self.bound.max_body}",
        )

    def finish(self):
        self.delegate.finish()

    def on_connection_close(self):
        self.delegate.on_connection_close()


async def _refuse(stream, answer):
    """Writes answer, then reads and drops what the client still sends (until it stops, at most LINGER seconds)
    before closing: closed with unread data, the connection would be reset, the answer lost with it."""
    try:
        await stream.write(answer)
        deadline = tornado.ioloop.IOLoop.current().time() + LINGER
        while True:
            await tornado.gen.with_timeout(deadline, stream.read_bytes(1 << 16, partial=True))
    except (tornado.iostream.StreamClosedError, tornado.gen.TimeoutError):
        pass
    finally:
        stream.close()


def _answer(status, text):
    """A whole HTTP answer that closes the connection, of plain text."""
    body = (text + "\n").encode()
    return (
        f"HTTP/1.1 {status} {http.HTTPStatus(status).phrase}\r\nContent-Type: text/plain; charset=UTF-8\r\n"
        f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n"
    ).encode() + body
