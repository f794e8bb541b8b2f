"""One client never hurts another: while a hostile client (hostile.py, a process of its own) abuses the bridge,
a well-behaved client subscribed to turtlesim's 62.5 Hz pose keeps receiving it with no gap over 0.5 s, and its
/rosapi/get_time calls are answered within 1 s; the bridge's memory stays bounded and it keeps running."""

import json
import socket
import struct
import time
from pathlib import Path

import pytest
from test_security import SECRET, auth_frame

from rosbridge.protocol import session as protocol

import hostile
from bridge_client import RawWebSocket, WsClient, ping
from fixtures import From, bridge_fixture
from harness import ProcStat, node_pid, start_bridge, wait_for

pytestmark = pytest.mark.slow  # (deselect with -m 'not slow' for a quick run)

ATTACK_SECONDS = 4.0  # (each attack does its harm within a second: CI stays within its 15 minutes)
MAX_GAP = 0.5
MAX_CALL_TIME = 1.0


# MB after the attack: a client that does not read its pongs leaves nothing (they wait one at a time: 0 MB; 9-103 MB
# when each waited); after ten clients that never read, the heap keeps the pages their answers took (heap.py),
# within the peak's bound below
MAX_RSS_GROWTH = {"pings_never_read": 8, "never_reads": 300}
# MB at the peak: five unfinished messages of 30 MB took 153 MB; all clients' together are bounded at 32 MB now,
# which the bridge holds about twice of (their frames' buffers, and what malloc keeps of them): 65-76 MB seen.
# Ten clients that never read their twelve answers of 7 MB took 774 MB (64 MB waiting for each); all clients'
# outboxes are bounded together at 128 MB now: 207 MB seen. Forty clients parking a `fragment` op of 8 MB took
# 311 MB; they count in the unfinished messages' bound now: 72 MB seen.
MAX_PEAK_RSS_GROWTH = {"unfinished_messages": 100, "never_reads": 300, "parked_fragments": 150}
# s: the victim's websocket pings (p95) while four clients send messages that unpack to 31 MB each: they took
# 0.5 s (p50) to 1.1 s (p95) when each message was unpacked at once, on the loop
MAX_PING_P95 = {"inflate_bombs": 0.05}


@pytest.fixture(scope="module")
def turtlesim(ros):
    with ros.spawn(["rosrun", "turtlesim", "turtlesim_node", "__name:=isolation_turtle"], "isolation_turtle") as turtle:
        turtle.wait_output("Spawning turtle [turtle1]", timeout=30)
        yield


@pytest.fixture
def secret(tmp_path):
    """A secret file holding SECRET."""
    path = tmp_path / "secret"
    path.write_text(SECRET)
    return path


@pytest.mark.alone  # (the victim's gaps are times: beside two workers, load 10.7 on 2 cores, the bridge's loop waited
# 0.71 s for a CPU, runnable, by its thread's /proc schedstat, and the victim went 0.73 s without a pose)
@pytest.mark.parametrize("abuse", hostile.ABUSES)
def test_a_hostile_client_does_not_hurt_a_well_behaved_one(ros, turtlesim, abuse, secret):
    args = {}
    if abuse == "auth_flood":  # the attacker is not authenticated, the victim is
        args = {"authenticate": "true", "secret_file": secret}
    proc, port = start_bridge(ros, node_name=f"isolation_{abuse}", unregister_timeout=1, **args)
    try:
        got = hostile.measure(
            ros,
            f"ws://127.0.0.1:{port}/",
            ProcStat(node_pid(ros, f"/isolation_{abuse}")),
            abuse,
            ATTACK_SECONDS,
            auth=auth_frame() if args else None,
        )
        print(
            f"{abuse}: {got['attacker']} (for {got['attacked']:.2f} s); victim's largest gap {got['gap']:.3f} s "
            f"at {got['gap_at']:.2f} s (its own loop's longest stall then {got['victims_own_stall']:.3f} s), "
            f"slowest get_time {got['slowest_call']:.3f} s, pings p50 {got['ping_p50'] * 1e3:.1f} ms, "
            f"p95 {got['ping_p95'] * 1e3:.1f} ms, slowest {got['slowest_ping'] * 1e3:.1f} ms; "
            f"bridge RSS {got['rss_growth']:+.0f} MB (peak {got['peak_rss_growth']:+.0f} MB)"
        )
        assert got["attacker_exit"] == 0, got["attacker"]
        assert got["gap"] < MAX_GAP, f"{abuse}: the victim went {got['gap']:.2f} s without a pose"
        assert got["slowest_call"] < MAX_CALL_TIME, f"{abuse}: a get_time took {got['slowest_call']:.2f} s"
        assert got["rss_growth"] < MAX_RSS_GROWTH.get(abuse, 200), (
            f"{abuse}: the bridge grew by {got['rss_growth']:.0f} MB"
        )
        assert got["peak_rss_growth"] < MAX_PEAK_RSS_GROWTH.get(abuse, 400), (
            f"{abuse}: the bridge grew by {got['peak_rss_growth']:.0f} MB at its peak"
        )
        assert got["ping_p95"] < MAX_PING_P95.get(abuse, MAX_GAP), (
            f"{abuse}: the victim's pings took {got['ping_p95'] * 1e3:.0f} ms (p95)"
        )
        assert proc.alive()
    finally:
        proc.stop()


