"""What a camera stream request asks (/stream, /snapshot, /stream_viewer: web_video_server's query parameters,
plus adaptive) and which topic it streams from (choose_source); a request refused is a BadRequest."""

from rosbridge.http import access, jpeg

STREAM_TYPES = ("mjpeg", "ros_compressed")


class BadRequest(Exception):
    """A request refused: the HTTP status and the text the client gets."""

    def __init__(self, status, text):
        super().__init__(text)
        self.status, self.text = status, text


class StreamRequest:
    """What a /stream, /snapshot or /stream_viewer request asks (web_video_server's query parameters, plus
    adaptive). quality is None when not given; width and height 0 when not given (or -1, web_video_server's
    "as the source")."""

    __slots__ = ("topic", "type", "width", "height", "quality", "invert", "adaptive", "transport")

    def __init__(self, args):
        self.topic = _text(args, "topic") or ""
        if not self.topic:
            raise BadRequest(400, "topic is required, e.g. ?topic=/camera/image_raw")
        self.type = _text(args, "type") or "mjpeg"
        if self.type not in STREAM_TYPES:
            video = (
                " (web_video_server's video codecs are not offered by this bridge)"
                if self.type in ("vp8", "vp9", "h264", "png")
                else ""
            )
            raise BadRequest(
                400, f"stream type {self.type!r} is not supported{video}: use type=mjpeg (or ros_compressed)"
            )
        self.width = _integer(args, "width", 0, jpeg.MAX_SIDE)
        self.height = _integer(args, "height", 0, jpeg.MAX_SIDE)
        self.quality = _integer(args, "quality", 1, 100, default=None)
        self.adaptive = _flag(args, "adaptive", absent=False, bare=True)
        self.invert = _flag(args, "invert", absent=False, bare=True)
        self.transport = _text(args, "default_transport") or "raw"
        if self.transport not in ("raw", "compressed"):
            raise BadRequest(400, f"default_transport must be raw or compressed, got {self.transport!r}")

    @property
    def resized(self):
        return bool(self.width or self.height or self.quality is not None or self.invert or self.adaptive)


_text = access.query_text


def _integer(args, name, low, high, default=0):
    text = _text(args, name)
    if text is None or text == "":
        return default
    try:
        value = int(text)
    except ValueError:
        value = None
    if value == -1 and name in ("width", "height"):
        return 0
    if value is None or not low <= value <= high:
        raise BadRequest(400, f"{name} must be an integer from {low} to {high}, got {text!r}")
    return value


def _flag(args, name, absent, bare):
    text = _text(args, name)
    if text is None:
        return absent
    text = text.lower()
    if text == "":
        return bare
    if text in ("1", "true", "yes", "on"):
        return True
    if text in ("0", "false", "no", "off"):
        return False
    raise BadRequest(400, f"{name} must be 1 or 0, got {text!r}")


class Source:
    """The topic a viewer's frames come from: its name and type, and pass: "any" to send a CompressedImage's JPEG or
    PNG as it is (type=ros_compressed), "jpeg" to send its JPEG as it is (nothing resized), None to make JPEGs."""

    __slots__ = ("topic", "type", "pass_mode")

    def __init__(self, topic, type_name, pass_mode=None):
        self.topic, self.type, self.pass_mode = topic, type_name, pass_mode


def choose_source(request, topic, types):
    """The Source of a request for `topic` (resolved) from the master's {topic: type} (the allowed ones), or None
    while nobody publishes it. As web_video_server: type=ros_compressed (and default_transport=compressed) take
    `topic`/compressed when it exists, else `topic` itself."""
    compressed = topic.rstrip("/") + "/compressed"
    if types.get(compressed) == jpeg.COMPRESSED:
        if request.type == "ros_compressed" and not request.adaptive:
            return Source(compressed, jpeg.COMPRESSED, "any")
        if request.type == "ros_compressed" or request.transport == "compressed":
            return Source(compressed, jpeg.COMPRESSED)
    kind = types.get(topic)
    if not kind:
        return None
    if kind not in jpeg.IMAGE_TYPES:
        raise BadRequest(404, f"topic {topic} is a {kind}, not an image ({jpeg.IMAGE} or {jpeg.COMPRESSED})")
    if kind == jpeg.COMPRESSED and request.type == "ros_compressed" and not request.adaptive:
        return Source(topic, kind, "any")
    return Source(topic, kind, "jpeg" if kind == jpeg.COMPRESSED and not request.resized else None)
