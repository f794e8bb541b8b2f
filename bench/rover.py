"""The rover of the bad-link benchmark (bench/badlink.py): one rospy node that publishes

  /rover/stamp   std_msgs/Float64 at 50 Hz, its data the wall time it was published (time.time(), seconds)
  /rover/camera  sensor_msgs/Image, 640x480 rgb8 at 15 Hz, header.stamp the wall time it was published

The camera shows one of two pictures, made once at start (so that publishing costs a copy, not a drawing):

  camera-like  a scene panning 8 px a frame, blurred shapes over a grainy texture, fresh sensor noise in every
               frame: about 34 kB as JPEG at quality 50, as a real camera's picture (a smooth gradient or a
               repeated pattern would deflate about 15x and hide the problem)
  busy         many small sharp shapes and strong noise: about 77 kB as JPEG at quality 50

Each frame carries its publish time in its top 48 rows, as a barcode of 32 black or white blocks 20 px wide
(`stamp_band`): block 0 black and block 1 white (the reference levels), then the time in ms modulo 2^24 (24
blocks, most significant first, white = 1), then a 6-bit check. It survives JPEG at quality 20 and scaling to
0.35x (`python3 bench/rover.py --check` tries that), so a page's picture tells its age from its pixels
(bench/badlink_page.js decodes it in the browser).

It also listens to /rover/cmd_vel (geometry_msgs/Twist), as a rover's base does.

Protocol with bench/badlink.py: prints the pictures' sizes, then READY once publishing; a line
`count <t0> <t1>` on stdin answers `RESULT {"small": n, "camera": m}`: how many of each it published with a
stamp in [t0, t1) (wall seconds); `twists` answers `RESULT {"twists": [[arrived, linear.x, linear.z], ...]}`,
the Twists received since the last time asked."""

import argparse
import io
import json
import random
import sys
import threading
import time
import zlib

W, H = 640, 480
SMALL_HZ, CAMERA_HZ = 50.0, 15.0
FRAMES = 30  # made once: 2 s of panning, then it starts again
PAN_PX = 8

# the barcode: 32 blocks of 20 px across the top 48 rows
CELLS, CELL_W, BAND_H = 32, W // 32, 48
DATA_BITS, CHECK_BITS = 24, 6
MODULO = 1 << DATA_BITS  # ms: wraps every 4.66 hours; the reader takes the age modulo this

# (blur, shapes, texture sigma, sensor noise sigma): tuned with --check to about 34 kB and 77 kB at q50
PICTURES = {
    "camera-like": dict(shapes=60, blur=2.0, texture=21, sensor=5),
    "busy": dict(shapes=700, blur=0.3, texture=92, sensor=18),
}


def check_bits(data):
    """The 6-bit check of a 24-bit stamp (bench/badlink_page.js computes the same)."""
    groups = [(data >> shift) & 63 for shift in (18, 12, 6, 0)]
    return (groups[0] + 3 * groups[1] + 5 * groups[2] + 7 * groups[3] + 11) & 63


def stamp_bits(ms):
    data = int(ms) % MODULO
    bits = [0, 1] + [(data >> (DATA_BITS - 1 - i)) & 1 for i in range(DATA_BITS)]
    check = check_bits(data)
    return bits + [(check >> (CHECK_BITS - 1 - i)) & 1 for i in range(CHECK_BITS)]


_BLOCKS = (b"\x00" * (3 * CELL_W), b"\xff" * (3 * CELL_W))


def stamp_band(ms):
    """The top BAND_H rows of an rgb8 frame showing `ms` (wall time in ms) as a barcode."""
    return b"".join(_BLOCKS[bit] for bit in stamp_bits(ms)) * BAND_H


def read_stamp(picture):
    """A PIL picture (of any size) -> the 24-bit stamp its barcode shows, or None when it shows none."""
    from PIL import Image

    band = picture.convert("L").resize(
        (CELLS * 4, 4), Image.BILINEAR, box=(0, 0, picture.width, picture.height * BAND_H / H)
    )
    row = [band.getpixel((4 * i + 2, 2)) for i in range(CELLS)]  # each block's middle
    black, white = row[0], row[1]
    if white - black < 80:
        return None
    bits = [v > (black + white) / 2 for v in row]
    data = sum(b << (DATA_BITS - 1 - i) for i, b in enumerate(bits[2 : 2 + DATA_BITS]))
    check = sum(b << (CHECK_BITS - 1 - i) for i, b in enumerate(bits[2 + DATA_BITS :]))
    return data if check == check_bits(data) else None