UNFINISHED_TIMEOUT = 3.0  # s: its bridge's fragment_timeout
unfinished_bridge = bridge_fixture("isolation_unfinished", scope="function", fragment_timeout=UNFINISHED_TIMEOUT)


def test_unfinished_messages_are_dropped_after_fragment_timeout_and_their_memory_with_them(ros, unfinished_bridge):
    """Three clients each begin a 10 MB message and stop: a fragmented one (FIN=0 frames), or one frame cut short
    (30 MB in all: within what unfinished messages may hold together). fragment_timeout after its first byte each
    is closed (1008, naming the setting) and the bridge lets go of what they held: it is back where it was, and
    again after three more do the same (before, each one's message stayed until it left). A client whose message
    takes a while but ends in time keeps its connection."""
    timeout = UNFINISHED_TIMEOUT
    port = unfinished_bridge
    stat = ProcStat(node_pid(ros, "/isolation_unfinished"))
    part = bytes(1_000_000)
    fragmented = (
        RawWebSocket.header(len(part), fin=False)
        + bytes(4)
        + part
        + (RawWebSocket.header(len(part), opcode=0x0, fin=False) + bytes(4) + part) * 9
    )
    cut_short = RawWebSocket.header(11_000_000) + bytes(4) + bytes(10_000_000)

    def unfinished_by_three(slow=None):
        """RSS growth while three clients hold their messages, and when the bridge closed them."""
        holders = [RawWebSocket(port) for _ in range(3)]
        started = time.monotonic()
        for index, holder in enumerate(holders):
            holder.sock.sendall(fragmented if index % 2 else cut_short)
        if slow is not None:
            slow.sock.sendall(RawWebSocket.frame(b'{"op":"set_level",', fin=False))
        time.sleep(timeout - 1)
        held = stat.rss_mb() - before
        if slow is not None:
            slow.sock.sendall(RawWebSocket.frame(b'"level":"bogus","id":"late"}', opcode=0x0))
        for holder in holders:
            opcode, payload = holder.recv_frame()
            assert (opcode, payload[:2]) == (0x8, struct.pack("!H", 1008)) and b"fragment_timeout" in payload
            assert holder.closed_by_server()
            holder.close()
        return held, time.monotonic() - started

    time.sleep(1)
    before = stat.rss_mb()
    slow = RawWebSocket(port)
    held, closed = unfinished_by_three(slow)
    opcode, payload = slow.recv_frame()
    assert opcode == 0x1 and b"bogus" in payload, payload  # (its status: still served)
    slow.close()
    after_first = stat.rss_mb() - before
    held_again, closed_again = unfinished_by_three()
    after_second = stat.rss_mb() - before
    print(
        f"held +{held:.0f} MB, closed after {closed:.1f} s, then +{after_first:.0f} MB; again +{held_again:.0f} MB,"
        f" closed after {closed_again:.1f} s, then +{after_second:.0f} MB"
    )
    # (what three more hold at once varies with how their reads interleave in the heap: 33-51 MB; once they are
    # closed, the bridge is back within 0-6 MB, or within 17-21 MB when the heap keeps one 10 MB block, in about one
    # run in four; where kept, 30 MB more would stay every round)
    assert held > 25 and after_first < 25 and after_second < 25
    assert timeout <= closed < timeout + 2 and timeout <= closed_again < timeout + 2


fds_bridge = bridge_fixture("isolation_fds", scope="function", yields="bridge", max_fds=256)


