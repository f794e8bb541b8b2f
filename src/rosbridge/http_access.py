"""Who may use the bridge's HTTP endpoints beside the websocket (the camera streams, the bags): the same rules as
the websocket. A request from a web page (an Origin header) must come from a page allowed_origins allows; with
`authenticate`, the rosauth fields (as the `auth` op has them) come as query parameters."""
import time

import tornado.web

from rosbridge.auth import mac_is_valid
from rosbridge.origins import origin_allowed
from rosbridge.pages import SECURITY_HEADERS

AUTH_FIELDS = ("mac", "client", "dest", "rand", "t", "level", "end")


def query_text(args, name):
    """The last value of query parameter `name` (Tornado's query_arguments), or None."""
    values = args.get(name)
    return values[-1].decode("utf-8", "replace").strip() if values else None


def refusal(bridge, request, what):
    """(status, text) if `request` (a tornado HTTPServerRequest for `what`, e.g. "a camera stream") is refused by
    the origin rules or authentication, else None."""
    origin = request.headers.get("Origin")
    if origin is not None:
        same_origin = origin.lower().partition("://")[2] == request.host.lower()
        if not origin_allowed(origin, same_origin, request.remote_ip, bridge.allowed_origins):
            bridge.log_refusal((what, origin), f"Refused {what} requested by the web page at origin {origin} "
                               f"(browser at {request.remote_ip}); allowed_origins decides, as for the websocket")
            return 403, (f"Cross origin requests not allowed: the web page at {origin} may not use this bridge "
                         "(allowed_origins)")
    config = bridge.config
    if config.authenticate:
        text = _auth_refusal(request.query_arguments, config)
        if text is not None:
            return 401, text
    return None


def _auth_refusal(args, config):
    missing = [name for name in AUTH_FIELDS if not query_text(args, name)]
    if missing:
        return ("authentication required: this bridge runs with authenticate on; give the rosauth fields as "
                f"query parameters ({', '.join(AUTH_FIELDS)}); missing: {', '.join(missing)}")
    auth = {name: query_text(args, name) for name in AUTH_FIELDS}
    try:
        auth["t"], auth["end"] = float(auth["t"]), float(auth["end"])
    except ValueError:
        return "authentication failed: t and end must be numbers"
    if not mac_is_valid(auth, config.auth_secret, time.time(), config.auth_time_delta):
        return "authentication failed (bad MAC, or t/end out of time)"
    return None


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
