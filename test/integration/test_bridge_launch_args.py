"""Launch options: authentication (rosauth MAC), origin allow-list, address binding, the web page, wss."""

import asyncio
import hashlib
import socket
import ssl
import subprocess
import time
import urllib.error
import urllib.request

import pytest
import tornado.httpclient

from bridge_client import WsClient, ping
from harness import launch_bridge

SECRET = "1234567890abcdef"


def mac(client, dest, rand, t, level, end, secret=SECRET):
    text = f"{secret}{client}{dest}{rand}{int(t)}{level}{int(end)}"
    return hashlib.sha512(text.encode()).hexdigest()


def auth_frame(**changes):
    now = time.time()
    fields = {
        "client": "192.168.1.101",
        "dest": "192.168.1.111",
        "rand": "xyzzy",
        "t": now,
        "level": "admin",
        "end": now + 60,
    }
    fields["mac"] = mac(**fields)
    return {"op": "auth", **fields, **changes}


@pytest.fixture(scope="module")
def auth_bridge(ros, tmp_path_factory):
    secret_file = tmp_path_factory.mktemp("auth") / "secret"
    secret_file.write_text(SECRET + "\n")
    proc, port = launch_bridge(ros, node_name="auth_bridge", authenticate="true", secret_file=secret_file)
    yield f"ws://127.0.0.1:{port}/"
    proc.stop()


def test_valid_mac_opens_every_op(auth_bridge):
    ws = WsClient(auth_bridge)
    ws.send({"op": "set_level", "level": "info"})  # refused: not authenticated yet
    reply = ws.recv()
    assert reply["level"] == "error" and "not authenticated" in reply["msg"]
    ws.send(auth_frame())
    ws.send({"op": "set_level", "level": "info"})
    ws.send({"op": "call_service", "service": "/rosapi/get_time", "id": "t"})
    assert ws.recv_op("service_response", id="t")["result"] is True
    ws.close()


@pytest.mark.parametrize(
    "frame",
    [
        {"op": "subscribe", "topic": "/rosout", "type": "rosgraph_msgs/Log", "id": "x"},
        'junk{"op": "subscribe", "topic": "/rosout", "type": "rosgraph_msgs/Log", "id": "x"}',
        {"op": "call_service", "service": "/rosapi/topics", "id": "x"},
        b'{"op": "subscribe", "topic": "/rosout", "type": "rosgraph_msgs/Log"}',
    ],
    ids=["op", "junk-before-json", "rosapi", "binary"],
)
def test_nothing_runs_before_auth(auth_bridge, frame):
    ws = WsClient(auth_bridge)
    ws.send(frame)
    reply = ws.recv()
    assert reply["op"] == "status" and reply["level"] == "error"
    ws.send({"op": "set_level", "level": "info"})
    assert "not authenticated" in ws.recv()["msg"]  # still refused: no publish/service_response came
    ws.close()


# (made when the test runs: a frame made at collection would be out of auth_time_delta, refused for its time)
@pytest.mark.parametrize(
    "make_frame",
    [
        lambda: auth_frame(mac="0" * 128),
        lambda: auth_frame(level="superuser"),  # the MAC covers the level
        lambda: auth_frame(t=time.time() - 3600),  # too old (and the MAC no longer matches)
        lambda: {k: v for k, v in auth_frame().items() if k != "rand"},
        lambda: {**auth_frame(), "t": "now"},
        lambda: {**auth_frame(), "extra": 1},
    ],
    ids=["bad-mac", "changed-level", "old", "missing-field", "wrong-type", "extra-field"],
)
def test_bad_auth_is_refused_and_closes(auth_bridge, make_frame):
    ws = WsClient(auth_bridge)
    ws.send(make_frame())
    reply = ws.recv()
    assert reply["op"] == "status" and reply["level"] == "error"
    assert ws.is_closed()


def test_expired_session_mac_is_refused(auth_bridge):
    now = time.time()
    fields = {"client": "c", "dest": "d", "rand": "r", "t": now, "level": "user", "end": now - 1}
    ws = WsClient(auth_bridge)
    ws.send({"op": "auth", "mac": mac(**fields), **fields})
    assert "authentication failed" in ws.recv()["msg"]
    assert ws.is_closed()


@pytest.fixture(scope="module")
def plain_bridge(ros):
    proc, port = launch_bridge(ros, node_name="options_bridge")
    yield port
    proc.stop()


