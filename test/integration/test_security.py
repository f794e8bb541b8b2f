"""Security of live bridges: the listening address, the origin allow-list, the Host check (DNS rebinding), the
globs as a wall (not only a filter of rosapi lists), rosauth authentication that cannot be bypassed, TLS, and the
message size limit."""

import hashlib
import json
import socket
import ssl
import subprocess
import time
import urllib.error
import urllib.parse
import urllib.request

import pytest
import roslibpy
import tornado.httpclient

from bridge_client import WsClient, ping
from fixtures import From, bridge_fixture
from harness import ProcStat, make_workdir, node_pid, wait_for
from sensor_messages import big_cloud

SECRET = "fuzz-and-security-secret"


def connect_refused(host, port):
    try:
        socket.create_connection((host, port), timeout=5).close()
        return False
    except OSError:
        return True


def listening_addresses(port):
    """The local addresses of the sockets listening on TCP `port`, as `ss` shows them."""
    out = subprocess.run(["ss", "-Hltn", f"sport = :{port}"], capture_output=True, text=True, check=True).stdout
    return sorted(line.split()[3].rsplit(":", 1)[0] for line in out.splitlines() if line.strip())


def other_local_addresses():
    """IPv4 addresses of this machine besides 127.0.0.1 (127.0.0.2 is always there: lo owns 127/8)."""
    out = subprocess.run(["ip", "-o", "-4", "addr", "show"], capture_output=True, text=True, check=True).stdout
    found = {line.split()[3].split("/")[0] for line in out.splitlines()}
    return sorted((found | {"127.0.0.2"}) - {"127.0.0.1"})


# ---- address binding --------------------------------------------------------------------------------------
bind_bridge = bridge_fixture("security_bind_bridge", scope="function", address=From("address"))


@pytest.mark.parametrize("address", ["127.0.0.1", "127.0.0.2"])
def test_the_bridge_listens_only_on_the_given_address(address, bind_bridge):
    port = bind_bridge
    assert listening_addresses(port) == [address]
    client = WsClient(f"ws://{address}:{port}/")
    assert ping(client)
    client.close()
    for other in other_local_addresses() + ["127.0.0.1"]:
        if other != address:
            assert connect_refused(other, port), f"reachable on {other}:{port}"


# ---- origins ----------------------------------------------------------------------------------------------
origin_bridge = bridge_fixture(
    "security_origin_bridge", allowed_origins="[http://good.example:8080, https://*.robots.lan]"
)
default_bridge_proc = bridge_fixture("security_default_origin_bridge", yields="bridge")


@pytest.fixture(scope="module")
def default_bridge(default_bridge_proc):
    return default_bridge_proc.port


def refused_with_403(port, origin, host_header=None):
    headers = {"Origin": origin, **({"Host": host_header} if host_header else {})}
    with pytest.raises(tornado.httpclient.HTTPClientError) as error:
        WsClient(f"ws://127.0.0.1:{port}/", headers=headers)
    return error.value.code == 403


@pytest.mark.parametrize(
    "origin", ["http://good.example:8080", "HTTP://GOOD.EXAMPLE:8080", "https://a.robots.lan", "https://b.c.robots.lan"]
)
def test_allowed_origins_connect(origin_bridge, origin):
    client = WsClient(f"ws://127.0.0.1:{origin_bridge}/", headers={"Origin": origin})
    assert ping(client)
    client.close()


@pytest.mark.parametrize(
    "origin",
    [
        "http://evil.example",
        "http://good.example:8081",
        "https://good.example:8080",
        "http://good.example:8080.evil.example",
        "https://robots.lan.evil.example",
        "http://a.robots.lan",
        "null",
        "",
    ],
)
def test_other_origins_are_refused_with_403(origin_bridge, origin):
    assert refused_with_403(origin_bridge, origin)


def test_the_bridges_own_page_connects_to_an_allow_list_bridge(origin_bridge):
    for own in (f"http://127.0.0.1:{origin_bridge}", f"http://localhost:{origin_bridge}"):
        client = WsClient(f"ws://{urllib.parse.urlsplit(own).netloc}/", headers={"Origin": own})
        assert ping(client)
        client.close()


def test_roslibpy_sends_no_origin_and_connects_to_an_allow_list_bridge(origin_bridge):
    ros = roslibpy.Ros(host="127.0.0.1", port=origin_bridge)
    ros.run(timeout=20)
    assert ros.is_connected
    ros.close()


@pytest.mark.parametrize("origin", ["http://localhost:8765", "http://127.0.0.1:3000", "null"])
def test_default_allows_this_machines_pages_on_any_port_and_from_disk(default_bridge, origin):
    """The tutorial's page served from another port, or opened from disk (Origin "null") by a browser on this
    machine (the test connects from 127.0.0.1)."""
    client = WsClient(f"ws://127.0.0.1:{default_bridge}/", headers={"Origin": origin})
    assert ping(client)
    client.close()


