"""A plain websocket client for the bridge tests (Tornado's client on a private asyncio loop), so a test can
send any frame, including broken ones, and read exactly what the server answers."""

import asyncio
import base64
import json
import os
import socket
import struct
import time
import zlib

import cbor2
from tornado.httpclient import HTTPRequest
from tornado.websocket import websocket_connect


class WsClient:
    def __init__(self, url, headers=None, timeout=10.0, compression_options=None, **request_kwargs):
        self.loop = asyncio.new_event_loop()
        request = HTTPRequest(
            url, headers=headers or {}, connect_timeout=timeout, request_timeout=timeout, **request_kwargs
        )
        self.ended = False  # the end of the connection was read
        self.conn = self._run(
            lambda: websocket_connect(
                request, max_message_size=256 * 1024 * 1024, compression_options=compression_options
            ),
            timeout,
        )

    def _run(self, start, timeout):
        """Runs start() (which returns an awaitable) inside this client's loop, up to timeout seconds."""

        async def run():
            return await asyncio.wait_for(start(), timeout)

        return self.loop.run_until_complete(run())

    def send(self, frame):
        """Sends a dict as JSON text, a str as text, bytes as a binary frame."""
        if isinstance(frame, dict):
            frame = json.dumps(frame)
        self._run(lambda: self.conn.write_message(frame, binary=isinstance(frame, bytes)), 30)

    def recv_raw(self, timeout=10.0):
        """The next frame (str or bytes); None when the server closed the connection."""
        frame = self._run(self.conn.read_message, timeout)
        self.ended = self.ended or frame is None
        return frame

    def recv(self, timeout=10.0):
        """The next frame decoded: JSON text -> object, binary -> CBOR-decoded object."""
        frame = self.recv_raw(timeout)
        if frame is None:
            return None
        return cbor2.loads(frame) if isinstance(frame, bytes) else json.loads(frame)

    def recv_until(self, predicate, timeout=10.0, limit=1000):
        """Reads frames until one satisfies predicate; returns it. TimeoutError once `timeout` seconds have
        passed in all, AssertionError if the socket closes or `limit` frames did not match."""
        deadline = time.monotonic() + timeout
        for _ in range(limit):
            frame = self.recv(max(0.0, deadline - time.monotonic()))
            assert frame is not None, "connection closed while waiting"
            if predicate(frame):
                return frame
        raise AssertionError(f"no matching frame within {limit} frames")

    def recv_op(self, op, timeout=10.0, **fields):
        return self.recv_until(lambda f: f.get("op") == op and all(f.get(k) == v for k, v in fields.items()), timeout)

    def request(self, frame, timeout=10.0):
        """Sends a frame and returns the first status or service_response that answers its id."""
        self.send(frame)
        return self.recv_until(
            lambda f: f.get("op") in ("status", "service_response") and f.get("id") == frame.get("id"), timeout
        )

    def is_closed(self, timeout=10.0):
        try:
            while True:
                if self.recv_raw(timeout) is None:
                    return True
        except TimeoutError:
            return False

    @property
    def close_code(self):
        return self.conn.close_code

    def close(self):
        self.conn.close()
        try:
            if not self.ended:  # (the end, once read, is not read again: it would wait for the timeout)
                self._run(self.conn.read_message, 5)
        except Exception:
            pass
        self.loop.close()

    def abort(self):
        """Drops the TCP connection without a websocket close handshake (a crashed client)."""
        self.conn.stream.close()
        self.loop.close()


def ping(client):
    """Proves the connection still works: a set_level round trip through the server (an error status
    comes back for the unknown level)."""
    reply = client.request({"op": "set_level", "level": "bogus", "id": "ping"})
    assert reply["op"] == "status" and reply["level"] == "error" and "bogus" in reply["msg"], reply
    return True


class RawWebSocket:
    """A websocket client written on a bare socket, so a test can stop reading or stop mid-frame."""

    def __init__(self, port, recv_buffer=None, early=b"", extensions=None):
        """early: bytes sent in the same write as the handshake's request (frames a client sends at once);
        extensions: the Sec-WebSocket-Extensions it offers (the server's answer is then self.extensions)."""
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=10)
        if recv_buffer:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, recv_buffer)
        key = base64.b64encode(os.urandom(16)).decode()
        offer = f"Sec-WebSocket-Extensions: {extensions}\r\n" if extensions else ""
        self.sock.sendall(
            (
                f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                f"{offer}\r\n"
            ).encode()
            + early
        )
        reply = b""
        while b"\r\n\r\n" not in reply:
            chunk = self.sock.recv(1)  # byte by byte: nothing after the handshake is consumed
            assert chunk, "server closed during the handshake"
            reply += chunk
        assert reply.startswith(b"HTTP/1.1 101"), reply
        answered = [
            line.split(b":", 1)[1].strip().decode()
            for line in reply.split(b"\r\n")
            if line.lower().startswith(b"sec-websocket-extensions:")
        ]
        self.extensions = answered[0] if answered else None

    @staticmethod
    def header(length, opcode=0x1, fin=True, rsv1=False):
        """FIN (RSV1: compressed) + opcode, then the masked payload length (clients must mask)."""
        first = (0x80 if fin else 0) | (0x40 if rsv1 else 0) | opcode
        if length < 126:
            return struct.pack("!BB", first, 0x80 | length)
        if length < 1 << 16:
            return struct.pack("!BBH", first, 0x80 | 126, length)
        return struct.pack("!BBQ", first, 0x80 | 127, length)

    @classmethod
    def frame(cls, payload, opcode=0x1, fin=True):
        """One client frame with a random mask, as a browser sends it."""
        mask = os.urandom(4)
        masked = bytes(byte ^ mask[i % 4] for i, byte in enumerate(payload))
        return cls.header(len(payload), opcode, fin) + mask + masked

    def recv_frame(self):
        """(opcode, payload) of the server's next frame (unmasked, as servers send them)."""
        first, second = self._recv_exactly(2)
        length = second & 0x7F
        if length == 126:
            (length,) = struct.unpack("!H", self._recv_exactly(2))
        elif length == 127:
            (length,) = struct.unpack("!Q", self._recv_exactly(8))
        return first & 0x0F, self._recv_exactly(length)

    def _recv_exactly(self, size):
        data = b""
        while len(data) < size:
            chunk = self.sock.recv(size - len(data))
            assert chunk, "the server closed the connection"
            data += chunk
        return data

    def closed_by_server(self):
        """True once the server has closed the connection (what it sent before is discarded)."""
        try:
            while self.sock.recv(65536):
                pass
        except ConnectionResetError:
            pass
        return True

    def send_text(self, text, cut_after=None, deflated=False):
        """Sends one text frame (mask of zeros: the payload is sent as is); with cut_after, only the header
        and that many payload bytes are sent; deflated: compressed on its own (permessage-deflate with no context
        kept between messages, as browsers do)."""
        data = text.encode()
        if deflated:
            compressor = zlib.compressobj(6, zlib.DEFLATED, -15)
            data = (compressor.compress(data) + compressor.flush(zlib.Z_SYNC_FLUSH))[:-4]
        frame = self.header(len(data), rsv1=deflated) + b"\0\0\0\0" + data
        self.sock.sendall(frame if cut_after is None else frame[: len(frame) - len(data) + cut_after])

    def close(self, reset=False):
        if reset:  # RST instead of FIN, as when the client machine drops off
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        self.sock.close()