def test_origin_same_host_and_no_origin_allowed_others_refused(plain_bridge):
    url = f"ws://127.0.0.1:{plain_bridge}/"
    assert ping(WsClient(url))
    assert ping(WsClient(url, headers={"Origin": f"http://127.0.0.1:{plain_bridge}"}))
    with pytest.raises(tornado.httpclient.HTTPClientError, match="403"):
        WsClient(url, headers={"Origin": "http://evil.example"})


@pytest.mark.parametrize("host", ["rebind.example", "localhost.evil.example"])
def test_default_origin_policy_refuses_dns_rebinding(plain_bridge, host):
    """A page of a name that the attacker's DNS points at this machine: Origin and Host agree, yet it is refused."""
    name = f"{host}:{plain_bridge}"
    with pytest.raises(tornado.httpclient.HTTPClientError, match="403"):
        WsClient(f"ws://127.0.0.1:{plain_bridge}/", headers={"Origin": f"http://{name}", "Host": name})
    local = f"localhost:{plain_bridge}"
    assert ping(WsClient(f"ws://127.0.0.1:{plain_bridge}/", headers={"Origin": f"http://{local}", "Host": local}))


def test_origin_allow_list(ros):
    proc, port = launch_bridge(ros, node_name="origin_bridge", allowed_origins="[http://good.example, https://*.lan]")
    try:
        url = f"ws://127.0.0.1:{port}/"
        assert ping(WsClient(url, headers={"Origin": "http://good.example"}))
        assert ping(WsClient(url, headers={"Origin": "https://robot.lan"}))
        assert ping(WsClient(url))  # not a browser
        assert ping(WsClient(url, headers={"Origin": f"http://127.0.0.1:{port}"}))  # the bridge's own page
        for origin in ("http://evil.example", f"http://127.0.0.1:{port + 1}", "null"):
            with pytest.raises(tornado.httpclient.HTTPClientError, match="403"):
                WsClient(url, headers={"Origin": origin})
    finally:
        proc.stop()


def test_address_is_honoured(plain_bridge):
    """Bound to 127.0.0.1 only: another loopback address of this host gets no answer."""
    with socket.create_connection(("127.0.0.1", plain_bridge), timeout=5):
        pass
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.2", plain_bridge), timeout=5).close()


def test_http_get_serves_the_page_and_its_files(plain_bridge):
    base = f"http://127.0.0.1:{plain_bridge}"
    with urllib.request.urlopen(base + "/", timeout=10) as response:
        page = response.read().decode()
        assert response.headers["Content-Type"].startswith("text/html")
    from harness import REPO

    assert page == (REPO / "web" / "index.html").read_text()
    assert urllib.request.urlopen(base + "/index.html", timeout=10).read().decode() == page
    with pytest.raises(urllib.error.HTTPError, match="404"):
        urllib.request.urlopen(base + "/no_such_file.js", timeout=10)
    with pytest.raises(urllib.error.HTTPError, match="40[34]"):
        urllib.request.urlopen(base + "/../../etc/passwd", timeout=10)


def test_web_root_off(ros):
    proc, port = launch_bridge(ros, node_name="no_page_bridge", web_root="none")
    try:
        with pytest.raises(urllib.error.HTTPError, match="404"):  # no page, the websocket still works
            urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=10)
        assert ping(WsClient(f"ws://127.0.0.1:{port}/"))
    finally:
        proc.stop()


def test_wss(ros, tmp_path):
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(
        [
            "openssl",
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-days",
            "1",
            "-subj",
            "/CN=127.0.0.1",
            "-keyout",
            str(key),
            "-out",
            str(cert),
        ],
        check=True,
        capture_output=True,
    )
    proc, port = launch_bridge(ros, node_name="wss_bridge", ssl="true", certfile=cert, keyfile=key)
    try:
        context = ssl.create_default_context(cafile=str(cert))
        context.check_hostname = False
        assert ping(WsClient(f"wss://127.0.0.1:{port}/", ssl_options=context))
    finally:
        proc.stop()