def test_default_refuses_look_alike_origins(default_bridge):
    for origin in (
        "http://localhost.evil.example",
        f"http://127.0.0.1.evil.example:{default_bridge}",
        "http://192.0.2.7:8000",
    ):
        assert refused_with_403(default_bridge, origin)


def test_a_refused_origin_is_logged_once_with_the_launch_arg_that_allows_it(default_bridge_proc):
    proc, port = default_bridge_proc.proc, default_bridge_proc.port
    origin = "http://once.example:8000"
    for _ in range(3):
        assert refused_with_403(port, origin)
    advice = f'allowed_origins:="[{origin}]"'
    proc.wait_output(advice)
    assert proc.output().count(advice) == 1


def test_default_refuses_a_dns_rebinding_page(default_bridge):
    """A page of http://rebind.example:PORT whose name the attacker re-points at 127.0.0.1: the browser sends
    Host and Origin of that name, so "same host" holds, yet the page is not one the user trusts."""
    host = f"rebind.example:{default_bridge}"
    assert refused_with_403(default_bridge, f"http://{host}", host_header=host)


# ---- Host: DNS rebinding ---------------------------------------------------------------------------------------
REBIND = "/sec_rebind"
BAG_BYTES = b"#ROSBAG V2.0\n" + bytes(range(256))


@pytest.fixture(scope="module")
def rebind_folder(tmp_path_factory):
    """A bag folder with a bag in it."""
    folder = tmp_path_factory.mktemp("rebind_bags")
    (folder / "run.bag").write_bytes(BAG_BYTES)
    return folder


@pytest.fixture(scope="module")
def rebind_latched(node):
    """A latched camera picture and a latched cloud."""
    from sensor_msgs.msg import Image, PointCloud2

    camera = node.Publisher(f"{REBIND}/camera", Image, queue_size=1, latch=True)
    camera.publish(Image(width=4, height=2, encoding="mono8", step=4, data=bytes(8)))
    cloud = node.Publisher(f"{REBIND}/cloud", PointCloud2, queue_size=1, latch=True)
    cloud.publish(big_cloud(100))
    yield
    camera.unregister()
    cloud.unregister()


# a bridge that has something to steal: a bag, a latched camera picture and a latched cloud; and a reverse proxy's
# public name in allowed_hosts
rebind_bridge = bridge_fixture(
    "security_rebind_bridge",
    yields="bridge",
    needs=("rebind_latched",),
    bag_folder=From("rebind_folder"),
    allowed_hosts="[robots.example, *.robots.lan]",
)


def browser_get(port, path, host):
    """(status, body) of a GET as a browser sends it for a page's fetch() of its own site (the name `host`
    re-pointed at 127.0.0.1 by the attacker's DNS): no Origin, the page's Referer and the usual headers."""
    request = urllib.request.Request(
        f"http://127.0.0.1:{port}{path}",
        headers={
            "Host": host,
            "Connection": "keep-alive",
            "Accept": "*/*",
            "Accept-Language": "en-US,en;q=0.9",
            "User-Agent": "Mozilla/5.0 (X11; Linux x86_64) AppleWebKit/537.36 (KHTML, like Gecko) Chrome/120.0",
            "Referer": f"http://{host}/",
            "Sec-Fetch-Site": "same-origin",
            "Sec-Fetch-Mode": "cors",
            "Sec-Fetch-Dest": "empty",
        },
    )
    try:
        with urllib.request.urlopen(request, timeout=20) as answer:
            return answer.status, answer.read(len(BAG_BYTES))  # (a stream goes on: its start is enough)
    except urllib.error.HTTPError as error:
        return error.code, error.read()


REBIND_PATHS = [
    "/bags/run.bag",
    "/bags",
    f"/snapshot?topic={REBIND}/camera",
    f"/cloud?topic={REBIND}/cloud",
    f"/stream?topic={REBIND}/camera",
    f"/stream_viewer?topic={REBIND}/camera",
    "/streams",
    "/",
    "/app.js",
]


@pytest.mark.parametrize("path", REBIND_PATHS)
def test_a_dns_rebinding_page_reads_nothing(rebind_bridge, path):
    """Before: 200 and the bag, the list, the picture, the cloud (a same-origin GET carries no Origin)."""
    port = rebind_bridge.port
    host = f"evil.example:{port}"
    status, body = browser_get(port, path, host)
    assert status == 403, (status, body[:200])
    assert host.encode() in body and b"allowed_hosts" in body, body


def test_a_dns_rebinding_page_opens_no_websocket(rebind_bridge):
    """A browser sends the page's Origin with a websocket; Host is checked before it, with or without one."""
    port = rebind_bridge.port
    for headers in (
        {"Host": f"evil.example:{port}"},
        {"Host": f"evil.example:{port}", "Origin": f"http://evil.example:{port}"},
    ):
        with pytest.raises(tornado.httpclient.HTTPClientError) as error:
            WsClient(f"ws://127.0.0.1:{port}/", headers=headers)
        assert error.value.code == 403, headers


