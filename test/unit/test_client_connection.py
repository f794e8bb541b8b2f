"""transport/connection.ClientConnection with a Foxglove session, on a real loopback TCP connection and Tornado's
loop: a read's messages go to the socket at once while nothing of the client's waits, an image's too, and the
pool shared by every client's outbox holds an image's bytes only until the socket has taken them all."""

import asyncio
import json
import socket
import types

import tornado.ioloop
import tornado.iostream

from rosbridge.contract import GraphState
from rosbridge.foxglove.catalog import Catalog
from rosbridge.protocol import Config
from rosbridge.protocol.encoded import TopicRead
from rosbridge.transport import rfc6455 as ws
from rosbridge.transport.budget import Carryover
from rosbridge.transport.connection import ClientConnection, unfinished_bound
from rosbridge.transport.write_turns import WriteTurns

from fakes import BackendRecorder
from loopback import read_all, run, tcp_pair, until

ANSWER = b"HTTP/1.1 101 Switching Protocols\r\n\r\n"
STAMP = 1_700_000_000.0


def bridge_for_one_client(**settings):
    """What a ClientConnection asks of the server (server.py's), on the current loop, with a recording backend."""
    loop = tornado.ioloop.IOLoop.current()
    config, backend = Config(**settings), BackendRecorder()
    return types.SimpleNamespace(
        config=config,
        settings=config.settings,
        backend=backend,
        unfinished=unfinished_bound(config.settings),
        budgets=Carryover(1e9, 1e12, loop.time),
        foxglove=Catalog(backend, config.globs, loop.call_later, loop.remove_timeout),
        session_id="s1",
        writes=WriteTurns(loop.add_callback),
        client_opened=lambda client: None,
        client_closed=lambda client: None,
        log_refusal=lambda kind, text: None,
    )


async def subscribed_to_a_camera(**settings):
    """(the connection, the client's socket, the bridge) once the client has subscribed to /camera and has read
    everything before. The client's socket takes a megabyte unread (the socket's receive buffer)."""
    server, client = tcp_pair(receive_buffer=1 << 20)
    bridge = bridge_for_one_client(**settings)
    connection = ClientConnection(bridge, tornado.iostream.IOStream(server), "peer", None, "foxglove.websocket.v1")
    connection.start(ANSWER)
    bridge.backend.watchers[0](GraphState({"/camera": ("sensor_msgs/Image", "")}, {}, {}, {}, {}))
    [channel] = bridge.foxglove.channels
    connection.session.handle_text(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channel}]}))
    await asyncio.sleep(0.1)
    await read_until_quiet(client)
    return connection, client, bridge


async def read_until_quiet(client):
    got = bytearray()
    loop = asyncio.get_running_loop()
    while True:
        try:
            got += await asyncio.wait_for(loop.sock_recv(client, 1 << 20), 0.1)
        except TimeoutError:
            return bytes(got)


def image_frame(picture):
    """What the client gets for the picture: its websocket frame's header, the message's head, the bytes."""
    head = bytes([1]) + (7).to_bytes(4, "little") + int(STAMP * 1e9).to_bytes(8, "little")
    return ws.frame_header(len(head) + len(picture), ws.BINARY) + head + picture


def test_an_image_the_socket_takes_whole_is_let_go_of_at_once():
    async def test():
        connection, client, bridge = await subscribed_to_a_camera()
        picture = bytes(range(256)) * 280  # (70 kB: the socket takes it whole)
        connection.session.deliver(TopicRead("/camera", None, [picture], STAMP))
        assert bridge.config.queue_pool.shared == 0 and len(connection.session._outbox) == 0
        assert await read_all(client, len(image_frame(picture))) == image_frame(picture)
        client.close()

    run(test)


def test_an_image_the_socket_has_not_taken_whole_is_held_until_it_has_and_what_follows_waits_behind_it():
    async def test():
        connection, client, bridge = await subscribed_to_a_camera()
        pool = bridge.config.queue_pool
        first, second = b"1" * 2_000_000, b"2" * 100_000
        connection.session.deliver(TopicRead("/camera", None, [first], STAMP))
        assert pool.shared == len(first) and len(connection.session._outbox) == 0  # (written, not queued)
        connection.session.deliver(TopicRead("/camera", None, [second], STAMP))  # (queued behind it)
        assert pool.shared == len(first) + len(second) and len(connection.session._outbox) == 1
        expected = image_frame(first) + image_frame(second)
        assert await read_all(client, len(expected)) == expected
        await until(lambda: pool.shared == 0)
        client.close()

    run(test)


def test_an_image_to_a_client_that_left_is_let_go_of():
    async def test():
        connection, client, bridge = await subscribed_to_a_camera()
        client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")  # (a reset)
        connection.session.deliver(TopicRead("/camera", None, [b"1" * 2_000_000], STAMP))
        assert bridge.config.queue_pool.shared == 2_000_000
        client.close()
        await until(lambda: bridge.config.queue_pool.shared == 0)

    run(test)


def test_an_image_delivered_after_the_socket_closed_leaves_no_hold_behind():
    """The socket closed, and the connection hears of it in a later turn: an image delivered meanwhile goes to
    write_now (may_write_now no longer asks whether the socket is closed), which writes nothing and lets the pool
    go at once; nothing is queued for a client that is gone."""

    async def test():
        connection, client, bridge = await subscribed_to_a_camera()
        connection._io.close()
        connection.session.deliver(TopicRead("/camera", None, [b"1" * 2_000_000], STAMP))
        assert bridge.config.queue_pool.shared == 0 and len(connection.session._outbox) == 0
        client.close()

    run(test)


def test_images_to_a_paced_client_are_let_go_of_once_written():
    """With delay_between_messages, frames go one per turn, queued; the turn that finds nothing more told the pool
    that the last image had left only if it had written it itself. Before, each image to a client whose socket
    kept up stayed held: the pool shared by every client filled, and every client's big messages were dropped."""

    async def test():
        connection, client, bridge = await subscribed_to_a_camera(delay_between_messages=0.01)
        pictures = [bytes([n]) * 70_000 for n in range(3)]
        for picture in pictures:
            connection.session.deliver(TopicRead("/camera", None, [picture], STAMP))
        expected = b"".join(map(image_frame, pictures))
        assert await read_all(client, len(expected)) == expected
        await until(lambda: bridge.config.queue_pool.shared == 0)
        client.close()

    run(test)
