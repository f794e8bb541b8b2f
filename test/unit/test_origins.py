"""The bridge's origin and Host policy (which browser pages may open a websocket, which names a request may be
addressed to), as pure functions."""

import socket
import subprocess

import pytest

from rosbridge.origins import host_allowed, host_name, is_this_machine, origin_allowed

HOSTNAME = socket.gethostname().lower()
LOCAL, REMOTE = "127.0.0.1", "192.0.2.7"  # browsers' addresses (192.0.2.0/24 is reserved for documentation)
BRIDGE = "127.0.0.1:9090"  # the Host of a request to the bridge by its address


@pytest.mark.parametrize(
    "origin, peer",
    [
        ("http://localhost:8765", LOCAL),  # the tutorial's page served from another port
        ("http://127.0.0.1:8000", LOCAL),
        ("http://[::1]:8000", LOCAL),
        (f"http://{HOSTNAME}:3000", REMOTE),
        ("HTTPS://LOCALHOST", LOCAL),
        ("null", LOCAL),  # the tutorial's page opened from disk in a browser on this machine
        ("null", "::ffff:127.0.0.1"),
    ],
)
def test_by_default_this_machines_pages_on_any_port_and_from_disk_connect(origin, peer):
    assert origin_allowed(origin, BRIDGE, peer, None)


@pytest.mark.parametrize(
    "origin, peer, host",
    [
        ("null", REMOTE, BRIDGE),  # from disk on another machine, or a sandboxed frame there
        ("http://192.0.2.7:8000", REMOTE, BRIDGE),  # a page of another machine
        ("http://evil.example", LOCAL, BRIDGE),
        ("http://rebind.example:9090", LOCAL, "rebind.example:9090"),  # DNS rebinding: same origin, a foreign name
        ("http://localhost.evil.example", LOCAL, BRIDGE),
        ("ftp://localhost", LOCAL, BRIDGE),
        ("file://", LOCAL, BRIDGE),
        ("http://[::1", LOCAL, BRIDGE),
        ("", LOCAL, BRIDGE),
    ],
)
def test_by_default_other_pages_are_refused(origin, peer, host):
    assert not origin_allowed(origin, host, peer, None)


def test_with_allowed_origins_the_list_decides_but_the_bridges_own_page_stays_allowed():
    patterns = ["http://*.lan:*"]
    assert origin_allowed("http://laptop.lan:8080", BRIDGE, REMOTE, patterns)
    assert origin_allowed("http://127.0.0.1:9090", BRIDGE, REMOTE, patterns)  # the page the bridge serves
    assert not origin_allowed("http://localhost:8765", BRIDGE, LOCAL, patterns)
    assert not origin_allowed("null", BRIDGE, LOCAL, patterns)
    assert origin_allowed("null", BRIDGE, REMOTE, ["null"])
    assert not origin_allowed("http://rebind.example:9090", "rebind.example:9090", LOCAL, patterns)


def test_the_bridges_own_page_behind_a_proxy_that_passes_its_name_on_is_allowed_by_allowed_hosts():
    host = "robots.example"
    assert origin_allowed(f"https://{host}", host, REMOTE, None, ["robots.example"])
    assert not origin_allowed(f"https://{host}", host, REMOTE, None, None)
    assert not origin_allowed("https://evil.example", host, REMOTE, None, ["robots.example"])


def test_this_machine_is_localhost_its_names_and_its_addresses(monkeypatch):
    short = HOSTNAME.partition(".")[0]
    monkeypatch.setenv("ROS_HOSTNAME", "rover.example")
    assert all(
        map(
            is_this_machine,
            [
                "localhost",
                "localhost.",
                "app.localhost",
                HOSTNAME,
                short,
                f"{short}.local",
                socket.getfqdn(HOSTNAME).lower(),
                "rover.example",
                "127.0.0.1",
                "127.3.4.5",
                "::1",
            ],
        )
    )
    assert not any(
        map(
            is_this_machine,
            ["192.0.2.7", "2001:db8::1", "localhost.evil.example", "evil.local", "", f"{short}.local.evil.example"],
        )
    )


