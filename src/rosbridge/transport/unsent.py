"""How much a client's socket may hold unsent in the kernel. The kernel's send buffer holds seconds of frames on a
slow link, and what sits there can no longer be skipped for a fresher message: with TCP_NOTSENT_LOWAT the socket
takes no more once that many bytes wait unsent, so the rest waits in the bridge, which chooses what goes next
(protocol/outbox.Outbox for a websocket client, the newest frame for a stream viewer)."""

import socket

UNSENT_LIMIT = 32 * 1024  # bytes: 50 ms at 5 Mbit/s; on loopback, enough for the socket to take a burst at once


def limit_unsent(sock, limit=UNSENT_LIMIT):
    """Sets TCP_NOTSENT_LOWAT on a connected TCP socket (public socket API; Linux >= 3.12)."""
    try:
        sock.setsockopt(socket.IPPROTO_TCP, getattr(socket, "TCP_NOTSENT_LOWAT", 25), limit)
    except OSError:  # not TCP, or a kernel without it: the kernel's own buffering, as before
        pass
