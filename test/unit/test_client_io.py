"""transport/client_io.PlainSocket on a real loopback TCP connection and Tornado's loop: what the client sends is
handed over read by read, what the bridge writes arrives whole and in order however long the client takes to read
it, and the connection's end is told once, with the socket and Tornado's stream (the server's count of the address's
connections) closed."""

import asyncio

import pytest
import tornado.iostream

from rosbridge.transport.client_io import WRITE_PIECE_BYTES, PlainSocket

from loopback import read_all, run, tcp_pair, until


class Events:
    def __init__(self):
        self.received, self.drained, self.closed = [], 0, 0

    def on_received(self, data):
        self.received.append(data)

    def on_drained(self):
        self.drained += 1

    def on_closed(self):
        self.closed += 1


async def opened(early=b""):
    """A started PlainSocket, with the client's side, its events and the stream it took over. `early`: bytes the
    client sent before the answer."""
    server, client = tcp_pair()
    if early:
        client.send(early)
        await asyncio.sleep(0.05)
    stream = tornado.iostream.IOStream(server)
    events = Events()
    io = PlainSocket(stream, events.on_received, events.on_drained, events.on_closed)
    assert io.start(b"answer")
    return io, client, events, stream


async def next_read(io, events):
    """What the next read asked brings."""
    before = len(events.received)
    assert io.read()
    await until(lambda: len(events.received) > before)
    return events.received[-1]


def test_each_read_asked_hands_over_what_came():
    async def test():
        io, client, events, _ = await opened()
        assert await read_all(client, 6) == b"answer"
        client.send(b"one")
        await asyncio.sleep(0.05)
        assert events.received == []  # (no read asked)
        assert await next_read(io, events) == b"one"
        client.send(b"two")
        await asyncio.sleep(0.05)
        assert events.received == [b"one"]  # (one read per ask)
        assert await next_read(io, events) == b"two"
        io.close()
        client.close()

    run(test)


def test_bytes_sent_before_the_answer_come_first():
    async def test():
        io, client, events, _ = await opened(early=b"too soon")
        assert await next_read(io, events) == b"too soon"
        client.send(b"then")
        assert await next_read(io, events) == b"then"
        io.close()
        client.close()

    run(test)


def test_what_waits_for_a_slow_reader_arrives_whole_in_pieces_then_drained_is_told():
    async def test():
        io, client, events, stream = await opened()
        await read_all(client, 6)
        blocks = [bytes([n]) * 300_000 for n in range(20)]  # 6 MB: far more than the socket takes at once
        for block in blocks:
            io.write(block)
        io.write(memoryview(b"tail"))
        io.write(b"")  # (nothing to send: it leaves nothing waiting)
        assert io.writing()
        io.when_drained()
        await asyncio.sleep(0.1)
        assert events.drained == 0
        assert await read_all(client, 6_000_004) == b"".join(blocks) + b"tail"
        await until(lambda: events.drained)
        assert not io.writing() and io.progressed_at is not None
        assert events.drained == 1
        handed = stream.socket.handed  # (what waited, a piece each time the socket took more)
        waited = 6_000_004 - stream.socket.sent_at_once  # (what the socket took at once depends on the machine)
        assert waited > 10 * WRITE_PIECE_BYTES
        assert len(handed) >= waited // WRITE_PIECE_BYTES and max(handed) <= WRITE_PIECE_BYTES
        io.close()
        client.close()

    run(test)


def test_the_client_leaving_is_told_once_and_closes_the_stream():
    async def test():
        io, client, events, stream = await opened()
        io.read()
        client.close()
        await until(lambda: events.closed)
        await asyncio.sleep(0.05)
        assert events.closed == 1 and events.received == []
        assert io.closed() and stream.closed()
        assert not io.read()
        io.write(b"nothing")  # (dropped, no error)

    run(test)


@pytest.mark.parametrize("wait_first", [False, True])
def test_close_once_written_sends_what_waits_then_ends(wait_first):
    async def test():
        io, client, events, stream = await opened()
        await read_all(client, 6)
        io.write(b"x" * 4_000_000)
        if wait_first:
            assert io.writing()
        io.write(b"bye")
        io.close_once_written()
        got = await read_all(client, 4_000_003)
        assert got.endswith(b"xbye")
        assert await asyncio.get_running_loop().sock_recv(client, 10) == b""  # then the end
        await until(lambda: events.closed)
        assert stream.closed()
        client.close()

    run(test)


def test_close_drops_what_waits_and_ends_at_once():
    async def test():
        io, client, events, stream = await opened()
        io.write(b"x" * 8_000_000)
        assert io.writing()
        io.close()
        assert io.closed() and stream.closed() and not io.writing()
        await until(lambda: events.closed)
        client.close()

    run(test)
