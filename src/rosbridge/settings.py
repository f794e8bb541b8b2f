"""Every setting of the bridge, in one table: its name (the launch arg and the node's private parameter), type,
default and meaning. The launch file, `server.main`, `protocol.Config` and the README's table all come from or
are checked against this table (test_settings.py)."""

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Setting:
    name: str
    kind: type  # bool, int, float or str
    default: object
    meaning: str
    ours: bool = False  # not a setting of the ROS 1 rosbridge_server, or a different default
    check: tuple | None = None  # (test, what it asks): a value that fails the test (or a float not finite) is refused


ABOVE_ZERO, NOT_NEGATIVE = (lambda value: value > 0, "above 0"), (lambda value: value >= 0, "0 or more")

SETTINGS = (
    Setting("port", int, 9090, "0 = pick a free port, written to the `~actual_port` param"),
    Setting(
        "foxglove_port",
        int,
        8765,
        "a second port of the same server, for Foxglove WebSocket clients (Lichtblick's default address); every "
        "port speaks both protocols, by the subprotocol a client offers. 0 = a free port (`~actual_foxglove_port`), "
        "-1 = none",
        ours=True,
        check=(lambda value: value >= -1, "-1 or more"),
    ),
    Setting("address", str, "", "interface to bind, e.g. `127.0.0.1`; empty = all interfaces"),
    Setting("ssl", bool, False, "serve `wss://` (and `https://` for the page)"),
    Setting("certfile", str, "", "TLS certificate file, with `ssl`"),
    Setting("keyfile", str, "", "TLS key file, with `ssl`"),
    Setting("authenticate", bool, False, "a valid rosauth `auth` must come first; see Security"),
    Setting("secret_file", str, "", "file holding the rosauth secret, with `authenticate`", ours=True),
    Setting("auth_time_delta", float, 5.0, "seconds `auth`'s `t` may differ from now (negative: no check)", ours=True),
    Setting(
        "fragment_timeout",
        float,
        600.0,
        "seconds to wait for the rest of a fragmented message: a `fragment` op's, or a websocket message's (its "
        "frames, from its first byte: the connection is then closed)",
        check=ABOVE_ZERO,
    ),
    Setting("delay_between_messages", float, 0.0, "seconds between frames sent to one client"),
    Setting(
        "max_message_size",
        int,
        8_000_000,
        "bytes; larger frames get a `status` error; 0 = no limit (the reference has none)",
        ours=True,
    ),
    Setting(
        "max_queue",
        int,
        1000,
        "frames waiting for one slow client before the oldest whole messages are dropped (the client is told)",
        ours=True,
    ),
    Setting("max_clients", int, 1000, "clients connected at once; more get HTTP 503", ours=True),
    Setting(
        "max_connections_per_address",
        int,
        256,
        "connections one address may hold at once (HTTP requests, websockets and streams; at most a quarter of "
        "the file descriptors); more get HTTP 503. Behind a reverse proxy every client comes from its "
        "address: raise it to the proxy's own bound",
        ours=True,
        check=ABOVE_ZERO,
    ),
    Setting(
        "max_frames_per_second",
        int,
        20000,
        "frames one client may send per second (a burst of one second); beyond it its next frames wait "
        "in its socket; 0 = no limit. Clients are served in turns whatever this is. A client that connects "
        "again starts with what its address's last one left",
        ours=True,
    ),
    Setting("max_bytes_per_second", int, 100_000_000, "bytes one client may send per second, likewise", ours=True),
    Setting(
        "max_topics_per_client",
        int,
        200,
        "topics one client may subscribe to, and topics it may advertise (each)",
        ours=True,
    ),
    Setting(
        "unregister_timeout",
        float,
        10.0,
        "seconds a topic's publisher outlives its last client (a page reload reuses it)",
    ),
    Setting(
        "deadman_timeout",
        float,
        1.0,
        "seconds a client that drives (publishes `geometry_msgs/Twist` or `TwistStamped`) may stay silent "
        "before the bridge publishes a zero on each such topic, as it does at once when the client leaves; "
        "0 = off. See Dead-man stop",
        ours=True,
    ),
    Setting(
        "bag_folder",
        str,
        "",
        "folder of the bag recorder (record topics, a black box, download); empty = off. See Bags",
        ours=True,
    ),
    Setting("bag_max_bytes", int, 1_000_000_000, "bytes the bag folder may hold: a recording stops there", ours=True),
    Setting("blackbox_seconds", float, 60.0, "seconds the black box keeps, in memory", ours=True),
    Setting("blackbox_max_bytes", int, 64_000_000, "bytes the black box keeps at most", ours=True),
    Setting("use_compression", bool, False, "websocket permessage-deflate, for every message"),
    Setting(
        "compress_slow_links",
        bool,
        True,
        "websocket permessage-deflate for a client that offers it (browsers, roslibjs in Node) while its link "
        "is measured slow (under 8 MB/s): its messages of 64 kB and more (a camera frame, a map) go deflated, "
        'made once for every such client; false = only with `use_compression`. See "Deflated on a slow link"',
        ours=True,
    ),
    Setting("websocket_ping_interval", float, 0.0, "seconds between keep-alive pings; 0 = none", check=NOT_NEGATIVE),
    Setting(
        "websocket_ping_timeout",
        float,
        30.0,
        "seconds without a pong before the connection is closed; likewise a client that reads nothing of what "
        "waits for it, and a camera stream whose frame has not left",
        check=ABOVE_ZERO,
    ),
    Setting("topics_glob", str, "", 'topics clients may use, e.g. `"[/turtle1/*, /rosout]"`; empty = all'),
    Setting("services_glob", str, "", "services clients may call or provide; empty = all"),
    Setting("params_glob", str, "", "parameters clients may read or write; empty = all"),
    Setting(
        "allowed_origins",
        str,
        "",
        'web pages allowed to connect, e.g. `"[http://*.lan:*]"`; `"[*]"` = any; empty = this machine\'s '
        "pages (see Security); the bridge's own page is always allowed",
        ours=True,
    ),
    Setting(
        "allowed_hosts",
        str,
        "",
        "names a request may be addressed to (its `Host`) besides this machine's and the sites "
        '`allowed_origins` allows, e.g. a reverse proxy\'s public name `"[robots.example, *.lan]"`; `"[*]"` = '
        "any; others are refused against DNS rebinding (see Security)",
        ours=True,
    ),
    Setting("web_root", str, "", "folder served over HTTP; empty = the package's `web/`; `none` = no page", ours=True),
)
BY_NAME = {setting.name: setting for setting in SETTINGS}