@pytest.mark.parametrize(
    "make_host",
    [
        lambda port: f"127.0.0.1:{port}",
        lambda port: f"localhost:{port}",
        lambda port: "localhost",
        lambda port: f"LOCALHOST.:{port}",
        lambda port: f"[::1]:{port}",
        lambda port: f"{socket.gethostname()}:{port}",
        lambda port: f"{socket.gethostname().split('.')[0]}.local:{port}",
        lambda port: f"app.localhost:{port}",
        lambda port: "robots.example",
        lambda port: "Robots.Example:8443",
        lambda port: "rover1.robots.lan",
    ],
    ids=[
        "127.0.0.1",
        "localhost",
        "localhost without port",
        "localhost.",
        "[::1]",
        "host name",
        "mDNS name",
        "*.localhost",
        "allowed_hosts",
        "allowed_hosts with port",
        "allowed_hosts pattern",
    ],
)
def test_this_machines_names_and_allowed_hosts_still_work(rebind_bridge, make_host):
    port = rebind_bridge.port
    host = make_host(port)
    assert browser_get(port, "/bags/run.bag", host) == (200, BAG_BYTES)
    client = WsClient(f"ws://127.0.0.1:{port}/", headers={"Host": host})
    assert ping(client)
    client.close()


def test_a_malformed_host_is_a_bad_request(rebind_bridge):
    port = rebind_bridge.port
    status, body = browser_get(port, "/bags/run.bag", "evil.example@localhost")
    assert status == 400 and b"evil.example@localhost" in body, (status, body)


def test_a_request_without_host_is_not_a_browsers_and_is_served(rebind_bridge):
    """HTTP/1.0 scripts may send no Host; browsers always send one (the page's), so rebinding cannot come so."""
    port = rebind_bridge.port
    with socket.create_connection(("127.0.0.1", port), timeout=10) as conn:
        conn.sendall(b"GET /bags/run.bag HTTP/1.0\r\n\r\n")
        answer = b""
        while chunk := conn.recv(65536):
            answer += chunk
    assert answer.startswith(b"HTTP/1.1 200") and answer.endswith(BAG_BYTES), answer[:200]


def test_a_refused_host_is_logged_once_with_the_launch_arg_that_allows_it(rebind_bridge):
    proc, port = rebind_bridge.proc, rebind_bridge.port
    for _ in range(3):
        assert browser_get(port, "/bags", f"once.example:{port}")[0] == 403
    advice = 'allowed_hosts:="[robots.example, *.robots.lan, once.example]"'
    proc.wait_output(advice)
    assert proc.output().count(advice) == 1


def test_hosts_that_allowed_origins_allows_are_served(origin_bridge):
    """A page allowed_origins lists may be served by the bridge under that name (a reverse proxy passing it on)."""
    for host, status in [
        ("good.example:8080", 200),
        ("a.robots.lan", 200),
        ("good.example", 403),
        ("a.robots.lan.evil.example", 403),
    ]:
        assert browser_get(origin_bridge, "/", host)[0] == status, host


