"""Camera pictures for the stream endpoints (stream_routes.py), pure: no tornado, no rospy, only Pillow.

- `read_frame`: a serialized sensor_msgs/Image or CompressedImage read in place (no message object, no copy of
  its pixels): its header stamp, size and encoding, and a view of its data;
- `Picture`: one frame decoded once (on first use) into a Pillow image, whatever its encoding (ENCODINGS), and
  made a JPEG at any size and quality (`Picture.jpeg`); `output_size` is the size a request's width and height
  give, within MAX_SIDE and MAX_OUTPUT_PIXELS whatever is asked; `compressed_content_type` says whether a
  CompressedImage can be sent as it is;
- the adaptation of the `adaptive=1` streams: `Ladder` (the sizes and qualities a viewer steps through),
  `Adaptation` (when one viewer steps, from how long its link took to take each frame) and `FrameInterval` (a
  topic's frame interval, from the frames' arrival times);
- `Sending`: the pictures being written to the viewers, bounded in bytes, and which stalled viewers make room.

Decoding and encoding (Picture) is CPU work: camera_encoder.py runs it on its thread and says how frames get
there. Everything else here is cheap and runs on the event loop."""

import io
import math
import struct

from PIL import Image, ImageMath

from rosbridge import heap

IMAGE = "sensor_msgs/Image"
COMPRESSED = "sensor_msgs/CompressedImage"
IMAGE_TYPES = (IMAGE, COMPRESSED)

# sensor_msgs/Image encodings made RGB or grey as they are: encoding -> (Pillow mode, its raw mode, bytes a pixel).
# 8UC3 and 8UC4 are OpenCV's BGR order, as cv_bridge reads them.
_DIRECT = {
    "rgb8": ("RGB", "RGB", 3),
    "bgr8": ("RGB", "BGR", 3),
    "rgba8": ("RGB", "RGBX", 4),
    "bgra8": ("RGB", "BGRX", 4),
    "mono8": ("L", "L", 1),
    "8UC1": ("L", "L", 1),
    "8UC3": ("RGB", "BGR", 3),
    "8UC4": ("RGB", "BGRX", 4),
}
# One channel of more than 8 bits, made grey: mono16 scaled from its full range (as cv_bridge and web_video_server
# show it), depth images (16UC1 in mm, 32FC1 in m) normalized so that their farthest valid point is white (0,
# NaN and infinities, no reading, are black).
_WIDE = {"mono16": 2, "16UC1": 2, "32FC1": 4}
ENCODINGS = tuple(_DIRECT) + tuple(_WIDE)

MAX_PIXELS = 64_000_000  # a frame larger than this (width x height) is refused, not decoded
# What a picture is sent at, at most, whatever was asked: 4096 px a side, 8.4 Mpx (4096x2048; 4K UHD fits). A
# resized picture then holds at most 32 MB (Pillow keeps RGB in 4 bytes), and one JPEG takes at most ~0.1-0.2 s.
MAX_SIDE = 4096
MAX_OUTPUT_PIXELS = 4096 * 2048


class ImageError(ValueError):
    """A frame that cannot be made a JPEG; the text says why, for the viewer."""


class UnsupportedEncoding(ImageError):
    pass


class RawImage:
    """A sensor_msgs/Image read in place. stamp: its header stamp in seconds (0.0 when unset); pixels: a
    memoryview of its data."""

    __slots__ = ("stamp", "width", "height", "encoding", "bigendian", "step", "pixels")

    def __init__(self, stamp, width, height, encoding, bigendian, step, pixels):
        self.stamp, self.width, self.height, self.encoding = stamp, width, height, encoding
        self.bigendian, self.step, self.pixels = bigendian, step, pixels

    @property
    def size(self):
        return self.width, self.height


class CompressedFrame:
    """A sensor_msgs/CompressedImage read in place: stamp as RawImage's, format (e.g. "jpeg", or image_transport's
    "bgr8; jpeg compressed bgr8"), data: a memoryview of the picture file."""

    __slots__ = ("stamp", "format", "data", "_size")

    def __init__(self, stamp, format, data):
        self.stamp, self.format, self.data, self._size = stamp, format, data, None

    @property
    def size(self):
        """The picture's width and height, read from its file's header (nothing decoded)."""
        if self._size is None:
            try:
                with Image.open(io.BytesIO(self.data)) as image:
                    self._size = image.size
            except Exception as error:  # Pillow reports unreadable files as OSError, SyntaxError, ValueError...
                raise ImageError(f"cannot read the {self.format!r} picture: {error}") from None
        return self._size


