"""Who may use the bridge over HTTP. Every request, the websocket's handshake and the page included, must be
addressed to this bridge by its Host (host_checked: against DNS rebinding). The endpoints beside the websocket (the
camera streams, the bags, the clouds) then have the websocket's rules: a request from a web page (an Origin
header) must come from a page allowed_origins allows; with `authenticate`, the rosauth fields (as the `auth` op has
them) come as query parameters."""

import time

import tornado.routing
import tornado.web

from rosbridge.origins import SECURITY_HEADERS, host_allowed, host_name, origin_allowed, own_names

AUTH_FIELDS = ("mac", "client", "dest", "rand", "t", "level", "end")


def query_text(args, name):
    """The last value of query parameter `name` (Tornado's query_arguments), or None."""
    values = args.get(name)
    return values[-1].decode("utf-8", "replace").strip() if values else None


def refusal(bridge, request, what):
    """(status, text) if `request` (a tornado HTTPServerRequest for `what`, e.g. "a camera stream") is refused by
    the origin rules or authentication, else None."""
    origin = request.headers.get("Origin")
    if origin is not None and not origin_allowed(
        origin, request.host, request.remote_ip, bridge.allowed_origins, bridge.allowed_hosts
    ):
        bridge.log_refusal(
            (what, origin),
            f"Refused {what} requested by the web page at origin {origin} "
            f"(browser at {request.remote_ip}); allowed_origins decides, as for the websocket",
        )
        return 403, (
            f"Cross origin requests not allowed: the web page at {origin} may not use this bridge (allowed_origins)"
        )
    config = bridge.config
    if config.authenticate:
        text = _auth_refusal(request.query_arguments, config, bridge.url_macs)
        if text is not None:
            return 401, text
    return None


def _auth_refusal(args, config, url_macs):
    missing = [name for name in AUTH_FIELDS if not query_text(args, name)]
    if missing:
        return (
            "authentication required: this bridge runs with authenticate on; give the rosauth fields as "
            f"query parameters ({', '.join(AUTH_FIELDS)}); missing: {', '.join(missing)}"
        )
    auth = {name: query_text(args, name) for name in AUTH_FIELDS}
    try:
        auth["t"], auth["end"] = float(auth["t"]), float(auth["end"])
    except ValueError:
        return "authentication failed: t and end must be numbers"
    if not url_macs.valid(auth, config.auth_secret, time.time()):
        return "authentication failed (bad MAC, or t/end out of time)"
    return None


def host_checked(bridge, table):
    """The route table `table` for the requests addressed to this bridge (origins.host_allowed), and every other
    request refused (MisdirectedRequest)."""
    own_names()  # (this machine's full name is asked of the resolver now, at start, not by the first request)
    return [
        tornado.routing.Rule(_HostMatches(bridge, True), table),
        tornado.routing.Rule(_HostMatches(bridge, False), MisdirectedRequest, {"bridge": bridge}),
    ]


class _HostMatches(tornado.routing.Matcher):
    """The requests whose Host the bridge answers to (allowed True), or the others."""

    def __init__(self, bridge, allowed):
        self.bridge, self.allowed = bridge, allowed

    def match(self, request):
        allowed = host_allowed(request.host, self.bridge.allowed_origins, self.bridge.allowed_hosts)
        return {} if allowed == self.allowed else None


class EndpointHandler(tornado.web.RequestHandler):
    """What the endpoints' handlers share: the page's security headers, answers never cached (CACHE_CONTROL),
    and refusals as plain text."""

    CACHE_CONTROL = "no-store"

    def set_default_headers(self):
        for name, value in SECURITY_HEADERS.items():
            self.set_header(name, value)
        self.set_header("Cache-Control", self.CACHE_CONTROL)

    def compute_etag(self):
        return None  # (every answer is fresh: no hash of it)

    def refuse(self, status, text):
        self.clear()
        self.set_status(status)
        self.set_header("Content-Type", "text/plain; charset=UTF-8")
        if status == 401:
            self.set_header("WWW-Authenticate", 'rosauth realm="rosbridge"')
        self.finish(text + "\n")


class MisdirectedRequest(EndpointHandler):
    """Any request (any method, a websocket's handshake too) addressed to a Host that is not this bridge's."""

    SHOWN = 200  # characters of the Host shown and logged

    def initialize(self, bridge):
        self.bridge = bridge

    def prepare(self):
        request, host, name = self.request, self.request.host[: self.SHOWN], host_name(self.request.host)
        if name is None:
            self.refuse(400, f"Host {host} is not a host name or address (with maybe a port)")
            return
        advice = f'allowed_hosts:="[{", ".join([*(self.bridge.allowed_hosts or []), name[: self.SHOWN]])}]"'
        self.bridge.log_refusal(
            ("host", host),
            f"Refused a request addressed to Host {host} (from "
            f"{request.remote_ip}, for {request.path[: self.SHOWN]}): not a name of this machine "
            "(a DNS-rebinding page re-points a name of its own here), nor one that allowed_hosts "
            "or allowed_origins allows. To allow it, e.g. a reverse proxy's public name: "
            f"roslaunch turtlesim rosbridge_websocket.launch {advice}",
        )
        self.refuse(
            403,
            f"Host {host} is not a name of this bridge's machine: refused (DNS rebinding). If it is a "
            f"name of yours (a reverse proxy's), start the bridge with {advice} (README, Security)",
        )