def test_idle_connections_beyond_the_descriptor_limit_neither_spin_nor_lock_clients_out(ros, turtlesim, fds_bridge):
    """Under `ulimit -n 256`, 400 idle TCP connections: the bridge stops accepting for a while instead of failing
    accept() in a loop (little CPU, a few log lines), closes the idle ones, and then takes new clients again."""
    proc, port = fds_bridge.proc, fds_bridge.port
    stat = ProcStat(node_pid(ros, "/isolation_fds"))
    idle = []
    for _ in range(400):
        try:
            idle.append(socket.create_connection(("127.0.0.1", port), timeout=2))
        except OSError:
            break
    cpu, log_size = stat.cpu_seconds(), proc.log_path.stat().st_size
    time.sleep(3)
    assert stat.cpu_seconds() - cpu < 1.0, "the bridge spins while descriptors are short"
    assert proc.log_path.stat().st_size - log_size < 5000, proc.output()[-2000:]
    for sock in idle:
        sock.close()
    client = wait_for(lambda: connects(f"ws://127.0.0.1:{port}/"), 30, what="a new client after the idle ones left")
    client.close()


def connects(url):
    try:
        return WsClient(url, timeout=2)
    except (OSError, TimeoutError):
        return None


squat_bridge = bridge_fixture("isolation_squat", scope="function", unregister_timeout=1)


def test_a_departed_clients_type_does_not_bind_the_topic(ros, node, squat_bridge):
    """A client subscribes to /squat/cmd_vel as std_msgs/String and leaves; the master still remembers that type,
    but nobody uses the topic any more: another client may advertise it as a Twist (a turtle spawned there)."""
    from geometry_msgs.msg import Twist

    port = squat_bridge
    squatter = WsClient(f"ws://127.0.0.1:{port}/")
    squatter.send({"op": "subscribe", "topic": "/squat/cmd_vel", "type": "std_msgs/String"})
    wait_for(lambda: "/squat/cmd_vel" in dict(ros.master().getTopicTypes()), 10, what="the squatted type")
    squatter.close()
    wait_for(
        lambda: not any(t == "/squat/cmd_vel" for t, _ in ros.master().getSystemState()[1]),
        10,
        what="the squatter's subscription gone",
    )
    got = []
    sub = node.Subscriber("/squat/cmd_vel", Twist, got.append)
    driver = WsClient(f"ws://127.0.0.1:{port}/")
    driver.send({"op": "advertise", "topic": "/squat/cmd_vel", "type": "geometry_msgs/Twist", "id": "adv"})
    forward = {"op": "publish", "topic": "/squat/cmd_vel", "msg": {"linear": {"x": 1.0}}}
    wait_for(lambda: (driver.send(forward), got)[1], 10, interval=0.2, what="the Twist through the topic")
    with pytest.raises(TimeoutError):  # and no refusal came
        driver.recv_until(lambda f: f.get("op") == "status", timeout=1)
    driver.close()
    sub.unregister()


fds_release_bridge = bridge_fixture("isolation_fds_release", scope="function")


def test_a_client_leaving_releases_its_descriptors(ros, fds_release_bridge):
    port = fds_release_bridge
    pid = node_pid(ros, "/isolation_fds_release")
    count = lambda: len(list(Path(f"/proc/{pid}/fd").iterdir()))  # noqa: E731
    client = WsClient(f"ws://127.0.0.1:{port}/")
    time.sleep(1)
    before = count()
    for i in range(150):
        client.send({"op": "subscribe", "topic": f"/isolation/fd{i}", "type": "std_msgs/String"})
    wait_for(
        lambda: sum(t.startswith("/isolation/fd") for t, _ in ros.master().getSystemState()[1]) == 150,
        30,
        what="150 subscriptions",
    )
    assert count() > before
    client.close()
    wait_for(lambda: count() <= before + 5, 30, what=f"the descriptors back to {before} (now {count()})")


stalled_bridge = bridge_fixture("isolation_stalled", scope="function")


