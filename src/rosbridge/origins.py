"""Who may use the bridge from a browser, against pages of other sites and DNS rebinding (a site whose name the
attacker's DNS re-points at this machine: the browser then sends the site's requests here, as to the site itself).

- Host: every request (HTTP or a websocket's handshake) must be addressed to this bridge: a name or address of
  this machine, a name allowed_hosts allows (a reverse proxy's public name), or the site of a page allowed_origins
  allows. Browsers always send Host, the name in the page's address; a request without one (an HTTP/1.0 script)
  is no browser's, and Tornado takes it as addressed to 127.0.0.1.
- Origin: browsers send the page's origin with a websocket and a cross-site request, and a robot on a network
  must not be driven by whatever site its user happens to browse. Clients that send no Origin are not browsers."""

import fnmatch
import functools
import ipaddress
import os
import re
import socket
import urllib.parse

NAME = re.compile(r"[a-z0-9_-]+(\.[a-z0-9_-]+)*")  # a host name (or an IPv4 address), lowercase: no empty label
# Headers on every page and answer the bridge serves: no MIME sniffing, and no other site may frame it
# (clickjacking: a hidden frame over the Stop button).
SECURITY_HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
    "Content-Security-Policy": "frame-ancestors 'none'",
}
HOST = re.compile(r"(\[[0-9a-f:.]+\]|[a-z0-9_.-]+)(:[0-9]*)?")  # a name or address (IPv6 in brackets), a port


def host_name(host):
    """The name or address a Host header names, lowercase, without port, brackets or a final dot
    ("Robots.Example.:8443" -> "robots.example", "[::1]:9090" -> "::1"); None when it is not a host."""
    match = HOST.fullmatch(host.lower())
    if not match:
        return None
    name = match[1].strip("[]")
    name = name[:-1] if name.endswith(".") else name
    return name if match[1].startswith("[") or NAME.fullmatch(name) else None


def host_allowed(host, patterns, host_patterns):
    """Whether a request whose Host header is `host` is addressed to this bridge: this machine (is_this_machine), a
    host `host_patterns` (allowed_hosts: its name, or name:port) allow, or a page's site that `patterns`
    (allowed_origins, over http or https) allow. Patterns: case-insensitive fnmatch, None when the setting is empty."""
    host = host.lower()
    name = host_name(host)
    if name is None:
        return False
    if any(fnmatch.fnmatchcase(text, pattern.lower()) for pattern in host_patterns or () for text in (name, host)):
        return True
    if any(
        fnmatch.fnmatchcase(f"{scheme}://{host}", pattern.lower())
        for pattern in patterns or ()
        for scheme in ("http", "https")
    ):
        return True
    return is_this_machine(name)


def origin_allowed(origin, host, peer, patterns, host_patterns=None):
    """Whether a browser page of `origin` may open a websocket or use an endpoint (clients that send no Origin
    are not browsers and are not asked). `host`: the request's Host; `peer`: the browser's address; `patterns`,
    `host_patterns`: the allowed_origins and allowed_hosts settings, None when empty.

    The bridge's own page (its origin is the request's Host, one host_allowed allows) is always allowed. Otherwise
    allowed_origins decides when it is set; by default pages of this machine on any port (by localhost, its name
    or one of its addresses: a DNS-rebinding name is refused), and pages opened from disk (Origin "null") when the
    browser runs on this machine (README, Security: a sandboxed frame sends "null" too)."""
    origin = origin.lower()
    try:
        url = urllib.parse.urlsplit(origin)
    except ValueError:  # e.g. an unbalanced "[": no page has that origin
        return False
    if origin.partition("://")[2] == host.lower() and host_allowed(host, patterns, host_patterns):
        return True
    if patterns is not None:
        return any(fnmatch.fnmatchcase(origin, pattern.lower()) for pattern in patterns)
    if origin == "null":
        return is_this_machine(peer)
    return url.scheme in ("http", "https") and is_this_machine(url.hostname or "")


def is_this_machine(host):
    """localhost and its subdomains (RFC 6761: browsers take them as loopback), this machine's names (own_names),
    or one of its own unicast addresses (loopback included). `host`: lowercase."""
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        name = host[:-1] if host.endswith(".") else host
        return bool(NAME.fullmatch(name)) and (
            name == "localhost" or name.endswith(".localhost") or name in own_names()
        )
    address = getattr(address, "ipv4_mapped", None) or address  # ::ffff:a.b.c.d from a dual-stack socket
    if address.is_unspecified or address.is_multicast:  # (both bind: "every address", a group)
        return False
    family = socket.AF_INET if address.version == 4 else socket.AF_INET6
    with socket.socket(family, socket.SOCK_DGRAM) as probe:
        try:
            if not address.is_loopback:
                probe.bind((str(address), 0))  # only this machine's own addresses can be bound
            probe.connect((str(address), 9))  # (sends nothing) a broadcast address refuses it: EACCES
        except OSError:
            return False
    return True


def own_names():
    """This machine's names, lowercase: its host name and that name's first label, the first label in .local (mDNS:
    a Raspberry Pi is reached as raspberrypi.local), its fully qualified name, and ROS_HOSTNAME and ROS_IP."""
    name = socket.gethostname().lower()
    short = name.partition(".")[0]
    names = {
        name,
        short,
        short + ".local",
        _fully_qualified(name),
        *(os.environ.get(variable, "").lower().rstrip(".") for variable in ("ROS_HOSTNAME", "ROS_IP")),
    }
    names.discard("")
    return names


@functools.lru_cache(maxsize=4)
def _fully_qualified(name):
    return socket.getfqdn(name).lower()  # the resolver's answer, asked once (a slow DNS must not hold requests)
