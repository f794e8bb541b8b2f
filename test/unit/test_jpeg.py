"""jpeg.py: reading Image and CompressedImage messages in place, every supported encoding made a JPEG, sizes and
their bounds, and the adaptive streams' ladder and policy."""

import io
import struct
import zlib

import pytest
from hypothesis import given
from hypothesis import strategies as st
from PIL import Image
from sensor_msgs.msg import CompressedImage
from sensor_msgs.msg import Image as RosImage

from rosbridge.http import jpeg


def serialized(msg):
    out = io.BytesIO()
    msg.serialize(out)
    return out.getvalue()


def ros_image(width, height, encoding, data, step=None, bigendian=0, stamp=(12, 500_000_000)):
    msg = RosImage(
        width=width,
        height=height,
        encoding=encoding,
        is_bigendian=bigendian,
        step=step if step is not None else len(data) // height,
        data=data,
    )
    msg.header.stamp.secs, msg.header.stamp.nsecs = stamp
    msg.header.frame_id = "camera"
    return serialized(msg)


def picture_of(data, type_name=jpeg.IMAGE):
    return jpeg.Picture(jpeg.read_frame(type_name, data))


def decoded(jpeg_bytes):
    image = Image.open(io.BytesIO(jpeg_bytes))
    image.load()
    return image


def near(pixel, expected, tolerance=6):
    pixel = pixel if isinstance(pixel, tuple) else (pixel,)
    expected = expected if isinstance(expected, tuple) else (expected,)
    return all(abs(a - b) <= tolerance for a, b in zip(pixel, expected))


# ---- reading ----------------------------------------------------------------------------------------------------
def test_an_image_is_read_in_place():
    data = bytes(range(48))
    frame = jpeg.read_frame(jpeg.IMAGE, ros_image(4, 4, "rgb8", data, step=12))
    assert (frame.stamp, frame.size, frame.encoding, frame.step, frame.bigendian) == (12.5, (4, 4), "rgb8", 12, False)
    assert isinstance(frame.pixels, memoryview) and bytes(frame.pixels) == data


def test_a_compressed_image_is_read_in_place_and_its_size_from_its_header():
    picture = io.BytesIO()
    Image.new("RGB", (30, 20), (10, 200, 30)).save(picture, "JPEG")
    msg = CompressedImage(format="jpeg", data=picture.getvalue())
    msg.header.stamp.secs = 7
    frame = jpeg.read_frame(jpeg.COMPRESSED, serialized(msg))
    assert (frame.stamp, frame.format, bytes(frame.data), frame.size) == (7.0, "jpeg", picture.getvalue(), (30, 20))


@pytest.mark.parametrize("cut", [3, 15, 30, 60])
def test_a_truncated_message_is_an_image_error(cut):
    data = ros_image(4, 4, "rgb8", bytes(48))
    with pytest.raises(jpeg.ImageError, match="truncated"):
        jpeg.read_frame(jpeg.IMAGE, data[:cut])


def test_another_type_is_refused():
    with pytest.raises(jpeg.ImageError, match="not an image type"):
        jpeg.read_frame("std_msgs/String", ros_image(1, 1, "mono8", b"\0"))


# ---- encodings --------------------------------------------------------------------------------------------------
RED, BLUE = (255, 0, 0), (0, 0, 255)


@pytest.mark.parametrize(
    "encoding, pixel, expected",
    [
        ("rgb8", bytes(RED), RED),
        ("bgr8", bytes(RED), BLUE),  # bytes 255, 0, 0 are blue in BGR
        ("8UC3", bytes(RED), BLUE),  # OpenCV's order
        ("rgba8", bytes((255, 0, 0, 7)), RED),
        ("bgra8", bytes((255, 0, 0, 7)), BLUE),
        ("8UC4", bytes((255, 0, 0, 7)), BLUE),
        ("mono8", bytes((200,)), 200),
        ("8UC1", bytes((90,)), 90),
    ],
)
def test_8_bit_encodings(encoding, pixel, expected):
    image = decoded(picture_of(ros_image(8, 8, encoding, pixel * 64)).jpeg((8, 8), 95))
    assert image.size == (8, 8)
    assert near(image.getpixel((4, 4)), expected), image.getpixel((4, 4))