def make_frames(picture, count=FRAMES):
    """`count` rgb8 frames (bytes) of the picture, panning; the barcode band is written over each at publish."""
    from PIL import Image, ImageChops, ImageDraw, ImageFilter

    p = PICTURES[picture]
    rng = random.Random(1)
    world = Image.new("RGB", (W + PAN_PX * count, H))
    draw = ImageDraw.Draw(world)
    for y in range(H):  # sky, then ground
        sky = y < H * 0.45
        draw.line(
            [(0, y), (world.width, y)],
            fill=(90 + y // 6, 120 + y // 8, 200 - y // 4) if sky else (80 + y // 10, 70 + y // 12, 50 + y // 16),
        )
    for _ in range(p["shapes"]):
        x, y, s = rng.randrange(world.width), rng.randrange(H), rng.randrange(8, 90)
        colour = tuple(rng.randrange(256) for _ in range(3))
        if rng.random() < 0.5:
            draw.rectangle([x, y, x + s, y + int(s * rng.uniform(0.3, 2))], fill=colour)
        else:
            draw.ellipse([x, y, x + s, y + s], fill=colour)
    world = world.filter(ImageFilter.GaussianBlur(p["blur"]))
    texture = Image.effect_noise(world.size, p["texture"]).filter(ImageFilter.GaussianBlur(0.8)).convert("RGB")
    world = ImageChops.add(world, texture, 1, -128)
    frames = []
    for i in range(count):
        frame = world.crop((i * PAN_PX, 0, i * PAN_PX + W, H))
        frame = ImageChops.add(frame, Image.effect_noise((W, H), p["sensor"]).convert("RGB"), 1, -128)
        frames.append(frame.tobytes())
    return frames


def with_stamp(frame, ms):
    return stamp_band(ms) + frame[len(_BLOCKS[0]) * CELLS * BAND_H :]


def sizes(picture, frames, ms=None):
    """What one picture weighs: JPEG at q50 (mean over the frames), deflated raw, raw."""
    from PIL import Image

    ms = time.time() * 1000 if ms is None else ms
    jpegs = []
    for frame in frames:
        out = io.BytesIO()
        Image.frombytes("RGB", (W, H), with_stamp(frame, ms)).save(out, "JPEG", quality=50)
        jpegs.append(len(out.getvalue()))
    raw = with_stamp(frames[0], ms)
    return {
        "picture": picture,
        "jpeg_q50_bytes": round(sum(jpegs) / len(jpegs)),
        "deflate_bytes": len(zlib.compress(raw, 6)),
        "raw_bytes": len(raw),
    }


def check(picture, frames):
    """The barcode read back after JPEG q20 and scaling to 0.35x (both orders), at many stamps."""
    from PIL import Image

    failures = 0
    rng = random.Random(2)
    for n in range(40):
        ms = rng.randrange(1 << 41)
        img = Image.frombytes("RGB", (W, H), with_stamp(frames[n % len(frames)], ms))
        small = img.resize((round(W * 0.35), round(H * 0.35)), Image.BILINEAR)
        for shown in (jpeg_again(small, 20), jpeg_again(img, 20).resize(small.size, Image.BILINEAR), img):
            failures += read_stamp(shown) != ms % MODULO
    return failures


def jpeg_again(img, quality):
    from PIL import Image

    out = io.BytesIO()
    img.save(out, "JPEG", quality=quality)
    return Image.open(io.BytesIO(out.getvalue()))


def publish(a, frames):
    import rospy
    from geometry_msgs.msg import Twist
    from sensor_msgs.msg import Image
    from std_msgs.msg import Float64, Header

    rospy.init_node("rover", disable_signals=True)
    small = rospy.Publisher(a.small, Float64, queue_size=10)
    camera = rospy.Publisher(a.camera, Image, queue_size=2)
    stamps = {"small": [], "camera": []}
    lock = threading.Lock()

    def small_loop():
        period, due = 1.0 / SMALL_HZ, time.monotonic()
        while True:
            now = time.time()
            small.publish(Float64(data=now))
            with lock:
                stamps["small"].append(now)
            due += period
            time.sleep(max(0.0, due - time.monotonic()))

    def camera_loop():
        period, due, n = 1.0 / CAMERA_HZ, time.monotonic(), 0
        while True:
            now = time.time()
            msg = Image(
                header=Header(seq=n, stamp=rospy.Time.from_sec(now), frame_id="camera"),
                height=H,
                width=W,
                encoding="rgb8",
                is_bigendian=0,
                step=3 * W,
                data=with_stamp(frames[n % len(frames)], now * 1000),
            )
            camera.publish(msg)
            with lock:
                stamps["camera"].append(now)
            n += 1
            due += period
            time.sleep(max(0.0, due - time.monotonic()))

    twists = []  # [arrived, linear.x, linear.z]: the bench's drivers put their send time in linear.z

    def driven(msg):
        with lock:
            twists.append((time.time(), msg.linear.x, msg.linear.z))

    rospy.Subscriber(a.cmd_vel, Twist, driven, tcp_nodelay=True)

    for loop in (small_loop, camera_loop):
        threading.Thread(target=loop, daemon=True).start()
    print("READY", flush=True)
    for line in sys.stdin:
        words = line.split()
        if words[:1] == ["count"]:
            t0, t1 = float(words[1]), float(words[2])
            with lock:
                counts = {k: sum(t0 <= s < t1 for s in v) for k, v in stamps.items()}
            print("RESULT " + json.dumps(counts), flush=True)
        elif words[:1] == ["twists"]:  # what arrived on cmd_vel since the last time asked
            with lock:
                got, twists[:] = list(twists), []
            print("RESULT " + json.dumps({"twists": got}), flush=True)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--picture", choices=sorted(PICTURES), default="camera-like")
    p.add_argument("--small", default="/rover/stamp")
    p.add_argument("--camera", default="/rover/camera")
    p.add_argument("--cmd-vel", default="/rover/cmd_vel")
    p.add_argument("--check", action="store_true", help="print both pictures' sizes, test the barcode, and exit")
    p.add_argument("--save", metavar="DIR", help="with --check: write a PNG of each picture's first frame there")
    a = p.parse_args()
    if a.check:
        bad = 0
        for picture in sorted(PICTURES):
            frames = make_frames(picture)
            failures = check(picture, frames)
            bad += failures
            print("PICTURE " + json.dumps({**sizes(picture, frames), "barcode_failures": failures}), flush=True)
            if a.save:
                from PIL import Image

                Image.frombytes("RGB", (W, H), with_stamp(frames[0], time.time() * 1000)).save(
                    f"{a.save}/rover-{picture}.png"
                )
        sys.exit(1 if bad else 0)
    frames = make_frames(a.picture)
    print("PICTURE " + json.dumps(sizes(a.picture, frames)), flush=True)
    publish(a, frames)


if __name__ == "__main__":
    main()
