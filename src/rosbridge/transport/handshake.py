"""The websocket's opening handshake on "/" (RFC 6455 4.2): BridgeSocket checks the request (its headers, the web
page it comes from, the room left for clients), chooses the protocol by the subprotocol the client offers
(rosbridge by default, Foxglove's for foxglove.websocket.v1 / foxglove.sdk.v1), answers 101 and hands the socket to
a ClientConnection (connection.py). A plain GET or HEAD of "/" gets the page (index.html) instead."""

import json

import tornado.iostream
import tornado.web

from rosbridge.foxglove import SUBPROTOCOLS
from rosbridge.origins import SECURITY_HEADERS, origin_allowed
from rosbridge.transport import rfc6455 as ws
from rosbridge.transport.connection import ClientConnection


class BridgeSocket(tornado.web.RequestHandler):
    """GET / : the websocket handshake of a rosbridge client, or else (a plain GET or HEAD) the index page."""

    def initialize(self, bridge, index_page=None):
        self.bridge, self.index_page = bridge, index_page

    def set_default_headers(self):
        for name, value in SECURITY_HEADERS.items():
            self.set_header(name, value)

    def get(self):
        headers = self.request.headers
        if headers.get("Upgrade", "").lower() != "websocket":
            if self.index_page is None:
                raise tornado.web.HTTPError(404)
            self.set_header("Content-Type", "text/html; charset=UTF-8")
            self.finish(self.index_page.read_bytes())
            return
        refusal = ws.handshake_error(headers) or self._policy_refusal(headers.get("Origin"))
        if refusal is not None:
            status, text = refusal
            self.set_status(status)
            if status == 426:
                self.set_header("Sec-WebSocket-Version", "13")
            self.finish(text)
            return
        extensions, window_bits = None, None
        if self.bridge.settings.use_compression or self.bridge.settings.compress_slow_links:
            extensions, window_bits = ws.negotiate_deflate(headers.get("Sec-WebSocket-Extensions", ""))
        subprotocol = ws.choose_subprotocol(headers.get("Sec-WebSocket-Protocol", ""), SUBPROTOCOLS)
        answer = [
            "HTTP/1.1 101 Switching Protocols",
            "Upgrade: websocket",
            "Connection: Upgrade",
            "Sec-WebSocket-Accept: " + ws.accept_key(headers["Sec-WebSocket-Key"]),
        ]
        if extensions:
            answer.append("Sec-WebSocket-Extensions: " + extensions)
        if subprotocol is not None:
            answer.append("Sec-WebSocket-Protocol: " + subprotocol)
        handshake = ("\r\n".join(answer) + "\r\n\r\n").encode()
        if subprotocol is not None and self.bridge.settings.authenticate:
            self._refuse_unauthenticated(handshake)
            return
        connection = ClientConnection(self.bridge, self.detach(), self.request.remote_ip, window_bits, subprotocol)
        connection.start(handshake)

    def _refuse_unauthenticated(self, handshake):
        """The Foxglove protocol has no way to authenticate: with authenticate on, its client is told why (a
        status it shows, and the close frame's reason) and the connection ends."""
        reason = "this bridge requires rosauth authentication, which the Foxglove protocol cannot do"
        self.bridge.log_refusal("foxglove auth", f"a Foxglove client refused: {reason}")
        status = json.dumps({"op": "status", "level": 2, "message": reason}).encode()
        stream = self.detach()
        try:
            stream.write(handshake + ws.frame_header(len(status), ws.TEXT) + status + ws.close_frame(ws.POLICY, reason))
            stream.close()
        except tornado.iostream.StreamClosedError:
            pass

    def head(self):
        if self.index_page is None:
            raise tornado.web.HTTPError(404)
        self.set_header("Content-Type", "text/html; charset=UTF-8")
        self.set_header("Content-Length", self.index_page.stat().st_size)
        self.finish()

    def _policy_refusal(self, origin):
        """(status, text) if the bridge turns this client away: a web page it does not allow, or too many. With
        authenticate, a client that has waited longest without authenticating makes room for a new one (a place
        kept by an idle socket is the first to go; none lives past protocol.AUTH_TIMEOUT anyway)."""
        bridge, peer = self.bridge, self.request.remote_ip
        if origin is not None and not origin_allowed(
            origin, self.request.host, peer, bridge.allowed_origins, bridge.allowed_hosts
        ):
            bridge.refused_origin(origin, peer)
            return 403, "Cross origin websockets not allowed"
        if len(bridge.clients) >= bridge.settings.max_clients:
            idle = min(
                (client for client in bridge.clients if client.unauthenticated_since is not None),
                key=lambda client: client.unauthenticated_since,
                default=None,
            )
            if idle is not None:
                bridge.log_refusal(
                    "max_clients auth",
                    "a client that had not authenticated closed, making room "
                    f"for a new one (max_clients {bridge.settings.max_clients})",
                )
                idle.drop(ws.TRY_AGAIN, "making room for another client: authenticate sooner")
                return None
            bridge.log_refusal(
                "max_clients",
                f"a client refused: {len(bridge.clients)} connected (max_clients {bridge.settings.max_clients})",
            )
            return 503, "too many clients"
        return None