def test_mono16_is_scaled_from_its_full_range_both_byte_orders():
    values = [0, 32768, 65535, 65535] * 16
    for pack, bigendian in (("<", 0), (">", 1)):
        data = struct.pack(f"{pack}64H", *values)
        image = decoded(picture_of(ros_image(4, 16, "mono16", data, bigendian=bigendian)).jpeg((4, 16), 100))
        row = [image.getpixel((x, 8)) for x in range(4)]
        assert near(row[0], 0, 10) and near(row[1], 128, 10) and near(row[3], 255, 10), (bigendian, row)


def test_16uc1_depth_is_normalized_to_its_farthest_point():
    values = [0, 1000, 2000, 2000] * 16  # millimetres: the farthest (2 m) is white, 0 (no reading) black
    image = decoded(picture_of(ros_image(4, 16, "16UC1", struct.pack("<64H", *values))).jpeg((4, 16), 100))
    row = [image.getpixel((x, 8)) for x in range(4)]
    assert near(row[0], 0, 12) and near(row[1], 128, 12) and near(row[3], 255, 12), row


def test_32fc1_depth_is_normalized_and_invalid_points_are_black():
    nan, inf = float("nan"), float("inf")
    values = [nan, 1.0, 4.0, inf, -2.0, 2.0, 4.0, 4.0] * 8
    for pack, bigendian in (("<", 0), (">", 1)):
        data = struct.pack(f"{pack}64f", *values)
        image = decoded(picture_of(ros_image(8, 8, "32FC1", data, bigendian=bigendian)).jpeg((8, 8), 100))
        assert image.mode == "L"
        # (a JPEG blurs 8x8 blocks a little: compare with a loose tolerance)
        row = [image.getpixel((x, 4)) for x in range(8)]
        assert row[2] > 200 and row[6] > 200 and 40 < row[1] < 100 and row[0] < 60 and row[4] < 60, row


def test_32fc1_with_the_imagemath_of_pillow_10_3_and_later(monkeypatch):
    """Debian 13's Pillow deprecates ImageMath.eval for lambda_eval(expression(args), **images); where it is
    missing (Debian 12's), a stand-in calling the expression as that one does."""
    from PIL import ImageMath

    if not hasattr(ImageMath, "lambda_eval"):

        def lambda_eval(expression, options={}, **images):  # noqa: B006  (never changed: as Pillow 10 has it)
            args = dict(ImageMath.ops, **options, **images)
            args.update({name: ImageMath._Operand(value) for name, value in args.items() if hasattr(value, "im")})
            return expression(args).im

        monkeypatch.setattr(ImageMath, "lambda_eval", lambda_eval, raising=False)
        monkeypatch.setattr(ImageMath, "eval", None)  # (not used on that path)
    test_32fc1_depth_is_normalized_and_invalid_points_are_black()


def test_depth_all_zero_is_black():
    image = decoded(picture_of(ros_image(4, 4, "16UC1", bytes(32))).jpeg((4, 4), 90))
    assert image.getextrema() == (0, 0)


def test_rows_with_padding_are_read_by_step():
    width, height, step = 5, 4, 20  # 15 bytes of pixels, 5 of padding a row
    rows = b"".join(bytes(RED) * width + b"\xff" * 5 for _ in range(height))
    image = decoded(picture_of(ros_image(width, height, "rgb8", rows, step=step)).jpeg((width, height), 100))
    assert all(near(image.getpixel((x, y)), RED, 12) for x in range(width) for y in range(height))


@pytest.mark.parametrize("encoding", ["yuv422", "bayer_rggb8", "rgb16", "nonsense"])
def test_unsupported_encodings_are_named(encoding):
    with pytest.raises(jpeg.UnsupportedEncoding, match=f"encoding '{encoding}' is not supported.*rgb8, bgr8"):
        picture_of(ros_image(2, 2, encoding, bytes(12))).jpeg((2, 2), 90)


@pytest.mark.parametrize(
    "width, height, encoding, data, step, match",
    [
        (4, 4, "rgb8", bytes(47), 12, "data holds 47 bytes"),
        (4, 4, "rgb8", bytes(48), 8, "step 8 is less than width 4"),
        (0, 0, "rgb8", b"", 0, "empty"),
        (100_000, 100_000, "mono8", b"", 100_000, "too large"),
        (7000, 7000, "mono8", bytes(10), 7000, "data holds 10 bytes"),  # (its claim alone decodes nothing)
    ],
)
def test_inconsistent_images_are_image_errors(width, height, encoding, data, step, match):
    msg = RosImage(width=width, height=height, encoding=encoding, step=step, data=data)
    with pytest.raises(jpeg.ImageError, match=match):
        picture_of(serialized(msg)).jpeg((4, 4), 90)