@pytest.mark.parametrize(
    "path",
    [
        "/../../../../etc/passwd",
        "/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
        "/..%2f..%2f..%2fetc%2fpasswd",
        "//etc/passwd",
        "/vendor/../../package.xml",
    ],
)
def test_the_page_server_serves_nothing_outside_web_root(default_bridge, path):
    with socket.create_connection(("127.0.0.1", default_bridge), timeout=10) as conn:
        conn.sendall(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n".encode())
        answer = b""
        while chunk := conn.recv(65536):
            answer += chunk
    status = answer.split(b"\r\n", 1)[0]
    assert b"root:" not in answer and b"<package" not in answer, status
    assert status.split()[1] in (b"400", b"403", b"404"), status


@pytest.fixture(scope="module")
def web_root(tmp_path_factory):
    """A web_root laid out as the demo's is, with a symlink pointing out of it and the npm tree beside the page."""
    root = tmp_path_factory.mktemp("web_root")
    (root / "index.html").write_text("<canvas></canvas>")
    (root / "app.js").write_text("export const page = 1;")
    (root / "leak.js").symlink_to("/etc/passwd")
    (root / "node_modules" / "roslib").mkdir(parents=True)
    (root / "node_modules" / "roslib" / "index.js").write_text("module.exports = 1;")
    (root / "package.json").write_text('{"name": "page"}')
    (root / ".hidden.js").write_text("secret")
    return root


page_bridge = bridge_fixture("security_page_bridge", web_root=From("web_root"))


def http(url, method="GET"):
    """(status, headers, body) of one request."""
    request = urllib.request.Request(url, method=method)
    try:
        with urllib.request.urlopen(request, timeout=10) as answer:
            return answer.status, answer.headers, answer.read()
    except urllib.error.HTTPError as error:
        return error.code, error.headers, b""


@pytest.mark.parametrize("path", ["/", "/app.js"])
def test_page_files_are_served_with_nosniff_and_no_framing(page_bridge, path):
    status, headers, body = http(f"http://127.0.0.1:{page_bridge}{path}")
    assert status == 200 and body
    assert headers["X-Content-Type-Options"] == "nosniff"
    assert headers["X-Frame-Options"] == "DENY"
    assert "frame-ancestors 'none'" in headers["Content-Security-Policy"]


def test_head_of_the_page(page_bridge):
    status, headers, body = http(f"http://127.0.0.1:{page_bridge}/", method="HEAD")
    assert (status, body) == (200, b"") and headers["Content-Type"].startswith("text/html")


@pytest.mark.parametrize("path", ["/leak.js", "/node_modules/roslib/index.js", "/package.json", "/.hidden.js"])
def test_only_the_pages_own_files_are_served(page_bridge, path):
    status, _, body = http(f"http://127.0.0.1:{page_bridge}{path}")
    assert status == 404 and b"root:" not in body


# ---- globs ------------------------------------------------------------------------------------------------
glob_bridge = bridge_fixture(
    "security_glob_bridge", topics_glob="[/sec/open/*]", services_glob="[/sec/open/*]", params_glob="[/sec/open/*]"
)


@pytest.fixture
def glob_client(glob_bridge):
    client = WsClient(f"ws://127.0.0.1:{glob_bridge}/")
    yield client
    client.close()


def refused(reply, name):
    """A status error or a failed service_response that names the hidden thing."""
    if reply["op"] == "status":
        return reply["level"] == "error" and name in reply["msg"]
    return reply["result"] is False and name in json.dumps(reply["values"])


@pytest.mark.parametrize(
    "frame",
    [
        {"op": "subscribe", "topic": "/sec/hidden/pose", "type": "std_msgs/String"},
        {"op": "advertise", "topic": "/sec/hidden/cmd", "type": "std_msgs/String"},
        {"op": "publish", "topic": "/sec/hidden/cmd", "msg": {"data": "x"}},
        {"op": "call_service", "service": "/sec/hidden/reset"},
        {"op": "advertise_service", "service": "/sec/hidden/offer", "type": "std_srvs/Empty"},
        {"op": "call_service", "service": "/rosapi/get_param", "args": {"name": "/sec/hidden/gain"}},
        {"op": "call_service", "service": "/rosapi/set_param", "args": {"name": "/sec/hidden/gain", "value": "1"}},
        {"op": "call_service", "service": "/rosapi/delete_param", "args": {"name": "/sec/hidden/gain"}},
    ],
    ids=lambda frame: f"{frame['op']}-{frame.get('topic') or frame['service']}",
)
def test_hidden_names_are_refused(glob_client, frame):
    name = frame["args"]["name"] if "args" in frame else frame.get("topic") or frame["service"]
    reply = glob_client.request({**frame, "id": "hidden"})
    assert refused(reply, name), reply
    assert ping(glob_client)


def test_relative_service_names_meet_the_globs_as_ros_resolves_them(glob_client):
    """roslib 2.x calls "rosapi/topics": resolved in the bridge's namespace ("/"), as rospy does."""
    reply = glob_client.request({"op": "call_service", "service": "rosapi/topics", "id": "relative rosapi"})
    assert reply["op"] == "service_response" and reply["result"] is True, reply
    assert refused(
        glob_client.request({"op": "call_service", "service": "sec/hidden/reset", "id": "r"}), "/sec/hidden/reset"
    )


def test_a_library_call_of_a_hidden_service_fails_at_once(glob_bridge):
    """roslibjs and roslibpy match a call by its service_response; the spec answers failures with
    result:false, so the caller's error callback runs instead of waiting forever."""
    ros = roslibpy.Ros(host="127.0.0.1", port=glob_bridge)
    ros.run(timeout=20)
    try:
        with pytest.raises(roslibpy.core.ServiceException, match="/sec/hidden/reset"):
            roslibpy.Service(ros, "/sec/hidden/reset", "std_srvs/Empty").call(roslibpy.ServiceRequest(), timeout=15)
    finally:
        ros.close()


@pytest.fixture
def hidden_things(ros, node):
    """A latched publisher, a service and a parameter under /sec/hidden, which the glob bridge hides."""
    from std_msgs.msg import String
    from std_srvs.srv import Empty, EmptyResponse

    ros.run(["rosparam", "set", "/sec/hidden/gain", "7"])
    calls = []
    server = node.Service("/sec/hidden/reset", Empty, lambda req: calls.append(req) or EmptyResponse())
    pub = node.Publisher("/sec/hidden/pose", String, queue_size=10, latch=True)
    pub.publish(String("secret"))
    wait_for(lambda: "/sec/hidden/pose" in dict(ros.master().getTopicTypes()), 20, what="the hidden topic")
    yield calls
    server.shutdown()
    pub.unregister()
    ros.run(["rosparam", "delete", "/sec/hidden"], check=False)


def test_hidden_topics_and_services_stay_hidden_from_ros(ros, glob_client, hidden_things):
    """Nothing reaches ROS or comes back from it through a refused name."""
    glob_client.request({"op": "subscribe", "topic": "/sec/hidden/pose", "id": "s"})
    assert glob_client.request({"op": "call_service", "service": "/sec/hidden/reset", "id": "c"})
    glob_client.request(
        {
            "op": "call_service",
            "service": "/rosapi/set_param",
            "id": "p",
            "args": {"name": "/sec/hidden/gain", "value": "8"},
        }
    )
    assert ping(glob_client)  # no publish frame of the hidden topic came in between
    assert hidden_things == [] and ros.run(["rosparam", "get", "/sec/hidden/gain"]).stdout.strip() == "7"


@pytest.mark.parametrize(
    "service, args",
    [
        ("/rosapi/topics", {}),
        ("/rosapi/topics_and_raw_types", {}),
        ("/rosapi/topics_for_type", {"type": "std_msgs/String"}),
        ("/rosapi/topic_type", {"topic": "/sec/hidden/pose"}),
        ("/rosapi/publishers", {"topic": "/sec/hidden/pose"}),
        ("/rosapi/services", {}),
        ("/rosapi/services_for_type", {"type": "std_srvs/Empty"}),
        ("/rosapi/service_type", {"service": "/sec/hidden/reset"}),
        ("/rosapi/service_providers", {"service": "/sec/hidden/reset"}),
        ("/rosapi/service_node", {"service": "/sec/hidden/reset"}),
        ("/rosapi/service_host", {"service": "/sec/hidden/reset"}),
        ("/rosapi/get_param_names", {}),
        ("/rosapi/has_param", {"name": "/sec/hidden/gain"}),
        ("/rosapi/search_param", {"name": "gain"}),
        ("/rosapi/search_param", {"name": "/sec/hidden/gain"}),
        ("/rosapi/get_param", {"name": "/"}),
        ("/rosapi/get_param", {"name": "/sec"}),
        ("/rosapi/get_param", {"name": "sec/hidden/gain"}),
    ],
)
def test_rosapi_answers_never_show_hidden_names(glob_client, hidden_things, service, args):
    """Either refused (the error may repeat the name asked for) or answered without a trace of /sec/hidden."""
    reply = glob_client.request({"op": "call_service", "service": service, "args": args, "id": service})
    assert reply["op"] == "service_response", reply
    if reply["result"]:
        assert "hidden" not in json.dumps(reply["values"]) and reply["values"] != {"exists": True}, reply


def test_node_details_hide_what_the_node_does_on_hidden_names(glob_client, hidden_things, node):
    reply = glob_client.request(
        {"op": "call_service", "service": "/rosapi/node_details", "id": "n", "args": {"node": node.get_name()}}
    )
    assert reply["result"], reply
    assert "/sec/hidden" not in json.dumps(reply["values"]), reply


def test_open_names_still_work(node, glob_client):
    from std_msgs.msg import String

    got = []
    sub = node.Subscriber("/sec/open/cmd", String, lambda m: got.append(m.data))
    try:
        glob_client.send({"op": "advertise", "topic": "/sec/open/cmd", "type": "std_msgs/String"})

        def delivered():
            glob_client.send({"op": "publish", "topic": "/sec/open/cmd", "msg": {"data": "open"}})
            return got

        assert wait_for(delivered, 20, interval=0.2, what="the open topic in rospy")[0] == "open"
    finally:
        sub.unregister()


# ---- authentication ---------------------------------------------------------------------------------------
def mac_for(secret, client, dest, rand, t, level, end):
    """rosauth's MAC: sha512 hex of secret, client, dest, rand, t (whole seconds), level, end (whole seconds)."""
    return hashlib.sha512(f"{secret}{client}{dest}{rand}{int(t)}{level}{int(end)}".encode()).hexdigest()


def auth_frame(secret=SECRET, t=None, end=None, rand="r4nd0m", **changes):
    t = time.time() if t is None else t
    end = t + 60 if end is None else end
    frame = {
        "op": "auth",
        "client": "127.0.0.1",
        "dest": "127.0.0.1",
        "rand": rand,
        "t": t,
        "level": "admin",
        "end": end,
    }
    frame["mac"] = mac_for(secret, frame["client"], frame["dest"], rand, t, frame["level"], end)
    frame.update(changes)
    return frame


@pytest.fixture(scope="module")
def secret_file():
    path = make_workdir("rosauth") / "secret"
    path.write_text(SECRET + "\n")
    return path


auth_bridge = bridge_fixture("security_auth_bridge", authenticate="true", secret_file=From("secret_file"))
nosecret_bridge = bridge_fixture("security_auth_nosecret_bridge", scope="function", authenticate="true")


@pytest.fixture
def auth_client(auth_bridge):
    client = WsClient(f"ws://127.0.0.1:{auth_bridge}/")
    yield client
    client.close()


GET_TIME = {"op": "call_service", "service": "/rosapi/get_time", "id": "t"}
GET_TIME_TEXT = json.dumps(GET_TIME)


def not_executed(client, frame=GET_TIME):
    reply = client.request(frame)
    return reply["op"] == "status" and reply["level"] == "error" and "not authenticated" in reply["msg"]


@pytest.mark.parametrize(
    "frame",
    [  # besides subscribe and rosapi calls, in test_bridge_launch_args.py
        {"op": "publish", "topic": "/sec/cmd", "msg": {}, "id": "t"},
        {"op": "advertise_service", "service": "/sec/offer", "type": "std_srvs/Empty", "id": "t"},
        {"op": "set_level", "level": "info", "id": "t"},
        # wrapped ops: a fragment or png must not smuggle a request past authentication
        {"op": "fragment", "id": "t", "data": GET_TIME_TEXT, "num": 0, "total": 1},
        {"op": "png", "id": "t", "data": "iVBORw0KGgo="},
    ],
    ids=lambda frame: frame["op"],
)
def test_every_op_before_auth_is_refused(auth_client, frame):
    assert not_executed(auth_client, frame)
    assert not_executed(auth_client)


# The auth frames below are made when the test runs, not when it is collected: made earlier, their `t` would be
# out of the bridge's auth_time_delta by then, and a frame refused for its time proves nothing about its flaw.
@pytest.mark.parametrize(
    "make_text",
    [
        lambda: (
            "x" + json.dumps(auth_frame())
        ),  # junk before the JSON (the reference then runs the next ops unauthenticated)
        lambda: json.dumps(auth_frame())[:-1],
        lambda: json.dumps([auth_frame()]),
    ],
    ids=["junk before", "cut short", "in a list"],
)
def test_junk_around_auth_is_not_authentication(auth_client, make_text):
    auth_client.send(make_text())
    assert not_executed(auth_client)


def test_binary_auth_is_not_authentication(auth_client):
    auth_client.send(json.dumps(auth_frame()).encode())
    assert not_executed(auth_client)


@pytest.mark.parametrize(
    "name, make_frame",
    [
        pytest.param(name, make, id=name)
        for name, make in [
            ("missing mac", lambda: {k: v for k, v in auth_frame().items() if k != "mac"}),
            ("missing t", lambda: {k: v for k, v in auth_frame().items() if k != "t"}),
            ("missing end", lambda: {k: v for k, v in auth_frame().items() if k != "end"}),
            ("only op", lambda: {"op": "auth"}),
            ("wrong secret", lambda: auth_frame(secret="guess")),
            ("empty mac", lambda: auth_frame(mac="")),
            ("mac as number", lambda: auth_frame(mac=0)),
            ("t an hour ahead", lambda: auth_frame(t=time.time() + 3600)),
            ("t NaN", lambda: {**auth_frame(), "t": float("nan")}),
            ("end Infinity", lambda: {**auth_frame(), "end": float("inf")}),
        ]
    ],
)
def test_bad_auth_is_refused_and_the_socket_closed(auth_client, name, make_frame):
    auth_client.send(json.dumps(make_frame()))
    reply = auth_client.recv()
    assert reply is not None and reply["op"] == "status" and reply["level"] == "error", (name, reply)
    assert auth_client.is_closed(), name


def test_a_replayed_mac_is_refused_once_its_time_window_is_over(auth_bridge):
    """rosauth has no nonce store: a captured MAC works again only while |t - now| < auth_time_delta (5 s by
    default); after that it is refused."""
    frame = auth_frame()
    first = WsClient(f"ws://127.0.0.1:{auth_bridge}/")
    first.send(frame)
    assert first.request(GET_TIME)["result"] is True
    first.close()
    time.sleep(max(0.0, frame["t"] + 5.5 - time.time()))
    replay = WsClient(f"ws://127.0.0.1:{auth_bridge}/")
    replay.send(frame)
    assert replay.recv()["level"] == "error"
    assert replay.is_closed()


def auth_query(frame):
    return urllib.parse.urlencode(
        {name: frame[name] for name in ("mac", "client", "dest", "rand", "t", "level", "end")}
    )


def test_a_query_string_whose_t_lies_ahead_counts_that_within_its_window(auth_bridge):
    """A URL (logs, histories and Referer headers keep it) is valid auth_time_delta (5 s) in all: from its t, or
    from its first use when its t lay ahead of the bridge's clock. Before: t 4 s ahead kept it valid 9 s (up to
    10). The websocket `auth` op keeps rosauth's rule, |t - now| < auth_time_delta, as the reference's clients
    expect (a frame inside the connection, not a URL)."""
    frame = auth_frame(t=time.time() + 4)
    url = f"http://127.0.0.1:{auth_bridge}/streams?format=json&{auth_query(frame)}"
    first_use = time.time()
    assert http(url)[0] == 200
    time.sleep(max(0.0, first_use + 5.3 - time.time()))
    assert http(url)[0] == 401
    op = WsClient(f"ws://127.0.0.1:{auth_bridge}/")
    op.send(frame)
    assert op.request(GET_TIME)["result"] is True
    op.close()


def test_without_a_secret_nobody_gets_in(nosecret_bridge):
    client = WsClient(f"ws://127.0.0.1:{nosecret_bridge}/")
    client.send(auth_frame(secret=""))
    assert client.recv()["level"] == "error" and client.is_closed()


# ---- TLS --------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def tls_folder():
    """A self-signed certificate for localhost (cert.pem) and its key (key.pem)."""
    folder = make_workdir("tls")
    cert, key = folder / "cert.pem", folder / "key.pem"
    subprocess.run(
        [
            "openssl",
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-subj",
            "/CN=localhost",
            "-addext",
            "subjectAltName=DNS:localhost,IP:127.0.0.1",
            "-days",
            "1",
            "-keyout",
            str(key),
            "-out",
            str(cert),
        ],
        check=True,
        capture_output=True,
    )
    return folder


tls_bridge = bridge_fixture(
    "security_tls_bridge", ssl="true", certfile=From("tls_folder", "cert.pem"), keyfile=From("tls_folder", "key.pem")
)


def test_wss_refuses_an_untrusted_certificate(tls_bridge):
    port = tls_bridge
    with pytest.raises(ssl.SSLError):
        WsClient(f"wss://127.0.0.1:{port}/")


def test_roslibpy_over_wss(tls_bridge):
    """roslibpy 2.1.0 (autobahn + twisted) connects with is_secure=True; it does not verify the certificate."""
    port = tls_bridge
    ros = roslibpy.Ros(host="127.0.0.1", port=port, is_secure=True)
    ros.run(timeout=20)
    try:
        reply = roslibpy.Service(ros, "/rosapi/get_time", "rosapi/GetTime").call(roslibpy.ServiceRequest(), timeout=20)
        assert reply["time"]["secs"] > 0
    finally:
        ros.close()


def test_plain_ws_to_the_tls_port_fails(tls_bridge):
    port = tls_bridge
    with pytest.raises(Exception) as error:
        WsClient(f"ws://127.0.0.1:{port}/", timeout=10)
    assert not isinstance(error.value, AssertionError)


# ---- message size -----------------------------------------------------------------------------------------
def test_a_frame_over_max_message_size_gets_an_error_and_the_connection_goes_on(default_bridge):
    client = WsClient(f"ws://127.0.0.1:{default_bridge}/")
    try:
        client.send(json.dumps({"op": "publish", "topic": "/sec/big", "msg": {"data": "z" * 9_000_000}}))
        reply = client.recv(timeout=30)
        assert reply["op"] == "status" and reply["level"] == "error" and "max_message_size" in reply["msg"]
        assert ping(client)
        # the same size in fragments is refused too, and the connection still works
        text = json.dumps({"op": "publish", "topic": "/sec/big", "msg": {"data": "z" * 9_000_000}, "id": "big"})
        step = 1_000_000
        parts = [text[i : i + step] for i in range(0, len(text), step)]
        for num, part in enumerate(parts):
            client.send({"op": "fragment", "id": "big", "data": part, "num": num, "total": len(parts)})
        reply = client.recv_op("status", timeout=30)
        assert reply["level"] == "error" and "max_message_size" in reply["msg"]
        assert ping(client)
    finally:
        client.close()


# ---- HTTP bounds: request bodies, connections per address ------------------------------------------------------
def post_head(path, length, host="localhost"):
    return (
        f"POST {path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\nContent-Length: {length}\r\n\r\n"
    ).encode()


def answer_head(sock, timeout):
    """What the bridge answers on sock within timeout seconds (its head, some of its text), or b"" if nothing."""
    sock.settimeout(timeout)
    try:
        return sock.recv(1000)
    except OSError:
        return b""


def test_a_body_larger_than_any_endpoint_takes_is_refused_at_its_headers_and_never_kept(ros, default_bridge):
    """Before: bodies of up to 100 MB were read whole before any check, with no time limit (six stalled POSTs of 95
    MB to a name not the bridge's held 600 MB); here five of 20 MB each took 100 MB."""
    stat = ProcStat(node_pid(ros, "/security_default_origin_bridge"))
    rss_before = stat.rss_mb()
    stat.reset_peak_rss()
    stalled = []
    for path, host in [("/bags/record", "localhost"), ("/nothing", "evil.example"), ("/", "localhost")] * 2:
        sock = socket.create_connection(("127.0.0.1", default_bridge), timeout=10)
        stalled.append(sock)
        try:
            sock.sendall(post_head(path, 100_000_000, host) + bytes(20_000_000))
        except OSError:  # (the bridge closed it, once it had dropped what came for a while)
            pass
    time.sleep(1)
    assert stat.peak_rss_mb() - rss_before < 20, f"the bridge grew {stat.peak_rss_mb() - rss_before:.0f} MB"
    with socket.create_connection(("127.0.0.1", default_bridge), timeout=10) as sock:
        sock.sendall(post_head("/bags/record", 10_000_000) + bytes(65536))
        answer = answer_head(sock, 2)  # (at once: before, it waited for the rest of the body)
    assert answer.startswith(b"HTTP/1.1 413") and b"at most 65536" in answer, answer
    # a client that sends the whole body before it reads (as Python's do) reads the answer too
    status, answer = urllib_post(default_bridge, "/bags/record", bytes(10_000_000))
    assert status == 413 and "request body too large: 10000000 bytes" in answer, (status, answer)
    for sock in stalled:
        sock.close()


@pytest.mark.parametrize("chunk", [4096, 1_000_000], ids=["many-chunks", "one-big-chunk"])
def test_a_chunked_body_larger_than_any_endpoint_takes_is_refused_with_a_413_naming_the_bound(default_bridge, chunk):
    """A body sent in chunks has no Content-Length to refuse at its headers: it is refused once past the bound,
    as one with a Content-Length is (before: Tornado's bare "400 Bad Request", no text), and a chunked body within
    the bound is still taken."""
    head = (
        b"POST /bags/record HTTP/1.1\r\nHost: localhost\r\nContent-Type: application/json\r\n"
        b"Transfer-Encoding: chunked\r\n\r\n"
    )
    with socket.create_connection(("127.0.0.1", default_bridge), timeout=10) as sock:
        sock.sendall(head)
        try:
            for _ in range(200_000 // chunk + 1):
                sock.sendall(f"{chunk:x}\r\n".encode() + b" " * chunk + b"\r\n")
        except OSError:  # (refused and closed meanwhile)
            pass
        answer = answer_head(sock, 5)
    assert answer.startswith(b"HTTP/1.1 413") and b"at most 65536" in answer, answer
    with socket.create_connection(("127.0.0.1", default_bridge), timeout=10) as sock:
        body = b'{"topics": 1}'
        sock.sendall(head + f"{len(body):x}\r\n".encode() + body + b"\r\n0\r\n\r\n")
        answer = answer_head(sock, 5)
    assert answer.startswith(b"HTTP/1.1 404") and b"bag recorder is off" in answer, answer  # (the endpoint's)


def urllib_post(port, path, data):
    request = urllib.request.Request(
        f"http://127.0.0.1:{port}{path}", data=data, headers={"Content-Type": "application/json"}
    )
    try:
        with urllib.request.urlopen(request, timeout=20) as answer:
            return answer.status, answer.read().decode()
    except urllib.error.HTTPError as error:
        return error.code, error.read().decode()


fds_bridge = bridge_fixture("security_fds_bridge", scope="function", max_fds=256)


def test_stalled_bodies_from_one_address_leave_the_descriptors_to_others(fds_bridge):
    """Under `ulimit -n 256`, 300 POSTs from 127.0.0.1 whose bodies never come: before, they took every descriptor
    and a client from another address waited in vain (and the stalled ones were never closed). Now one address
    holds a quarter of the descriptors at most (48 here; 503 beyond), and a body must come within 10 s."""
    port, stalled = fds_bridge, []
    try:
        for _ in range(300):
            try:
                sock = socket.create_connection(("127.0.0.1", port), timeout=3)
                sock.sendall(post_head("/bags/record", 10) + b"{")
            except OSError:
                break
            stalled.append(sock)
        started = time.monotonic()
        with socket.create_connection(("127.0.0.1", port), timeout=5, source_address=("127.0.0.2", 0)) as other:
            other.sendall(b"GET /bags HTTP/1.1\r\nHost: localhost\r\n\r\n")
            assert answer_head(other, 5).startswith(b"HTTP/1.1 404"), "the other address was not served"
        assert time.monotonic() - started < 2
        answers = [answer_head(sock, 0.2) for sock in stalled[-100:]]
        assert all(
            answer.startswith(b"HTTP/1.1 503") and b"max_connections_per_address" in answer for answer in answers
        ), answers[:3]
        stalled[0].settimeout(15)
        assert stalled[0].recv(100) == b""  # closed, its body late (a timeout would raise)
    finally:
        for sock in stalled:
            sock.close()
