"""The bridge's default origin policy (which browser pages may open a websocket), as a pure function."""
import socket

import pytest

from rosbridge.origins import is_this_machine, origin_allowed

HOSTNAME = socket.gethostname().lower()
LOCAL, REMOTE = "127.0.0.1", "192.0.2.7"  # browsers' addresses (192.0.2.0/24 is reserved for documentation)


@pytest.mark.parametrize("origin, peer", [
    ("http://localhost:8765", LOCAL),  # the tutorial's page served from another port
    ("http://127.0.0.1:8000", LOCAL),
    ("http://[::1]:8000", LOCAL),
    (f"http://{HOSTNAME}:3000", REMOTE),
    ("HTTPS://LOCALHOST", LOCAL),
    ("null", LOCAL),  # the tutorial's page opened from disk in a browser on this machine
    ("null", "::ffff:127.0.0.1"),
])
def test_by_default_this_machines_pages_on_any_port_and_from_disk_connect(origin, peer):
    assert origin_allowed(origin, False, peer, None)


@pytest.mark.parametrize("origin, peer, same_origin", [
    ("null", REMOTE, False),  # from disk on another machine, or a sandboxed frame there
    ("http://192.0.2.7:8000", REMOTE, False),  # a page of another machine
    ("http://evil.example", LOCAL, False),
    ("http://rebind.example:9090", LOCAL, True),  # DNS rebinding: same origin as the socket, by a foreign name
    ("http://localhost.evil.example", LOCAL, False),
    ("ftp://localhost", LOCAL, False),
    ("file://", LOCAL, False),
    ("http://[::1", LOCAL, False),
    ("", LOCAL, False),
])
def test_by_default_other_pages_are_refused(origin, peer, same_origin):
    assert not origin_allowed(origin, same_origin, peer, None)


def test_with_allowed_origins_the_list_decides_but_the_bridges_own_page_stays_allowed():
    patterns = ["http://*.lan:*"]
    assert origin_allowed("http://laptop.lan:8080", False, REMOTE, patterns)
    assert origin_allowed("http://127.0.0.1:9090", True, REMOTE, patterns)  # the page the bridge serves
    assert not origin_allowed("http://localhost:8765", False, LOCAL, patterns)
    assert not origin_allowed("null", False, LOCAL, patterns)
    assert origin_allowed("null", False, REMOTE, ["null"])
    assert not origin_allowed("http://rebind.example:9090", True, LOCAL, patterns)


def test_this_machine_is_localhost_its_name_and_its_addresses():
    assert all(map(is_this_machine, ["localhost", HOSTNAME, "127.0.0.1", "127.3.4.5", "::1"]))
    assert not any(map(is_this_machine, ["192.0.2.7", "2001:db8::1", "localhost.evil.example", ""]))