# ---- sizes, quality, invert --------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "width, height, max_side, expected",
    [
        (0, 0, 0, (640, 480)),
        (320, 0, 0, (320, 240)),
        (0, 120, 0, (160, 120)),
        (100, 100, 0, (100, 100)),  # both given: as asked (web_video_server)
        (0, 0, 400, (400, 300)),
        (1280, 0, 800, (800, 600)),
        (1, 0, 0, (1, 1)),
    ],
)
def test_output_size(width, height, max_side, expected):
    assert jpeg.output_size((640, 480), width, height, max_side) == expected


@pytest.mark.parametrize(
    "source, width, height, max_side, expected",
    [
        ((4, 300), 4096, 0, 0, (55, 4096)),  # the aspect alone: 4096x307,200 (1.2 GB of pixels)
        ((4, 3000), 4096, 0, 0, (5, 4096)),  # 4096x3,072,000 (12.6 GB)
        ((300, 4), 0, 4096, 0, (4096, 55)),
        ((4, 300), 4096, 0, 800, (11, 800)),
        ((640, 480), 4096, 0, 0, (3344, 2508)),  # 4096x3072 is 12.6 Mpx: scaled to 8.4, its aspect kept
        ((640, 480), 4096, 4096, 0, (2896, 2896)),  # (stretched as asked, then scaled)
        ((640, 480), 4096, 2048, 0, (4096, 2048)),  # the largest there is
        ((8000, 6000), 0, 0, 0, (3344, 2508)),  # a source larger than a picture is sent
        ((1, 100_000), 0, 0, 0, (1, 4096)),
    ],
)
def test_the_output_is_bounded_whatever_the_request_and_the_source(source, width, height, max_side, expected):
    assert jpeg.output_size(source, width, height, max_side) == expected