class _Reader:
    """Reads ROS serialization (little-endian) from a memoryview, refusing truncated messages."""

    __slots__ = ("view", "at")

    def __init__(self, data):
        self.view, self.at = memoryview(data).cast("B"), 0

    def take(self, fmt):
        size = struct.calcsize(fmt)
        if self.at + size > len(self.view):
            raise ImageError("the message is truncated")
        values = struct.unpack_from(fmt, self.view, self.at)
        self.at += size
        return values

    def bytes(self):
        (length,) = self.take("<I")
        if self.at + length > len(self.view):
            raise ImageError("the message is truncated")
        part = self.view[self.at : self.at + length]
        self.at += length
        return part

    def string(self):
        return bytes(self.bytes()).decode("utf-8", "replace")

    def stamp(self):
        """A std_msgs/Header: its stamp in seconds (frame_id skipped)."""
        _, secs, nsecs = self.take("<III")
        self.bytes()
        return secs + nsecs * 1e-9


def read_frame(type_name, data):
    """A RawImage (sensor_msgs/Image) or CompressedFrame (sensor_msgs/CompressedImage) of a serialized message."""
    reader = _Reader(data)
    stamp = reader.stamp()
    if type_name == COMPRESSED:
        return CompressedFrame(stamp, reader.string(), reader.bytes())
    if type_name != IMAGE:
        raise ImageError(f"{type_name} is not an image type ({IMAGE} or {COMPRESSED})")
    height, width = reader.take("<II")
    encoding = reader.string()
    bigendian, step = reader.take("<BI")
    return RawImage(stamp, width, height, encoding, bool(bigendian), step, reader.bytes())


def compressed_content_type(fmt):
    """The HTTP content type a CompressedImage of this format goes out as unchanged, or None."""
    fmt = fmt.lower()
    if "compresseddepth" in fmt:  # a PNG behind a header of its own: not a picture a browser shows
        return None
    if "jpeg" in fmt or "jpg" in fmt:
        return "image/jpeg"
    if "png" in fmt:
        return "image/png"
    return None


def output_size(source, width=0, height=0, max_side=0):
    """The size a picture of size `source` is sent at: width and height as asked (0: as the source's); with only
    one of them, the other keeps the source's aspect; then scaled down, its aspect kept, to fit in max_side (if
    given), MAX_SIDE a side and MAX_OUTPUT_PIXELS in all, whatever was asked and whatever the source's shape."""
    _checked_size(*source)
    source_width, source_height = source
    if width and height:
        out = width, height
    elif width:
        out = width, max(1, round(source_height * width / source_width))
    elif height:
        out = max(1, round(source_width * height / source_height)), height
    else:
        out = source_width, source_height
    return _fitted(out, min(max_side, MAX_SIDE) if max_side else MAX_SIDE)