def test_deflated_frames_count_against_the_byte_budget_as_what_they_unpack_to(ros):
    # a 100 KB message of one repeated character deflates to a few hundred bytes: counted as sent, 30 of them
    # would pass a 1 MB/s budget at once
    proc, port = launch_bridge(
        ros, node_name="deflate_budget_bridge", use_compression="true", max_bytes_per_second=1_000_000
    )
    try:
        ws = WsClient(f"ws://127.0.0.1:{port}/", compression_options={})
        assert ws.conn.protocol._compressor is not None  # permessage-deflate was negotiated
        start = time.monotonic()
        for n in range(30):
            ws.send({"op": "set_level", "level": "x" * 100_000, "id": n})
        assert [ws.recv(timeout=30)["id"] for _ in range(30)] == list(range(30))
        assert time.monotonic() - start > 1.0  # 3 MB unpacked at 1 MB/s, after a burst of 1 MB
        ws.close()
    finally:
        proc.stop()


def test_compression_and_delay_between_messages(ros, node):
    from std_msgs.msg import String

    proc, port = launch_bridge(ros, node_name="deflate_bridge", use_compression="true", delay_between_messages=0.05)
    pub = node.Publisher("/options_test/deflate", String, queue_size=10, latch=True)
    pub.publish(String("squeeze me " * 100))
    try:
        ws = WsClient(f"ws://127.0.0.1:{port}/", compression_options={})
        assert ws.conn.protocol._compressor is not None  # permessage-deflate was negotiated
        ws.send({"op": "subscribe", "topic": "/options_test/deflate", "type": "std_msgs/String"})
        assert ws.recv_op("publish")["msg"]["data"] == "squeeze me " * 100
        start = time.monotonic()
        for n in range(4):
            ws.send({"op": "set_level", "level": "bogus", "id": n})
        assert [ws.recv()["id"] for _ in range(4)] == [0, 1, 2, 3]
        assert time.monotonic() - start >= 0.15  # at least 50 ms between frames
        ws.close()
    finally:
        pub.unregister()
        proc.stop()


def test_pings_keep_alive_and_drop_a_silent_peer(ros):
    """websocket_ping_interval/timeout: the bridge pings every interval; a peer that never answers (here a raw
    socket that completed the handshake and then went silent, like a phone that lost Wi-Fi) is dropped."""
    proc, port = launch_bridge(ros, node_name="ping_bridge", websocket_ping_interval=0.5, websocket_ping_timeout=1.5)
    try:
        answering = WsClient(f"ws://127.0.0.1:{port}/")  # Tornado's client answers pings while its loop runs
        with pytest.raises(asyncio.TimeoutError):
            answering.recv_raw(timeout=3)  # nothing to read for twice the ping timeout: pings answered meanwhile
        assert ping(answering)  # still served
        answering.close()
        with socket.create_connection(("127.0.0.1", port), timeout=10) as silent:
            silent.sendall(
                b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
            )
            received = b""
            started = time.monotonic()
            while chunk := silent.recv(4096):  # until the bridge closes the socket
                received += chunk
                assert time.monotonic() - started < 30, "the silent peer was never dropped"
            assert b" 101 " in received.split(b"\r\n", 1)[0]
            frames = received.split(b"\r\n\r\n", 1)[1]
            assert frames[:1] == b"\x89"  # the first frame the bridge sent is a ping (FIN + opcode 9)
            assert time.monotonic() - started >= 1.5  # kept until the timeout ran out, not dropped at once
    finally:
        proc.stop()


@pytest.mark.parametrize(
    "setting, value, must",
    [
        ("websocket_ping_timeout", "0", "above 0"),  # (it stopped the bridge with PeriodicCallback's ValueError)
        ("websocket_ping_timeout", "-1", "above 0"),
        ("websocket_ping_interval", "-1", "0 or more"),  # (each client's connection failed with that ValueError)
        ("fragment_timeout", "0", "above 0"),  # (every websocket message not whole in one read would be dropped)
    ],
)
def test_a_setting_out_of_its_range_stops_the_node_at_start_naming_it(ros, setting, value, must):
    node_name = f"bad_{setting}{value}".replace("-", "minus")
    for name, given in {"port": 0, "address": "127.0.0.1", setting: value}.items():
        ros.master().setParam(f"/{node_name}/{name}", given)
    proc = ros.spawn(["rosrun", "turtlesim", "rosbridge_websocket", f"__name:={node_name}"], node_name)
    assert proc.popen.wait(30) != 0
    assert f"setting {setting}: must be {must}, got '{value}'" in proc.output(), proc.output()[-2000:]
