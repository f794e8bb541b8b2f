"""The rospy-free parts of the ROS side: who holds what, the early replay's thread rules, and the proxy for the
bridge's own looks at the master."""

import threading
import xmlrpc.client

import pytest
from rosgraph.xmlrpc import ThreadingXMLRPCServer

from rosbridge.ros_side.holders import Holders
from rosbridge.ros_side.master_proxy import ANSWERS_KEPT, MasterError, api_proxy, succeeded
from rosbridge.ros_side.publishers import REPLAY_BYTES, REPLAY_WINDOW, EarlyReplay

from fakes import Clock


def test_the_first_holder_makes_and_the_last_one_releases():
    holders = Holders()
    assert holders.add("/t", "a") is True
    assert holders.add("/t", "b") is False
    assert holders.add("/t", "a") is False
    assert holders.discard("/t", "a") is False
    assert holders.holds("/t", "b") and not holders.holds("/t", "a")
    assert holders.discard("/t", "c") is False  # never held
    assert holders.discard("/t", "b") is True
    assert holders.holders("/t") == () and holders.discard("/t", "b") is False


def test_names_of_a_holder():
    holders = Holders()
    for name in ("/a", "/b"):
        holders.add(name, "x")
    holders.add("/c", "y")
    assert sorted(holders.names_of("x")) == ["/a", "/b"]


def test_early_messages_are_replayed_to_a_subscriber_within_the_window_after_registering():
    """The window starts when the master knows the publisher, however long the worker took to register it (it
    started at the advertise: beside a CPU hog, a page's first Twist was lost)."""
    clock = Clock(100.0)
    replay = EarlyReplay(10, clock)
    replay.record("m1")
    clock.now += 5 * REPLAY_WINDOW  # (the worker, busy)
    replay.record("m2")
    replay.registered()
    clock.now += REPLAY_WINDOW / 2
    assert replay.replay() == ("m1", "m2")
    clock.now += REPLAY_WINDOW / 2
    replay.record("m3")
    assert replay.replay() == ()


def test_no_replay_once_a_subscriber_left():
    replay = EarlyReplay(10, Clock(100.0))
    replay.record("m1")
    replay.end()
    replay.record("m2")
    assert replay.replay() == ()


def test_early_replay_keeps_the_newest_messages():
    replay = EarlyReplay(2, Clock(100.0))
    for n in range(5):
        replay.record(b"%d" % n)
    assert replay.replay() == (b"3", b"4")


def test_early_replay_keeps_the_newest_messages_within_replay_bytes():
    """Before, it kept queue_size messages of any size: a client advertising new topics and publishing 8 MB
    messages at once on each held 620 MB in 5 s."""
    replay = EarlyReplay(100, Clock(100.0))
    for n in range(5):
        replay.record(bytes([n]) * (REPLAY_BYTES // 3))
    assert [m[0] for m in replay.replay()] == [2, 3, 4]
    replay.record(bytes(REPLAY_BYTES + 1))  # (too big to keep)
    assert [m[0] for m in replay.replay()] == [2, 3, 4]


@pytest.fixture
def xmlrpc_server():
    """rosgraph's XML-RPC server, the master's, on loopback; `answer` is what its one method returns, and
    `encodings` the Accept-Encoding of each request."""
    server = ThreadingXMLRPCServer(("127.0.0.1", 0), log_requests=False)
    server.answer = [1, "", "small"]
    server.encodings = []
    server.register_function(lambda caller: server.answer, "getSystemState")
    handler = server.RequestHandlerClass
    parse_request = handler.parse_request

    def recording(request):
        parsed = parse_request(request)
        server.encodings.append(request.headers.get("Accept-Encoding"))
        return parsed

    handler.parse_request = recording
    threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True).start()
    try:
        yield server
    finally:
        handler.parse_request = parse_request
        server.shutdown()
        server.server_close()


def test_an_answer_seen_lately_is_not_parsed_again(xmlrpc_server):
    proxy = api_proxy("http://127.0.0.1:%d/" % xmlrpc_server.server_address[1])
    first = proxy.getSystemState("/me")
    assert first == [1, "", "small"] and proxy.getSystemState("/me") is first
    answers = [[1, "", "x" * n] for n in (3000, 3001, 3002)]
    for answer in answers:
        xmlrpc_server.answer = answer
        assert proxy.getSystemState("/me") == answer
    xmlrpc_server.answer = [1, "", "small"]
    assert proxy.getSystemState("/me") is first  # (within ANSWERS_KEPT)
    xmlrpc_server.answer = [1, "", "x" * 4000]
    proxy.getSystemState("/me")
    xmlrpc_server.answer = answers[0]
    assert proxy.getSystemState("/me") == answers[0]  # (forgotten, parsed again)
    assert len(proxy("transport")._answers) == ANSWERS_KEPT


def test_answers_are_asked_unzipped(xmlrpc_server):
    """The master gzips answers over 1,400 bytes for a client that accepts it (Python's own client does)."""
    proxy = api_proxy("http://127.0.0.1:%d/" % xmlrpc_server.server_address[1])
    xmlrpc_server.answer = [1, "", "x" * 10_000]
    assert proxy.getSystemState("/me") == xmlrpc_server.answer
    xmlrpc.client.ServerProxy("http://127.0.0.1:%d/" % xmlrpc_server.server_address[1]).getSystemState("/me")
    assert xmlrpc_server.encodings == ["identity", "gzip"]


def test_an_error_code_from_the_master_is_an_error():
    assert succeeded([1, "ok", ["value"]]) == ["value"]
    with pytest.raises(MasterError, match="no such service"):
        succeeded([-1, "no such service", 0])