def _fitted(size, side):
    """size scaled down (aspect kept, in integers) to at most `side` a side and MAX_OUTPUT_PIXELS in all."""
    long, short = max(size), min(size)
    fitted_long = min(long, side, math.isqrt(MAX_OUTPUT_PIXELS * long // short))
    if fitted_long == long:
        return size
    fitted_short = max(1, min(round(short * fitted_long / long), MAX_OUTPUT_PIXELS // fitted_long))
    return (fitted_long, fitted_short) if size[0] >= size[1] else (fitted_short, fitted_long)


def _checked_size(width, height):
    if width <= 0 or height <= 0:
        raise ImageError(f"the image is empty ({width}x{height})")
    if width * height > MAX_PIXELS:
        raise ImageError(f"the image is too large ({width}x{height})")


def decode_raw(frame):
    """A Pillow image ("RGB" or "L") of a RawImage."""
    _checked_size(frame.width, frame.height)
    encoding, width, height, step = frame.encoding, frame.width, frame.height, frame.step
    direct = _DIRECT.get(encoding)
    depth = direct[2] if direct else _WIDE.get(encoding)
    if depth is None:
        raise UnsupportedEncoding(f"encoding {encoding!r} is not supported (supported: {', '.join(ENCODINGS)})")
    if step < width * depth:
        raise ImageError(f"step {step} is less than width {width} x {depth} bytes ({encoding})")
    if len(frame.pixels) < step * height:
        raise ImageError(f"data holds {len(frame.pixels)} bytes, less than step x height = {step * height}")
    pixels = frame.pixels[: step * height].tobytes()  # (Pillow's decoders take bytes, not a view; unpacked: a copy)
    if direct:
        mode, raw_mode, _ = direct
        return Image.frombytes(mode, (width, height), pixels, "raw", raw_mode, step, 1)
    if encoding == "32FC1":
        image = Image.frombytes("F", (width, height), pixels, "raw", "F;32BF" if frame.bigendian else "F;32F", step, 1)
        image = _finite_or_zero(image)
        _, top = image.getextrema()
    else:
        image = Image.frombytes("I", (width, height), pixels, "raw", "I;16B" if frame.bigendian else "I;16", step, 1)
        top = 65535 if encoding == "mono16" else image.getextrema()[1]
    if not top or top <= 0:
        return Image.new("L", (width, height), 0)
    scale = 255.0 / top
    return image.point(lambda value: value * scale).convert("L")  # (convert clips to 0..255)


def _finite_or_zero(image):
    """A float image with NaN, infinities and negative values made 0: x + (x - x) is NaN unless x is finite,
    and max(NaN, 0) is 0."""
    lambda_eval = getattr(ImageMath, "lambda_eval", None)  # (Pillow >= 10.3; eval() is deprecated there)
    if lambda_eval is not None:
        return lambda_eval(lambda args: args["max"](args["a"] + (args["a"] - args["a"]), 0.0), a=image)
    return ImageMath.eval("max(a + (a - a), 0.0)", a=image)


def decode_compressed(frame, at_least=None):
    """A Pillow image ("RGB" or "L") of a CompressedFrame; a JPEG is decoded at a reduced scale when every size
    wanted fits in `at_least` (width, height)."""
    try:
        image = Image.open(io.BytesIO(frame.data))
        _checked_size(*image.size)
        if at_least is not None and image.format == "JPEG":
            image.draft(image.mode if image.mode in ("RGB", "L") else "RGB", at_least)
        image.load()
    except ImageError:
        raise
    except Exception as error:  # Pillow reports unreadable files as OSError, SyntaxError, ValueError...
        raise ImageError(f"cannot decode the {frame.format!r} picture: {error}") from None
    if image.mode in ("RGB", "L"):
        return image
    if image.mode in ("I", "I;16", "I;16B", "F"):  # a 16-bit PNG: its full range made grey
        return image.point(lambda value: value * (255.0 / 65535)).convert("L")
    return image.convert("RGB")


class Picture:
    """One frame, decoded once for every JPEG made of it. Not thread-safe: one thread at a time (camera_encoder.py's
    encoder) may use it."""

    __slots__ = ("frame", "_image", "_decoded_for", "_resized")

    def __init__(self, frame):
        self.frame = frame  # a RawImage or CompressedFrame
        self._image = None
        self._decoded_for = None  # the size a reduced decode (draft) covers; None: full size
        # (size, the decoded image resized to it) of the last size made: several qualities of one size, asked one
        # after the other, are resized once (forget_resized lets it go)
        self._resized = None

    def image(self, at_least=None):
        """The decoded image, at full size or (a JPEG CompressedImage) at least `at_least`."""
        frame = self.frame
        if isinstance(frame, RawImage):
            if self._image is None:
                self._image = decode_raw(frame)
            return self._image
        if self._image is None or (
            self._decoded_for is not None
            and (at_least is None or at_least[0] > self._decoded_for[0] or at_least[1] > self._decoded_for[1])
        ):
            self._image = self._resized = None  # (the old one freed before the new one is made)
            self._image = decode_compressed(frame, at_least)
            self._decoded_for = at_least
        return self._image

    def resized(self, size):
        """The picture at `size` (at most MAX_SIDE a side and MAX_OUTPUT_PIXELS: output_size's): shrunk by
        averaging (a box filter: OpenCV's INTER_AREA, and a third cheaper than bilinear here), enlarged
        bilinearly."""
        if max(size) > MAX_SIDE or size[0] * size[1] > MAX_OUTPUT_PIXELS:
            raise ImageError(
                f"{size[0]}x{size[1]} is larger than a picture is sent ({MAX_SIDE} px a side, "
                f"{MAX_OUTPUT_PIXELS} px in all)"
            )
        image = self.image(size)
        if image.size == size:
            return image
        if self._resized is None or self._resized[0] != size:
            self._resized = None  # (freed before the next is made)
            shrink = size[0] <= image.width and size[1] <= image.height
            self._resized = size, image.resize(size, Image.Resampling.BOX if shrink else Image.Resampling.BILINEAR)
        return self._resized[1]

    def forget_resized(self):
        """Lets the resized picture go (up to 32 MB): a frame kept for later viewers keeps its decoded image only."""
        self._resized = None

    def jpeg(self, size, quality, invert=False):
        """The picture as a JPEG of `size` (width, height) at `quality` (1-100), turned 180 degrees with invert."""
        image = self.resized(size)
        if invert:
            image = image.transpose(Image.Transpose.ROTATE_180)
        out = io.BytesIO()
        image.save(out, "JPEG", quality=quality)
        return out.getvalue()


# ---- adaptation ------------------------------------------------------------------------------------------------
ADAPTIVE_QUALITY = 50  # an adaptive stream's top quality unless asked, and its top size a side: rosboard's
ADAPTIVE_MAX_SIDE = 800
LADDER_SCALES = (1.0, 0.8, 0.64, 0.5, 0.4, 0.3, 0.2)  # each step ~0.8 of the side: ~0.64 of the pixels
QUALITY_STEP = 5  # and 5 less quality a step
MIN_QUALITY = 20


class Ladder:
    """The levels an adaptive viewer steps through, from the top (level 0): (size, quality) of a picture whose
    top size is `top` (width, height) and top quality `quality`. Each level down has about half the bytes."""

    def __init__(self, quality=ADAPTIVE_QUALITY):
        floor = min(quality, MIN_QUALITY)
        self.qualities = tuple(max(floor, quality - QUALITY_STEP * level) for level in range(len(LADDER_SCALES)))

    def __len__(self):
        return len(LADDER_SCALES)

    def level(self, index, top):
        """(size, quality) of level `index` for a picture whose top size is `top`."""
        scale = LADDER_SCALES[index]
        return (max(1, round(top[0] * scale)), max(1, round(top[1] * scale))), self.qualities[index]


class Adaptation:
    """When one adaptive viewer steps down or up its Ladder, from how long its link took to take each frame it was
    sent (the stream measures: from the frame's write to the socket taking its last byte) against the interval
    between the source's frames:
    - down one level when a frame took more than DOWN_SHARE of the interval, or a frame had to be skipped (a newer
      one replaced a frame that waited for the link);
    - up one level after UP_AFTER seconds in which every frame took less than UP_SHARE of the interval. A level that
      had to be left again within SETTLED seconds of stepping up to it is tried again only after twice as long
      each time (at most MAX_HOLD), so that a link just too narrow for it is not probed every two seconds; a level
      kept for SETTLED seconds is tried again after UP_AFTER.
    Reports of frames encoded at another level than the current one (sent before the last step) are ignored."""

    DOWN_SHARE = 0.8
    UP_SHARE = 0.35
    UP_AFTER = 2.0
    SETTLED = 10.0
    MAX_HOLD = 30.0

    def __init__(self, levels):
        self.levels = levels
        self.level = 0
        self._hold = [self.UP_AFTER] * levels  # level -> seconds of good frames before stepping up to it
        self._good_since = None  # since when every frame took less than UP_SHARE (None: the last did not)
        self._arrived = None  # (when, by stepping up) the current level was reached

    def taken(self, level, took, interval, now):
        """A frame of `level` took `took` seconds to leave; `interval`: seconds between the source's frames (None
        while unknown)."""
        if level != self.level or not interval:
            return
        if self._arrived is not None:
            since, by_up = self._arrived
            if now - since >= self.SETTLED:
                if by_up:
                    self._hold[self.level] = self.UP_AFTER
                self._arrived = None
        if took > self.DOWN_SHARE * interval:
            self._down(now)
        elif took < self.UP_SHARE * interval:
            if self._good_since is None:
                self._good_since = now
            elif self.level > 0 and now - self._good_since >= self._hold[self.level - 1]:
                self.level -= 1
                self._good_since, self._arrived = None, (now, True)
        else:
            self._good_since = None

    def skipped(self, level, now):
        """A newer frame replaced one that waited while a frame of `level` was being sent."""
        if level == self.level:
            self._down(now)

    def _down(self, now):
        self._good_since = None
        if self.level + 1 >= self.levels:
            return
        if self._arrived is not None and self._arrived[1] and now - self._arrived[0] < self.SETTLED:
            self._hold[self.level] = min(self.MAX_HOLD, 2 * self._hold[self.level])
        self.level += 1
        self._arrived = (now, False)


class FrameInterval:
    """A topic's interval between frames (seconds), smoothed over the last few arrivals; None until two came."""

    SMOOTHING = 0.2
    SHORTEST, LONGEST = 1 / 240, 10.0

    def __init__(self):
        self.seconds = None
        self._last = None

    def arrived(self, now):
        if self._last is not None:
            gap = min(self.LONGEST, max(self.SHORTEST, now - self._last))
            self.seconds = gap if self.seconds is None else (1 - self.SMOOTHING) * self.seconds + self.SMOOTHING * gap
        self._last = now


# ---- what is being sent ------------------------------------------------------------------------------------------
class Sending:
    """What is being written to the viewers, bounded in bytes: each writer (a viewer) writes one picture at a time,
    from when it started until it has left (done). A picture written to several viewers counts once (they share its
    bytes); `limit` in all, or one picture alone whatever its size. Beyond it, room is made by dropping the writers
    whose picture has not left for `stall` seconds, oldest first (crowding): a reader that takes nothing holds its
    picture only until others need the room."""

    def __init__(self, limit, stall):
        self.limit, self.stall = limit, stall
        self._pictures = heap.SharedBuffers()  # a hold per writer
        self._writers = {}  # writer -> (since, data), oldest first

    def __len__(self):
        """How many writers are writing."""
        return len(self._writers)

    @property
    def used(self):
        """Bytes of the pictures being written, each once."""
        return self._pictures.bytes

    def crowding(self, data, now):
        """The writers to drop before `data` may be written: [] when it fits now (or is being written already),
        None when it does not fit even without every writer stalled for `stall` seconds."""
        return [] if data in self._pictures else self._crowding(len(data), now)

    def room_for(self, size, now):
        """Whether a picture of `size` bytes (not being written yet) may be written now, maybe after crowding."""
        return self._crowding(size, now) is not None

    def _crowding(self, size, now):
        if self._fits(size, 0):
            return []
        dropped, freed, left = [], 0, {}
        for writer in self.stalled(now, self.stall):
            dropped.append(writer)
            held = self._writers[writer][1]
            key = id(held)
            left[key] = left.get(key, self._pictures.holds(held)) - 1
            if not left[key]:  # (its last writer: the picture's bytes go)
                freed += len(held)
                if self._fits(size, freed):
                    return dropped
        return None

    def _fits(self, size, freed):
        used = self.used - freed
        return not used or used + size <= self.limit

    def start(self, writer, data, now):
        """`data` is being written to `writer` from `now` (after crowding() made room for it)."""
        assert writer not in self._writers, "a writer writes one picture at a time"
        self._writers[writer] = (now, data)
        self._pictures.hold(data)

    def done(self, writer):
        """The writer's picture has left, or the writer is gone; whether it was writing one."""
        held = self._writers.pop(writer, None)
        if held is None:
            return False
        self._pictures.release(held[1])
        return True

    def stalled(self, now, seconds):
        """The writers whose picture has not left for more than `seconds`, oldest first."""
        found = []
        for writer, (since, _) in self._writers.items():
            if now - since <= seconds:
                break
            found.append(writer)
        return found