SOURCE_SIZES = st.integers(1, 100_000).flatmap(  # (of at most MAX_PIXELS: a larger one is refused)
    lambda width: st.tuples(st.just(width), st.integers(1, min(100_000, jpeg.MAX_PIXELS // width)))
)


@given(SOURCE_SIZES, st.integers(0, jpeg.MAX_SIDE), st.integers(0, jpeg.MAX_SIDE), st.sampled_from([0, 1, 800, 10_000]))
def test_no_output_size_leaves_the_bounds(source, width, height, max_side):
    out = jpeg.output_size(source, width, height, max_side)
    assert min(out) >= 1 and max(out) <= min(max_side or jpeg.MAX_SIDE, jpeg.MAX_SIDE)
    assert out[0] * out[1] <= jpeg.MAX_OUTPUT_PIXELS


def test_an_empty_source_has_no_output_size():
    with pytest.raises(jpeg.ImageError, match="empty"):
        jpeg.output_size((0, 480), 320)  # (a ZeroDivisionError before)


def test_a_picture_larger_than_the_bounds_is_never_made():
    """What output_size never gives, the resize refuses too: a 4x3000 image made 4096x3,072,000 allocated 12.6 GB."""
    picture = picture_of(ros_image(4, 3000, "mono8", bytes(12_000)))
    for size in ((4096, 3_072_000), (jpeg.MAX_SIDE + 1, 1), (4096, 4096)):
        with pytest.raises(jpeg.ImageError, match="larger than a picture is sent"):
            picture.jpeg(size, 90)
    assert decoded(picture.jpeg(jpeg.output_size((4, 3000), 4096), 90)).size == (5, 4096)


def png_claiming(width, height):
    """A small PNG whose header claims width x height (its data does not hold them)."""
    out = io.BytesIO()
    Image.new("L", (8, 8)).save(out, "PNG")
    data = bytearray(out.getvalue())
    data[16:24] = struct.pack(">II", width, height)  # IHDR's width and height, then its CRC
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    return bytes(data)


def test_a_compressed_image_claiming_a_huge_size_is_refused_from_its_header():
    claim = 9000, 8000  # (72 Mpx: more than MAX_PIXELS, less than Pillow's own bound, which would refuse it first)
    frame = jpeg.read_frame(jpeg.COMPRESSED, serialized(CompressedImage(format="png", data=png_claiming(*claim))))
    assert frame.size == claim
    with pytest.raises(jpeg.ImageError, match="too large"):
        jpeg.output_size(frame.size, 320)
    with pytest.raises(jpeg.ImageError, match="too large"):
        jpeg.Picture(frame).jpeg((320, 320), 90)


def gradient(width=64, height=48):
    return Image.linear_gradient("L").resize((width, height)).convert("RGB")


def test_resize_quality_and_invert():
    picture = picture_of(ros_image(64, 48, "rgb8", gradient().tobytes()))
    assert decoded(picture.jpeg((32, 24), 90)).size == (32, 24)
    assert len(picture.jpeg((64, 48), 10)) < len(picture.jpeg((64, 48), 95))
    upright, inverted = decoded(picture.jpeg((64, 48), 95)), decoded(picture.jpeg((64, 48), 95, invert=True))
    assert near(inverted.getpixel((0, 0)), upright.getpixel((63, 47)), 10)
    assert upright.getpixel((32, 2))[0] < 40 < 200 < upright.getpixel((32, 45))[0]  # (the gradient goes down)


def compressed_frame(image, fmt="jpeg", kind="JPEG"):
    out = io.BytesIO()
    image.save(out, kind)
    return serialized(CompressedImage(format=fmt, data=out.getvalue()))


@pytest.mark.parametrize("fmt, kind", [("jpeg", "JPEG"), ("bgr8; jpeg compressed bgr8", "JPEG"), ("png", "PNG")])
def test_compressed_images_are_decoded_and_made_jpegs_of_any_size(fmt, kind):
    picture = picture_of(compressed_frame(gradient(640, 480), fmt, kind), jpeg.COMPRESSED)
    small = decoded(picture.jpeg((80, 60), 80))
    assert small.size == (80, 60) and small.format == "JPEG"
    assert decoded(picture.jpeg((640, 480), 80)).size == (640, 480)  # (after a reduced decode: decoded again)


def test_a_corrupt_compressed_image_is_an_image_error():
    frame = jpeg.read_frame(jpeg.COMPRESSED, serialized(CompressedImage(format="jpeg", data=b"not a jpeg")))
    with pytest.raises(jpeg.ImageError, match="cannot read the 'jpeg' picture"):
        frame.size
    with pytest.raises(jpeg.ImageError, match="cannot decode"):
        jpeg.Picture(frame).jpeg((4, 4), 90)


@pytest.mark.parametrize(
    "fmt, expected",
    [
        ("jpeg", "image/jpeg"),
        ("JPG", "image/jpeg"),
        ("rgb8; jpeg compressed bgr8", "image/jpeg"),
        ("png", "image/png"),
        ("16UC1; compressedDepth png", None),
        ("tiff", None),
        ("", None),
    ],
)
def test_which_compressed_images_go_out_as_they_are(fmt, expected):
    assert jpeg.compressed_content_type(fmt) == expected


# ---- the ladder and the adaptation ------------------------------------------------------------------------------
def test_the_ladder_halves_the_bytes_a_step_from_the_requested_quality():
    ladder = jpeg.Ladder(50)
    levels = [ladder.level(i, (800, 600)) for i in range(len(ladder))]
    assert levels[0] == ((800, 600), 50)
    assert [quality for _, quality in levels] == [50, 45, 40, 35, 30, 25, 20]
    sides = [size[0] for size, _ in levels]
    assert sides == sorted(sides, reverse=True) and sides[-1] == 160
    assert [q for _, q in (jpeg.Ladder(15).level(i, (8, 6)) for i in range(7))] == [15] * 7  # never above asked
    picture = picture_of(ros_image(800, 600, "rgb8", Image.effect_noise((800, 600), 40).convert("RGB").tobytes()))
    sizes = [len(picture.jpeg(size, quality)) for size, quality in levels]
    assert all(0.25 < smaller / larger < 0.8 for larger, smaller in zip(sizes, sizes[1:])), sizes


INTERVAL = 0.1  # a 10 Hz camera


def feed(adaptation, took, seconds, start, interval=INTERVAL):
    """Reports a frame every interval for `seconds` from `start`, each taking `took`; returns the end time."""
    now = start
    while now < start + seconds - 1e-9:
        adaptation.taken(adaptation.level, took, interval, now)
        now += interval
    return now


def test_a_frame_slower_than_most_of_the_interval_steps_down_one_level():
    adaptation = jpeg.Adaptation(7)
    adaptation.taken(0, 0.079, INTERVAL, 0.0)
    assert adaptation.level == 0
    adaptation.taken(0, 0.081, INTERVAL, 0.1)
    assert adaptation.level == 1
    adaptation.taken(0, 0.5, INTERVAL, 0.2)  # a frame of the level left: ignored
    assert adaptation.level == 1
    adaptation.taken(1, 0.5, None, 0.3)  # the interval is not known yet
    assert adaptation.level == 1


def test_a_skipped_frame_steps_down():
    adaptation = jpeg.Adaptation(7)
    adaptation.skipped(0, 0.0)
    adaptation.skipped(0, 0.01)  # (the same write: already left)
    assert adaptation.level == 1


def test_it_stops_at_the_bottom_and_the_top():
    adaptation = jpeg.Adaptation(3)
    for step in range(10):
        adaptation.taken(adaptation.level, 1.0, INTERVAL, step)
    assert adaptation.level == 2
    feed(adaptation, 0.0, 60, 100)
    assert adaptation.level == 0


def test_two_seconds_of_fast_frames_step_up():
    adaptation = jpeg.Adaptation(7)
    adaptation.taken(0, 1.0, INTERVAL, 0.0)
    adaptation.taken(1, 1.0, INTERVAL, 0.1)
    assert adaptation.level == 2
    now = feed(adaptation, 0.03, 1.9, 0.2)
    assert adaptation.level == 2
    now = feed(adaptation, 0.03, 0.25, now)
    assert adaptation.level == 1
    feed(adaptation, 0.03, 2.1, now)
    assert adaptation.level == 0


def test_frames_between_the_thresholds_hold_the_level():
    adaptation = jpeg.Adaptation(7)
    adaptation.taken(0, 1.0, INTERVAL, 0.0)
    now = feed(adaptation, 0.05, 10, 0.1)  # half the interval: neither down nor up
    assert adaptation.level == 1
    now = feed(adaptation, 0.03, 1.0, now)
    adaptation.taken(1, 0.05, INTERVAL, now)  # one middling frame starts the two seconds again
    now = feed(adaptation, 0.03, 1.5, now + INTERVAL)
    assert adaptation.level == 1
    feed(adaptation, 0.03, 0.7, now)
    assert adaptation.level == 0


def test_a_level_left_soon_after_stepping_up_waits_twice_as_long_each_time():
    adaptation = jpeg.Adaptation(7)
    adaptation.taken(0, 1.0, INTERVAL, 0.0)  # to level 1
    waits, now = [], 0.1
    for _ in range(4):
        start = now
        while adaptation.level == 1:
            adaptation.taken(1, 0.0, INTERVAL, now)
            now += INTERVAL
        waits.append(round(now - start, 1))
        adaptation.taken(0, 1.0, INTERVAL, now)  # level 0 fails at once: back to 1
        now += INTERVAL
        assert adaptation.level == 1
    assert waits == pytest.approx([2.1, 4.1, 8.1, 16.1], abs=0.15), waits
    # a level kept for SETTLED seconds is tried again after two seconds once left
    while adaptation.level == 1:
        adaptation.taken(1, 0.0, INTERVAL, now)
        now += INTERVAL
    now = feed(adaptation, 0.0, jpeg.Adaptation.SETTLED + 1, now)
    assert adaptation.level == 0
    adaptation.taken(0, 1.0, INTERVAL, now)
    start = now = now + INTERVAL
    while adaptation.level == 1:
        adaptation.taken(1, 0.0, INTERVAL, now)
        now += INTERVAL
    assert now - start == pytest.approx(2.1, abs=0.15)


def test_the_frame_interval_is_smoothed():
    interval = jpeg.FrameInterval()
    interval.arrived(0.0)
    assert interval.seconds is None
    interval.arrived(0.1)
    assert interval.seconds == pytest.approx(0.1)
    for step in range(2, 40):
        interval.arrived(0.1 + (step - 1) * 0.05)
    assert interval.seconds == pytest.approx(0.05, rel=0.01)
    interval.arrived(1000.0)  # a pause counts for at most LONGEST
    assert interval.seconds < 3