@pytest.mark.parametrize(
    "host, name",
    [
        ("Robots.Example.:8443", "robots.example"),
        ("[::1]:9090", "::1"),
        ("[::1]", "::1"),
        ("127.0.0.1", "127.0.0.1"),
        ("localhost:", "localhost"),
        ("", None),
        (".", None),
        ("a b", None),
        ("evil@localhost", None),
        ("[::1", None),
        ("localhost:80.evil", None),
        ("localhost:9090:1", None),
        ("::1", None),
        ("local/host", None),
    ],
)
def test_host_name_is_the_name_of_a_host_header_or_none(host, name):
    assert host_name(host) == name


@pytest.mark.parametrize(
    "host",
    [
        "127.0.0.1:9090",
        "localhost",
        f"{HOSTNAME}:9090",
        "[::1]:9090",
        "app.localhost:3000",
        f"{HOSTNAME.partition('.')[0]}.local",
    ],
)
def test_by_default_requests_to_this_machine_are_allowed(host):
    assert host_allowed(host, None, None)


@pytest.mark.parametrize(
    "host",
    [
        "evil.example:9090",
        "evil.example",
        "192.0.2.7:9090",
        "localhost.evil.example",
        f"{HOSTNAME}.evil.example",
        "127.0.0.1.evil.example",
        "evil@localhost",
        "",
    ],
)
def test_by_default_requests_to_other_names_are_refused(host):
    assert not host_allowed(host, None, None)


def test_allowed_hosts_and_allowed_origins_allow_more_names():
    hosts = ["robots.example", "*.Robots.Lan", "proxy.example:8443"]
    for host in ("robots.example", "ROBOTS.EXAMPLE:443", "rover1.robots.lan", "proxy.example:8443", "localhost"):
        assert host_allowed(host, None, hosts), host
    for host in ("robots.example.evil.example", "robots.lan", "proxy.example", "proxy.example:8444"):
        assert not host_allowed(host, None, hosts), host
    origins = ["https://good.example", "http://*.lan:*"]
    for host in ("good.example", "laptop.lan:8080"):
        assert host_allowed(host, origins, None), host
    for host in ("good.example:8443", "laptop.lan", "evil.example"):
        assert not host_allowed(host, origins, None), host
    assert host_allowed("anything.example:1", None, ["*"])


@pytest.mark.parametrize(
    "host",
    [
        "0.0.0.0",
        "::",
        "0",
        "224.0.0.1",
        "ff02::1",
        "255.255.255.255",
        "127.255.255.255",
        "::ffff:0.0.0.0",
        "::ffff:224.0.0.1",
        "localhost..",
        ".localhost",
        "a..localhost",
        "localhost%00.evil.example",
        "localhost,evil.example",
        "local\u0127host",
        "-",
    ],
)
def test_unspecified_multicast_and_broadcast_addresses_and_malformed_names_are_not_this_machine(host):
    """Each of these binds (0.0.0.0 is every address, 224.0.0.1 a group, 255.255.255.255 a broadcast) or was read as
    localhost once its dots were stripped, yet no page of this machine is addressed by it."""
    assert not is_this_machine(host)
    assert not host_allowed(host if ":" not in host else f"[{host}]", None, None)


def test_the_broadcast_addresses_of_this_machines_networks_are_not_this_machine():
    """They bind like its own addresses (`ip` lists them as brd)."""
    out = subprocess.run(["ip", "-o", "-4", "addr", "show"], capture_output=True, text=True, check=True).stdout
    found = [
        (fields[3].split("/")[0], fields[fields.index("brd") + 1])
        for fields in map(str.split, out.splitlines())
        if "brd" in fields
    ]
    if not found:
        pytest.skip("no network with a broadcast address here")
    for own, broadcast in found:
        assert is_this_machine(own) and not is_this_machine(broadcast), (own, broadcast)