def default(name):
    return BY_NAME[name].default


class SettingError(ValueError):
    """A setting's value cannot be used (the node refuses to start, naming it)."""


def convert(setting, value):
    """`value` (from the parameter server: maybe a string, since launch args are text) as the setting's type."""
    if value is None or value == "None":
        return setting.default
    try:
        if setting.kind is bool:
            if isinstance(value, str):
                if value.lower() not in ("true", "false", "1", "0"):
                    raise ValueError(value)
                return value.lower() in ("true", "1")
            return bool(value)
        if setting.kind is str:
            return str(value)
        return setting.kind(value)
    except (TypeError, ValueError):
        raise SettingError(f"setting {setting.name}: expected {setting.kind.__name__}, got {value!r}") from None


class Settings:
    """The values in force: one attribute per setting."""

    def __init__(self, get=lambda name: None):
        """get(name) -> the configured value or None (then the default holds)."""
        for setting in SETTINGS:
            given = get(setting.name)
            value = convert(setting, given)
            if setting.check is not None and isinstance(value, float) and not math.isfinite(value):
                raise SettingError(f"setting {setting.name}: must be a finite number, got {given!r}")
            if setting.check is not None and not setting.check[0](value):
                raise SettingError(f"setting {setting.name}: must be {setting.check[1]}, got {given!r}")
            setattr(self, setting.name, value)


def markdown_table():
    """The README's table of launch args."""
    rows = ["| arg | default | meaning |", "|---|---|---|"]
    for s in SETTINGS:
        rows.append(f"| `{s.name}`{' (ours)' if s.ours else ''} | {launch_text(s.default)} | {s.meaning} |")
    return "\n".join(rows)


def launch_text(value):
    """A default as a launch file (and the README) writes it."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return format(value, "g")
    return '""' if value == "" else str(value)
