"""Which web pages may open a websocket: the browser sends the page's origin, and a robot on a network must not
be driven by whatever site its user happens to browse. Clients that send no Origin are not browsers."""
import fnmatch
import ipaddress
import socket
import urllib.parse


def origin_allowed(origin, same_origin, peer, patterns):
    """Whether a browser page of `origin` may open a websocket (clients that send no Origin are not browsers
    and are not asked). `same_origin`: the page came from this bridge (its Host); `peer`: the browser's address;
    `patterns`: the allowed_origins launch arg, None when empty.

    The bridge's own page, reached by a name of this machine, is always allowed. Otherwise allowed_origins
    decides when it is set; by default pages of this machine on any port (by localhost, its name or one of its
    addresses: a DNS-rebinding name is refused), and pages opened from disk (Origin "null") when the browser
    runs on this machine (README, Security: a sandboxed frame sends "null" too)."""
    origin = origin.lower()
    try:
        url = urllib.parse.urlsplit(origin)
    except ValueError:  # e.g. an unbalanced "[": no page has that origin
        return False
    if same_origin and is_this_machine(url.hostname or ""):
        return True
    if patterns is not None:
        return any(fnmatch.fnmatchcase(origin, pattern.lower()) for pattern in patterns)
    if origin == "null":
        return is_this_machine(peer)
    return url.scheme in ("http", "https") and is_this_machine(url.hostname or "")


def is_this_machine(host):
    """localhost, this machine's host name, or one of its addresses (loopback included)."""
    if host in ("localhost", socket.gethostname().lower()):
        return True
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        return False
    address = getattr(address, "ipv4_mapped", None) or address  # ::ffff:a.b.c.d from a dual-stack socket
    if address.is_loopback:
        return True
    family = socket.AF_INET if address.version == 4 else socket.AF_INET6
    with socket.socket(family, socket.SOCK_DGRAM) as probe:
        try:
            probe.bind((str(address), 0))  # only this machine's own addresses can be bound
        except OSError:
            return False
    return True
