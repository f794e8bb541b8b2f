"""A real loopback TCP connection for the unit tests of the transport (transport/client_io.py,
transport/connection.py), and the asyncio loop they run on."""

import asyncio
import socket


class CountedSocket(socket.socket):
    """A socket that keeps the size of what each sendmsg was handed, and what send took."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.handed, self.sent_at_once = [], 0

    def send(self, data, *args):
        sent = super().send(data, *args)
        self.sent_at_once += sent
        return sent

    def sendmsg(self, buffers, *args):
        self.handed.append(sum(len(buffer) for buffer in buffers))
        return super().sendmsg(buffers, *args)


def tcp_pair(receive_buffer=None):
    """(the bridge's side, a CountedSocket; the client's side) of a loopback TCP connection; `receive_buffer`: the
    client's SO_RCVBUF, set before it connects (the window it offers then follows it)."""
    with socket.create_server(("127.0.0.1", 0)) as listener:
        client = socket.socket()
        if receive_buffer is not None:
            client.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
        client.connect(listener.getsockname())
        accepted, _ = listener.accept()
        server = CountedSocket(fileno=accepted.detach())
    server.setblocking(False)
    client.setblocking(False)
    return server, client


async def until(condition, timeout=5.0):
    for _ in range(int(timeout / 0.01)):
        if condition():
            return
        await asyncio.sleep(0.01)
    raise AssertionError("timed out")


async def read_all(client, size):
    got = bytearray()
    loop = asyncio.get_running_loop()
    while len(got) < size:
        chunk = await loop.sock_recv(client, 1 << 20)
        assert chunk, "the bridge closed early"
        got += chunk
    return bytes(got)


def run(test):
    loop = asyncio.new_event_loop()  # not asyncio.run: it would leave no current loop for the tests after
    try:
        loop.run_until_complete(asyncio.wait_for(test(), 20))
    finally:
        loop.close()