def test_a_client_stalled_in_a_big_message_does_not_lock_the_others_out(stalled_bridge):
    """A client sends 31.8 MB of a 31.9 MB message (all that unfinished messages may hold together) and stops.
    Another client publishing 1 MB, which needs part of that bound, is served: the stalled one makes way (closed
    with 1013, try again) for the one whose bytes keep coming. Before, the one arriving was refused with 1013
    while the stalled one could hold the bound for fragment_timeout (600 s), and start again."""
    port = stalled_bridge
    hog = RawWebSocket(port, recv_buffer=4096)
    size = 31_900_000
    hog.sock.sendall(RawWebSocket.header(size) + bytes(4) + b" " * (size - 100_000))
    time.sleep(3)  # (its bytes stopped coming)
    client = WsClient(f"ws://127.0.0.1:{port}/")
    client.send({"op": "advertise", "topic": "/isolation/big", "type": "std_msgs/String"})
    client.send({"op": "publish", "topic": "/isolation/big", "msg": {"data": "x" * 1_000_000}})
    reply = client.request({"op": "call_service", "service": "/rosapi/get_time", "id": "after"})
    assert reply["op"] == "service_response" and reply["result"], reply
    client.close()
    opcode, payload = hog.recv_frame()
    assert (opcode, payload[:2]) == (0x8, struct.pack("!H", 1013)), payload
    hog.close()


never_reads_bridge = bridge_fixture("isolation_never_reads", scope="function", websocket_ping_timeout=2)


def test_a_client_that_never_reads_is_closed_after_websocket_ping_timeout(ros, never_reads_bridge):
    """A client that reads nothing while the bridge has answers for it (three of 3 MB) is closed once nothing of
    them has left for websocket_ping_timeout, and what waited for it is let go; a client that reads slowly, but
    reads, gets all of a 3 MB answer that takes longer than that to go. Before, the one that never read was kept
    (with up to 64 MB waiting for it) until it left."""
    port = never_reads_bridge
    pid = node_pid(ros, "/isolation_never_reads")
    descriptors = lambda: len(list(Path(f"/proc/{pid}/fd").iterdir()))  # noqa: E731
    call = json.dumps(
        {
            "op": "call_service",
            "service": "/rosapi/get_param",
            "id": "big",
            "args": {"name": "/isolation/unset", "default": json.dumps("B" * 3_000_000)},
        }
    ).encode()
    time.sleep(1)
    before = descriptors()
    idle = RawWebSocket(port, recv_buffer=4096)
    for _ in range(3):
        idle.sock.sendall(RawWebSocket.frame(call))
    slow = RawWebSocket(port, recv_buffer=65536)
    slow.sock.sendall(RawWebSocket.frame(call))
    started, got = time.monotonic(), 0
    wait_for(lambda: descriptors() == before + 2, 10, what="both clients connected")
    while got < 3_000_000:  # (at most 800 kB/s: 3.75 s for the answer)
        data = slow.sock.recv(8192)
        assert data, f"the slow client was closed after {got} bytes"
        got += len(data)
        time.sleep(0.01)
    taken = time.monotonic() - started
    assert taken > 3, taken  # (the slow client's answer took longer than websocket_ping_timeout)
    assert descriptors() == before + 1, "the client that never reads is still connected"
    ping_raw(slow)
    slow.close()
    idle.close()


def ping_raw(client):
    """The raw client is still served: a websocket ping answered (after what was sent before it)."""
    client.sock.sendall(RawWebSocket.frame(b"alive", opcode=0x9))
    while True:
        opcode, payload = client.recv_frame()
        if opcode == 0xA:
            assert payload == b"alive"
            return


no_auth_bridge = bridge_fixture(
    "isolation_no_auth", scope="function", authenticate="true", secret_file=From("secret"), max_clients=5
)


def test_clients_that_do_not_authenticate_make_way_for_one_that_does(no_auth_bridge):
    """With authenticate, idle clients that never authenticate fill max_clients. One more client is let in,
    the longest waiting of them making way (closed), and the others are closed protocol.AUTH_TIMEOUT after they came.
    Before, the client that came to authenticate got 503 for as long as they stayed."""
    port = no_auth_bridge
    idle = [RawWebSocket(port) for _ in range(5)]
    time.sleep(0.5)
    started = time.monotonic()
    client = WsClient(f"ws://127.0.0.1:{port}/")
    client.send(auth_frame(rand="isolation-no-auth"))
    reply = client.request({"op": "call_service", "service": "/rosapi/get_time", "id": "t"})
    assert reply["op"] == "service_response" and reply["result"], reply
    opcode, payload = idle[0].recv_frame()  # (the first one came first)
    assert opcode == 0x8 and payload[:2] == struct.pack("!H", 1013), payload
    for waiting in idle[1:]:
        opcode, payload = waiting.recv_frame()
        assert opcode == 0x8 and b"authenticate" in payload, payload
    closed = time.monotonic() - started
    assert protocol.AUTH_TIMEOUT - 1 < closed < protocol.AUTH_TIMEOUT + 2, closed
    ping(client)
    client.close()
