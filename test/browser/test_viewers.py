"""The viewers by message type (web/viewers/, one registry line each), opened from the Topics panel in headless
Chromium against real publishers: the demo's laser and TF nodes, and rospy publishers in this process for the rest,
odd messages included (NaN and infinite ranges, empty arrays, a 4000x4000 map, 50 TF frames at 100 Hz, a 300k-point
cloud). What a person sees is asserted: pixels of the canvas, rows of a table, numbers."""

import math
import time
import urllib.request
from array import array

import pytest
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

from fixtures import bridge_fixture
from harness import ARTIFACTS, wait_for
from page_actions import open_topic, open_viewer, text_of
from sensor_messages import Publishing, big_cloud, moving_frames, quaternion, tf_message, wide_scan

BACKGROUND = (15, 20, 36)


# ---- helpers ------------------------------------------------------------------------------------------------------
def pixels(page, canvas_selector, colour=None, tolerance=60):
    """How many pixels of the canvas are close to colour, or (colour None) differ from the background."""
    return page.js(
        """const [selector, colour, background, tol] = arguments;
        const c = document.querySelector(selector);
        if (!c || !c.width) return 0;
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        const near = (i, k) => Math.abs(d[i] - k[0]) + Math.abs(d[i + 1] - k[1]) + Math.abs(d[i + 2] - k[2]) < tol;
        let n = 0;
        for (let i = 0; i < d.length; i += 4) {
          if (colour ? near(i, colour) : !near(i, background)) n++;
        }
        return n;""",
        canvas_selector,
        list(colour) if colour else None,
        list(BACKGROUND),
        tolerance,
    )


def received(page):
    """The bytes the page has received so far: its link health's count (websocket messages and HTTP bodies as the
    page reads them), updated each second."""
    return int(page.js("return Number(document.getElementById('link').dataset.received || 0)"))


def seconds_of(text):
    """The age in a line like 'newest cloud drawn: 120 ms old (by its stamp)', in seconds."""
    value, unit = text.split(": ")[1].split(" ")[:2]
    return float(value) / (1000 if unit == "ms" else 1)


def shot(page, area, name):
    """A screenshot of the page scrolled to the viewer, in test/artifacts/viewer-<name>.png (look at them)."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.js(f"document.querySelector('{area}').closest('.open-topic').scrollIntoView()")
    page.driver.save_screenshot(str(ARTIFACTS / f"viewer-{name}.png"))


@pytest.fixture(scope="module")
def demo_sensors(ros, sim):
    """The demo's turtle_tf and turtle_laser, as tools/demo starts them."""
    procs = [ros.spawn(["rosrun", "turtlesim", name], name) for name in ("turtle_tf", "turtle_laser")]
    wait_for(lambda: "/turtle1/scan" in dict(ros.master().getTopicTypes()), 30, what="the demo laser")
    yield
    for proc in procs:
        proc.stop()


@pytest.fixture
def publishers():
    """publish(node, topic, class, make, rate, latch=False): a sensor_messages.Publishing, stopped after the test."""
    publishing = []

    def publish(*args, **kwargs):
        publishing.append(Publishing(*args, **kwargs))

    yield publish
    for each in publishing:
        each.stop()


def q_multiply(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def q_rotate(q, v):
    x, y, z, w = q
    p = q_multiply(q_multiply(q, (*v, 0.0)), (-x, -y, -z, w))
    return p[:3]


# ---- TF -----------------------------------------------------------------------------------------------------------
def test_the_transform_math_composes_and_inverts_as_tf_does(open_page):
    """web/tf-math.js against the same sums done here (quaternions as tf writes them)."""
    page = open_page()
    a = ((1.0, 2.0, 0.5), quaternion(0.3, -0.2, 1.1))
    b = ((-0.5, 0.25, 2.0), quaternion(-1.0, 0.4, 2.5))
    got = page.driver.execute_async_script(
        """const done = arguments[arguments.length - 1];
        const [a, b] = [arguments[0], arguments[1]].map(([t, q]) => ({ translation: { x: t[0], y: t[1], z: t[2] },
          rotation: { x: q[0], y: q[1], z: q[2], w: q[3] } }));
        import('/tf-math.js').then(m => {
          const flat = f => [f.translation.x, f.translation.y, f.translation.z, f.rotation.x, f.rotation.y,
            f.rotation.z, f.rotation.w];
          const rpy = m.rpyOf(a.rotation);
          done({ ab: flat(m.compose(a, b)), inverse: flat(m.invert(a)), back: flat(m.compose(m.invert(a), a)),
            rpy: [rpy.roll, rpy.pitch, rpy.yaw] });
        }, e => done(String(e)));""",
        a,
        b,
    )
    moved = q_rotate(a[1], b[0])
    expected_t = [a[0][i] + moved[i] for i in range(3)]
    expected_q = q_multiply(a[1], b[1])
    assert got["ab"] == pytest.approx([*expected_t, *expected_q], abs=1e-9)
    inverse_q = (-a[1][0], -a[1][1], -a[1][2], a[1][3])
    assert got["inverse"] == pytest.approx([*(-v for v in q_rotate(inverse_q, a[0])), *inverse_q], abs=1e-9)
    assert got["back"] == pytest.approx([0, 0, 0, 0, 0, 0, 1], abs=1e-9)
    assert got["rpy"] == pytest.approx([0.3, -0.2, 1.1], abs=1e-9)


def frame_rows(page, area):
    return page.js(f"""return [...document.querySelectorAll('{area} .tf-frames tbody tr')].map(r =>
        [r.dataset.frame, ...[...r.cells].slice(1).map(c => c.textContent)])""")


@pytest.mark.alone  # (it reads rates: a fast frame's showed over 130 Hz once beside two workers, its 100 Hz
# publisher catching up after a stall)
def test_the_tf_tree_lists_frames_with_parent_rate_age_and_the_transform_between_two(
    open_page, node, demo_sensors, publishers
):
    from tf2_msgs.msg import TFMessage

    # a static chain of our own, and 50 moving frames at 100 Hz
    static = [
        ("world", "test_a", (1.0, 2.0, 0.0), quaternion(yaw=math.pi / 2)),
        ("test_a", "test_b", (0.5, 0.0, 0.2), quaternion(roll=math.pi / 6)),
    ]
    publishers(node, "/tf_static", TFMessage, lambda n: tf_message(static, node.Time.now()), 1, latch=True)
    publishers(node, "/tf", TFMessage, lambda n: moving_frames(n, node.Time.now(), "world", "fast_"), 100)
    page = open_page()
    area = open_viewer(page, "/tf", "tf")

    def frame(name):
        return next((row for row in frame_rows(page, area) if row[0] == name), None)

    wait_for(
        lambda: frame("turtle1") and frame("turtle1")[2].endswith("Hz") and frame("fast_49") and frame("test_b"),
        20,
        what="world -> turtle1, the fast frames and ours listed",
    )
    wait_for(lambda: float(frame("turtle1")[2].split()[0]) > 30, 10, what="turtle1's rate (it follows the pose)")
    turtle1 = frame("turtle1")
    assert turtle1[1] == "world" and ("ms" in turtle1[3] or " s" in turtle1[3])
    assert frame("turtle1/laser")[1:] == ["turtle1", "static", ""]  # the demo's laser, on /tf_static
    assert frame("world")[1:] == ["", "root", ""]
    wait_for(lambda: float(frame("fast_0")[2].split()[0]) > 60, 10, what="a fast frame's rate near 100 Hz")
    assert all(float(frame(f"fast_{i}")[2].split()[0]) < 130 for i in range(50))
    assert text_of(page, f"{area} .tf-count") == "56 frames · 51 dynamic · 4 static"

    Select(page.driver.find_element(By.CSS_SELECTOR, f"{area} .tf-source")).select_by_value("test_b")
    Select(page.driver.find_element(By.CSS_SELECTOR, f"{area} .tf-target")).select_by_value("world")
    # world <- test_b = (world <- test_a) (test_a <- test_b)
    qa, qb = static[0][3], static[1][3]
    moved = q_rotate(qa, static[1][2])
    expected = [static[0][2][i] + moved[i] for i in range(3)] + list(q_multiply(qa, qb))
    shown = ".tf-transform"

    def transform():
        import json

        data = page.js(f"return document.querySelector('{area} {shown}').dataset.transform || null")
        if not data:
            return None
        t = json.loads(data)
        return [t["translation"][k] for k in "xyz"] + [t["rotation"][k] for k in "xyzw"]

    wait_for(
        lambda: transform() and transform()[:3] == pytest.approx(expected[:3], abs=1e-6),
        5,
        what="the transform world <- test_b",
    )
    assert transform() == pytest.approx(expected, abs=1e-6)
    text = text_of(page, f"{area} {shown}")
    assert (
        "world ← test_b: translation (1.000, 2.500, 0.200)" in text and "roll 30.000°" in text and "yaw 90.000°" in text
    )
    shot(page, area, "tf-56-frames")
    assert page.console_errors() == []


# ---- smooth at the topics' real rates ------------------------------------------------------------------------------
@pytest.mark.alone
def test_a_fast_laser_and_fifty_tf_frames_at_100_hz_keep_the_page_smooth(open_page, node, publishers):
    """A 1081-ray scan at 40 Hz and 50 TF frames at 100 Hz, both viewers shown: the page's animation frames per
    second, and how many scans the laser viewer drew (at most one per animation frame: all 40 a second)."""
    from sensor_msgs.msg import LaserScan
    from tf2_msgs.msg import TFMessage

    publishers(node, "/fast/scan", LaserScan, lambda n: wide_scan(n, node.Time.now()), 40)
    publishers(node, "/tf", TFMessage, lambda n: moving_frames(n, node.Time.now()), 100)
    page = open_page()
    laser = open_viewer(page, "/fast/scan", "laser")
    tf = open_viewer(page, "/tf", "tf")
    wait_for(lambda: "1081 rays" in text_of(page, f"{laser} .viewer-stats"), 15, what="scans drawn")
    wait_for(lambda: "moving_49" in text_of(page, f"{tf} .tf-frames"), 15, what="the 50 frames listed")
    measured = page.driver.execute_async_script(
        """const [done, canvas] = [arguments[1], document.querySelector(arguments[0])];
        const [paints, received] = [Number(canvas.dataset.paints), Number(canvas.dataset.received)];
        let frames = 0;
        const started = performance.now();
        const count = () => {
          frames++;
          if (performance.now() - started < 3000) requestAnimationFrame(count);
          else done({ fps: frames / 3, scans: (Number(canvas.dataset.paints) - paints) / 3,
                      arrived: (Number(canvas.dataset.received) - received) / 3 });
        };
        requestAnimationFrame(count);""",
        f"{laser} canvas",
    )
    print("page frames/s and scans drawn/s:", measured, text_of(page, '.open-topic[data-topic="/fast/scan"] .stats'))
    # Alone on this 2-core machine: 57-60 frames/s, 34-38 scans/s drawn of 40 published; with other test suites
    # running on it, 47 frames/s and 25 of 29 scans drawn; beside a CPU hog, 36 frames/s and 27 of 40 drawn. The
    # bounds leave room for a busy machine: the page keeps its frame rate, and the scans that arrive are drawn but
    # for those that came two in one animation frame (the newest drawn, none behind: one a frame at most).
    assert measured["fps"] >= 30
    drawable = min(measured["arrived"], measured["fps"])
    assert measured["scans"] >= 0.6 * drawable and measured["arrived"] >= 15
    assert page.console_errors() == []


# ---- laser --------------------------------------------------------------------------------------------------------
def test_the_demo_laser_drawn_around_the_sensor_coloured_by_range(open_page, demo_sensors):
    page = open_page()
    area = open_viewer(page, "/turtle1/scan", "laser")
    canvas = f"{area} canvas"
    wait_for(lambda: "360 rays" in text_of(page, f"{area} .viewer-stats"), 15, what="a scan drawn")
    stats = text_of(page, f"{area} .viewer-stats")
    assert "frame turtle1/laser" in stats and "in range" in stats
    in_range = int(stats.split(" · ")[1].split()[0])
    assert in_range >= 300  # turtle1 in the middle of the walled world: most rays hit a wall
    assert int(page.js(f"return document.querySelector('{canvas}').dataset.points")) == in_range
    assert pixels(page, canvas) > 2000  # points, rings, the key, the scale
    # the subscription: binary CBOR at most ~30 a second (the demo sends 10)
    wait_for(
        lambda: "for the laser view" in text_of(page, '.open-topic[data-topic="/turtle1/scan"] .stats'),
        5,
        what="the throttled subscription's note",
    )


def test_odd_scans_nan_infinite_and_empty_ranges(open_page, node, publishers):
    from sensor_msgs.msg import LaserScan

    def scan(n):
        rays = 0 if n % 2 else 1081  # an empty scan every other message
        ranges = [math.nan if i % 3 == 0 else math.inf if i % 3 == 1 else 2.0 + (i % 50) / 10 for i in range(rays)]
        message = LaserScan(
            angle_min=-2.35, angle_max=2.35, angle_increment=4.7 / 1081, range_min=0.1, range_max=30.0, ranges=ranges
        )
        message.header.frame_id = "odd_laser"
        return message

    publishers(node, "/odd/scan", LaserScan, scan, 40)
    page = open_page()
    area = open_viewer(page, "/odd/scan", "laser")
    seen = set()

    def both():
        seen.add(text_of(page, f"{area} .viewer-stats").split(" · ")[0])
        return {"1081 rays", "0 rays"} <= seen

    wait_for(both, 15, what="full and empty scans drawn")
    wait_for(
        lambda: text_of(page, f"{area} .viewer-stats").startswith("1081 rays · 360 in range"),
        10,
        what="only the finite third in range",
    )
    shot(page, area, "laser-odd")
    assert page.console_errors() == []


# ---- trails -------------------------------------------------------------------------------------------------------
def test_odometry_trail_with_heading_and_speed(open_page, node, publishers):
    from nav_msgs.msg import Odometry

    def odometry(n):
        t = n / 30
        message = Odometry()
        message.header.stamp, message.header.frame_id = node.Time.now(), "odom"
        message.pose.pose.position.x, message.pose.pose.position.y = 2 * math.cos(t / 2), 2 * math.sin(t / 2)
        q = quaternion(yaw=t / 2 + math.pi / 2)
        o = message.pose.pose.orientation
        o.x, o.y, o.z, o.w = q
        message.twist.twist.linear.x, message.twist.twist.angular.z = 1.0, 0.5
        return message

    publishers(node, "/test/odom", Odometry, odometry, 30)
    page = open_page()
    area = open_viewer(page, "/test/odom", "trail")
    wait_for(lambda: "speed 1.00 m/s" in text_of(page, f"{area} .viewer-stats"), 15, what="the speed")
    assert "turn 0.50 rad/s" in text_of(page, f"{area} .viewer-stats")
    assert "frame odom" in text_of(page, f"{area} .viewer-stats")
    wait_for(lambda: pixels(page, f"{area} canvas", (63, 214, 140)) > 300, 10, what="the green trail")
    assert pixels(page, f"{area} canvas", (255, 194, 71)) > 30  # the heading arrow
    shot(page, area, "odometry")


def test_pose_stamped_speed_from_its_poses_and_a_path_drawn_whole(open_page, node, publishers):
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Path

    def pose(n):
        message = PoseStamped()
        message.header.stamp, message.header.frame_id = node.Time.now(), "map"
        message.pose.position.x = 0.5 * n / 20  # 0.5 m/s
        message.pose.orientation.w = 1.0
        return message

    publishers(node, "/test/pose", PoseStamped, pose, 20)

    def path(n):
        message = Path()
        message.header.frame_id = "map"
        for i in range(200):
            p = PoseStamped()
            p.pose.position.x, p.pose.position.y = i / 20, math.sin(i / 20)
            p.pose.orientation.w = 1.0
            message.poses.append(p)
        return message

    publishers(node, "/test/path", Path, path, 2)
    empty = Path()
    publishers(node, "/test/empty_path", Path, lambda n: empty, 2)
    page = open_page()
    area = open_viewer(page, "/test/pose", "trail")
    wait_for(lambda: "speed 0.5" in text_of(page, f"{area} .viewer-stats"), 15, what="the speed from the poses")
    area = open_viewer(page, "/test/path", "trail")
    wait_for(lambda: "200 poses" in text_of(page, f"{area} .viewer-stats"), 15, what="the path")
    assert pixels(page, f"{area} canvas", (63, 214, 140)) > 300
    shot(page, area, "path")
    area = open_viewer(page, "/test/empty_path", "trail")
    wait_for(lambda: "0 poses" in text_of(page, f"{area} .viewer-stats"), 15, what="the empty path")
    assert page.console_errors() == []


# ---- map ----------------------------------------------------------------------------------------------------------
def grid(width, height, resolution, origin=(0.0, 0.0), frame="world"):
    """An OccupancyGrid: a border of walls (100), unknown (-1) in its top-right quarter, free (0) elsewhere."""
    from nav_msgs.msg import OccupancyGrid

    message = OccupancyGrid()
    message.header.frame_id = frame
    message.info.width, message.info.height, message.info.resolution = width, height, resolution
    message.info.origin.position.x, message.info.origin.position.y = origin
    message.info.origin.orientation.w = 1.0
    cells = bytearray(width * height)
    cells[:width] = cells[-width:] = b"\x64" * width
    for row in range(height):
        cells[row * width] = cells[row * width + width - 1] = 100
        if row >= height // 2:
            cells[row * width + width // 2 : row * width + width - 1] = b"\xff" * (width - 1 - width // 2)
    message.data = array("b", bytes(cells))
    return message


def test_the_map_with_the_turtle_placed_by_tf(open_page, node, demo_sensors, publishers):
    from nav_msgs.msg import OccupancyGrid

    publishers(node, "/test/map", OccupancyGrid, lambda n: grid(222, 222, 0.05), 0.5, latch=True)
    page = open_page()
    area = open_viewer(page, "/test/map", "map")
    wait_for(
        lambda: "robot turtle1 at (5.54, 5.54) m" in text_of(page, f"{area} .viewer-stats"),
        20,
        what="turtle1 placed by TF (world -> turtle1)",
    )
    stats = text_of(page, f"{area} .viewer-stats")
    assert "222×222 cells of 5 cm" in stats
    canvas = f"{area} canvas"
    total = page.js(f"const c = document.querySelector('{canvas}'); return c.width * c.height")
    assert pixels(page, canvas, (255, 255, 255), 30) > 0.3 * total  # free
    assert pixels(page, canvas, (68, 78, 90), 20) > 0.15 * total  # unknown
    assert pixels(page, canvas, (0, 0, 0), 30) > 500  # the walls
    assert pixels(page, canvas, (255, 107, 125), 40) > 30  # the turtle, red, in the middle
    centre = page.js(f"""const c = document.querySelector('{canvas}');
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let sx = 0, sy = 0, n = 0;
        for (let i = 0; i < d.length; i += 4) {{
          if (Math.abs(d[i] - 255) + Math.abs(d[i + 1] - 107) + Math.abs(d[i + 2] - 125) < 40) {{
            sx += (i / 4) % c.width; sy += Math.floor(i / 4 / c.width); n++; }}
        }}
        return [sx / n / c.width, sy / n / c.height];""")
    assert centre == pytest.approx([0.5, 0.5], abs=0.05)  # 5.54 m of the 11.1 m map
    shot(page, area, "map")


def test_a_4000x4000_map(open_page, node, publishers):
    """Its topic opened, the 16 MB map is not fetched until the Map viewer is chosen: the tree shows the type's
    definition instead (the tree's subscription took it whole, as JSON text, before); the viewer then draws it."""
    from nav_msgs.msg import OccupancyGrid

    big = grid(4000, 4000, 0.01, origin=(-20.0, -20.0), frame="big_map")
    publishers(node, "/test/big_map", OccupancyGrid, lambda n: big, 0.2, latch=True)
    page = open_page()
    wait_for(lambda: received(page) > 0, 10, what="the page's count of bytes received")
    before = received(page)
    open_topic(page, "/test/big_map")
    opened = '.open-topic[data-topic="/test/big_map"]'
    wait_for(
        lambda: "int8[] data" in page.js(f"return document.querySelector('{opened} .definition pre').textContent"),
        15,
        what="the map's definition read",
    )
    time.sleep(8)  # (the latched map would have come whole by now)
    assert received(page) - before < 1_000_000
    assert "Not followed: a nav_msgs/OccupancyGrid may be megabytes (data: int8[])" in text_of(
        page, f"{opened} .summary"
    )
    assert "Choose a viewer (Map)" in text_of(page, f"{opened} .summary")
    shot(page, f"{opened} .summary", "map-4000-not-followed")
    chosen = received(page)
    area = open_viewer(page, "/test/big_map", "map")
    wait_for(lambda: "4000×4000 cells of 1 cm" in text_of(page, f"{area} .viewer-stats"), 60, what="the big map drawn")
    wait_for(lambda: received(page) - chosen > 16_000_000, 5, what="the map counted as received (binary, 16 MB)")
    assert "data: (16000000 bytes)" in text_of(page, f"{opened} .message")  # the viewer's message in the tree
    assert "no transform from big_map" in text_of(page, f"{area} .viewer-stats")
    canvas = f"{area} canvas"
    total = page.js(f"const c = document.querySelector('{canvas}'); return c.width * c.height")
    assert pixels(page, canvas, (255, 255, 255), 30) > 0.3 * total
    shot(page, area, "map-4000")
    empty = OccupancyGrid()  # 0x0 cells, no data
    empty.header.frame_id = "world"
    publishers(node, "/test/empty_map", OccupancyGrid, lambda n: empty, 1)
    area = open_viewer(page, "/test/empty_map", "map")
    wait_for(lambda: text_of(page, f"{area} .viewer-stats") == "an empty map", 15, what="the empty map said")
    assert page.console_errors() == []


def test_the_fields_that_may_make_a_message_megabytes(open_page):
    """web/parts/messages.js's bulkArrays: variable-length arrays of bytes, nested ones too; not fixed-length ones
    (a uuid's 16 bytes), nor arrays of numbers or strings (a scan's ranges, a joint state)."""
    page = open_page()

    def typedef(name, fields):
        return {
            "type": name,
            "fieldnames": [f[0] for f in fields],
            "fieldtypes": [f[1] for f in fields],
            "fieldarraylen": [f[2] for f in fields],
            "constnames": [],
            "constvalues": [],
        }

    typedefs = [
        typedef(
            "test/Pair",
            [
                ("header", "std_msgs/Header", -1),
                ("id", "uint8", 16),
                ("images", "sensor_msgs/Image", 0),
                ("ranges", "float32", 0),
                ("names", "string", 0),
                ("raw", "char", 0),
            ],
        ),
        typedef("std_msgs/Header", [("seq", "uint32", -1), ("frame_id", "string", -1)]),
        typedef("sensor_msgs/Image", [("encoding", "string", -1), ("data", "uint8", 0)]),
    ]
    found = page.driver.execute_async_script(
        """const done = arguments[arguments.length - 1];
        import('/parts/messages.js').then(m => done(m.bulkArrays(arguments[0])), e => done(String(e)));""",
        typedefs,
    )
    assert found == ["images[].data: uint8[]", "raw: char[]"]


def test_a_topic_whose_messages_turn_out_big_is_not_followed_but_one_is_fetched_on_request(open_page, node, publishers):
    """A type without arrays of bytes, whose messages are big all the same (about 2 MB of JSON text, twice a second):
    the tree's subscription stops at the first message above 1 MB (before, it took them all, 4 MB/s), and Fetch one
    message fetches one, binary."""
    from std_msgs.msg import Float32MultiArray

    values = [float(i) for i in range(300_000)]
    publishers(node, "/test/big_array", Float32MultiArray, lambda n: Float32MultiArray(data=values), 2)
    page = open_page()
    open_topic(page, "/test/big_array")
    opened = '.open-topic[data-topic="/test/big_array"]'
    wait_for(lambda: "newest message" in text_of(page, f"{opened} .age"), 20, what="the first message")
    time.sleep(1.5)  # (a message on its way meanwhile has come)
    before = received(page)
    time.sleep(4)
    assert received(page) - before < 500_000
    assert "Not followed: its messages are " in text_of(page, f"{opened} .summary")
    page.click(f"{opened} .summary button.fetch")
    wait_for(
        lambda: "one message fetched on request: 1.20 MB" in text_of(page, f"{opened} .stats"),
        15,
        what="one message fetched",
    )
    assert "data: (1200000 bytes)" in text_of(page, f"{opened} .message")  # (its float32[] as bytes: CBOR)
    time.sleep(1.5)
    before = received(page)
    time.sleep(3)
    assert received(page) - before < 500_000  # one, not followed
    assert page.console_errors() == []


@pytest.mark.parametrize("screen", ["desktop", "phone"])
def test_an_open_viewer_takes_the_room_of_the_screen(open_page, node, publishers, screen):
    """At 1280x800 an open viewer was 480x480 px in the left half of the console, the right half empty: it now
    takes the console's width, its canvas as large as the window leaves room for and the topic's text beside it.
    On a phone it is as wide as the screen allows, nothing wider. Screenshots: viewer-room-<screen>.png."""
    from nav_msgs.msg import OccupancyGrid

    publishers(node, "/test/room_map", OccupancyGrid, lambda n: grid(400, 400, 0.05), 0.5, latch=True)
    page = open_page(screen)
    area = open_viewer(page, "/test/room_map", "map")
    wait_for(lambda: "400×400 cells of 5 cm" in text_of(page, f"{area} .viewer-stats"), 20, what="the map drawn")
    box = page.js(
        """const area = document.querySelector(arguments[0]);
        const rect = e => { const r = e.getBoundingClientRect();
          return { left: r.left, right: r.right, top: r.top, width: r.width, height: r.height }; };
        const canvas = area.querySelector('canvas');
        return { canvas: rect(canvas), pixels: [canvas.width, canvas.height], area: rect(area),
          topic: rect(area.closest('.open-topic')), topics: rect(area.closest('.open-topics')),
          tree: rect(area.closest('.open-topic').querySelector('.message')), ratio: devicePixelRatio,
          window: [innerWidth, innerHeight], page: document.documentElement.scrollWidth };""",
        area,
    )
    canvas = box["canvas"]
    # drawn at the size shown, at the screen's pixels
    assert box["pixels"] == [round(canvas["width"] * box["ratio"]), round(canvas["height"] * box["ratio"])]
    assert box["page"] <= box["window"][0]  # nothing wider than the screen
    assert canvas["height"] <= box["window"][1] - 100  # seen whole below the header
    if screen == "desktop":
        assert box["topic"]["width"] >= 0.95 * box["topics"]["width"]  # the console's width, not its left half
        assert canvas["width"] >= 700 and canvas["height"] >= 600  # (480 x 480 before)
        assert box["tree"]["left"] >= canvas["right"]  # the topic's text and tree beside the viewer
    else:
        assert canvas["width"] >= 0.95 * box["area"]["width"] and canvas["right"] <= box["window"][0]
        assert canvas["height"] == pytest.approx(canvas["width"], abs=1)  # square
    shot(page, area, f"room-{screen}")
    assert page.console_errors() == []


# ---- GPS, diagnostics, gauges -------------------------------------------------------------------------------------
def test_navsat_fix_status_and_track_in_metres(open_page, node, publishers):
    from sensor_msgs.msg import NavSatFix, NavSatStatus

    def fix(n):
        message = NavSatFix(latitude=48.8566 + n * 1e-5, longitude=2.3522 + n * 1e-5, altitude=35.0)
        message.status.status, message.status.service = NavSatStatus.STATUS_FIX, NavSatStatus.SERVICE_GPS
        message.position_covariance = [4.0, 0, 0, 0, 4.0, 0, 0, 0, 9.0]
        message.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
        if n % 10 == 9:
            message.status.status, message.latitude = NavSatStatus.STATUS_NO_FIX, math.nan
        return message

    publishers(node, "/test/fix", NavSatFix, fix, 10)
    page = open_page()
    area = open_viewer(page, "/test/fix", "navsat")

    def track():  # (fixes, east m, north m, a fix lost) from "12 fixes · now 3.4 m E, 5 m N of the first · ..."
        stats = text_of(page, f"{area} .viewer-stats")
        if " fixes · now " not in stats:
            return None
        metres = {"km": 1000, "m": 1, "cm": 0.01, "mm": 0.001}
        east, north = (
            float(part.split()[0]) * metres[part.split()[1]]
            for part in stats.split("now ")[1].split(" of the first")[0].split(", ")
        )
        return int(stats.split()[0]), east, north, "without a fix" in stats

    wait_for(lambda: track() and track()[0] >= 5 and track()[3], 15, what="a track and a lost fix")
    wait_for(lambda: text_of(page, f"{area} .navsat-status").startswith("fix (GPS)"), 5, what="a fix")
    assert "±2 m" in text_of(page, f"{area} .navsat-status")
    _, east, north, _ = track()
    assert north == pytest.approx(east / math.cos(math.radians(48.8566)), rel=0.05)  # 1e-5 deg each way
    assert pixels(page, f"{area} canvas", (38, 222, 235)) > 50
    shot(page, area, "navsat")


def test_diagnostics_table_worst_first(open_page, node, publishers):
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    def array_(n):
        message = DiagnosticArray()
        message.header.stamp = node.Time.now()
        message.status = [
            DiagnosticStatus(level=DiagnosticStatus.OK, name="motors: left", message="ok", hardware_id="m1"),
            DiagnosticStatus(
                level=DiagnosticStatus.ERROR,
                name="battery",
                message="voltage low",
                hardware_id="b1",
                values=[KeyValue("voltage", "10.1")],
            ),
            DiagnosticStatus(level=DiagnosticStatus.WARN, name="lidar", message="hot", hardware_id="l1"),
            DiagnosticStatus(level=DiagnosticStatus.OK, name="camera", message="ok"),
        ]
        return message

    publishers(node, "/diagnostics", DiagnosticArray, array_, 2)
    page = open_page()
    area = open_viewer(page, "/diagnostics", "diagnostics")
    rows = f"{area} tr.diag-status"
    wait_for(lambda: len(page.driver.find_elements(By.CSS_SELECTOR, rows)) == 4, 15, what="four statuses")
    table = page.js(f"""return [...document.querySelectorAll('{rows}')].map(r =>
        [...r.cells].map(c => c.textContent))""")
    assert table == [
        ["ERROR", "battery", "voltage low", "b1"],
        ["WARN", "lidar", "hot", "l1"],
        ["OK", "camera", "ok", ""],
        ["OK", "motors: left", "ok", "m1"],
    ]
    assert text_of(page, f"{area} .diag-summary") == "4 statuses: 1 ERROR · 1 WARN · 2 OK"
    page.click(rows)  # (found and clicked in one step: the table is redrawn as statuses come)
    wait_for(lambda: "voltage" in text_of(page, f"{area} .diag-values"), 5, what="the error's values")
    shot(page, area, "diagnostics")


def gauge_texts(page, area):
    return page.js(f"""return Object.fromEntries([...document.querySelectorAll('{area} .gauge')].map(g =>
        [g.dataset.key, g.querySelector('.gauge-value').textContent]))""")


def test_gauges_for_joints_imu_battery_and_range(open_page, node, publishers):
    from sensor_msgs.msg import BatteryState, Imu, JointState, Range

    publishers(
        node,
        "/test/joints",
        JointState,
        lambda n: (
            JointState(name=["shoulder", "elbow"], position=[0.5, -1.0], velocity=[0.1, 0.0], effort=[])
            if n % 2 == 0
            else JointState(name=["shoulder", "elbow"], position=[0.5, -1.0], velocity=[0.1, 0.0], effort=[])
        ),
        20,
    )
    publishers(node, "/test/empty_joints", JointState, lambda n: JointState(), 5)

    def imu(n):
        message = Imu()
        q = quaternion(0.1, -0.2, 1.0)
        message.orientation.x, message.orientation.y, message.orientation.z, message.orientation.w = q
        message.angular_velocity.z = 0.5
        message.linear_acceleration.z = 9.81
        return message

    publishers(node, "/test/imu", Imu, imu, 100)
    publishers(
        node,
        "/test/battery",
        BatteryState,
        lambda n: BatteryState(
            voltage=12.3, current=-1.5, percentage=0.25, power_supply_status=2, power_supply_health=1, present=True
        ),
        1,
    )
    publishers(
        node,
        "/test/range",
        Range,
        lambda n: Range(radiation_type=0, field_of_view=0.5, min_range=0.02, max_range=4.0, range=1.0),
        10,
    )
    page = open_page()
    expected = {
        "/test/joints": {"joint:shoulder": "0.500 (28.6°) · v 0.10", "joint:elbow": "-1.000 (-57.3°) · v 0.00"},
        "/test/empty_joints": {"none": "none in the message"},
        "/test/imu": {"roll": "5.7°", "pitch": "-11.5°", "yaw": "57.3°", "wz": "0.50 rad/s", "az": "9.81 m/s²"},
        "/test/battery": {
            "charge": "25 %",
            "voltage": "12.30 V",
            "current": "-1.50 A",
            "status": "discharging · health good",
        },
        "/test/range": {"range": "1.000 m (0.02–4.00 m)", "kind": "field of view 29°"},
    }
    for topic, wanted in expected.items():
        area = open_viewer(page, topic, "gauges")
        wait_for(
            lambda: all(gauge_texts(page, area).get(k) == v for k, v in wanted.items()),
            15,
            what=f"the gauges of {topic}: {gauge_texts(page, area)}",
        )
    assert (
        page.js("""return document.querySelector('.open-topic[data-topic="/test/battery"] .gauge-bar')
        .style.width""")
        == "25%"
    )
    for topic in expected:
        shot(page, f'.open-topic[data-topic="{topic}"] .viewer', "gauges-" + topic.split("/")[-1])
    assert page.console_errors() == []


# ---- point clouds -------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def cloud_topic(node):
    from sensor_msgs.msg import PointCloud2

    cloud = big_cloud()
    publishing = Publishing(node, "/test/cloud", PointCloud2, lambda n: cloud, 2)
    yield "/test/cloud"
    publishing.stop()


def get(url, timeout=20):
    try:
        with urllib.request.urlopen(url, timeout=timeout) as answer:
            return answer.status, dict(answer.headers), answer.read()
    except urllib.error.HTTPError as error:
        return error.code, dict(error.headers), error.read()


def test_the_cloud_endpoint_decimates_on_the_bridge_to_a_bounded_size(bridge_url, cloud_topic):
    status, headers, body = get(f"{bridge_url}cloud?topic=/test/cloud&max_points=5000")
    assert status == 200 and headers["Content-Type"] == "application/octet-stream"
    assert headers["X-Points-Total"] == "300000" and int(headers["X-Points"]) <= 5000
    assert len(body) == 12 * int(headers["X-Points"]) and headers["X-Third"] == "z"
    assert headers["X-Frame-Id"] == "lidar"
    values = array("f")
    values.frombytes(body)
    assert max(math.hypot(values[i], values[i + 1]) for i in range(0, len(values), 3)) <= 10.001
    seq = int(headers["X-Seq"])
    status, headers, _ = get(f"{bridge_url}cloud?topic=/test/cloud&max_points=100&after={seq}")  # the next one
    assert status == 200 and int(headers["X-Seq"]) > seq and int(headers["X-Points"]) <= 100
    assert get(f"{bridge_url}cloud?topic=/test/cloud&max_points=0")[0] == 400
    assert get(f"{bridge_url}cloud?topic=/turtle1/pose")[0] == 404  # not a cloud
    assert get(f"{bridge_url}cloud?topic=bad%20name")[0] == 400


cloud_rules_bridge = bridge_fixture("cloud_rules_bridge", scope="function", yields="url", topics_glob="[/allowed/*]")


def test_the_cloud_endpoint_keeps_the_websockets_rules(sim, cloud_rules_bridge):
    url = f"{cloud_rules_bridge}cloud?topic="
    assert get(url + "/test/cloud")[0] == 403
    request = urllib.request.Request(url + "/allowed/cloud", headers={"Origin": "http://evil.example"})
    try:
        urllib.request.urlopen(request, timeout=10)
        refused = None
    except urllib.error.HTTPError as error:
        refused = error.code
    assert refused == 403


def test_the_cloud_viewer_draws_the_decimated_cloud_from_above(open_page, cloud_topic):
    page = open_page()
    area = open_viewer(page, "/test/cloud", "cloud")
    wait_for(lambda: "20000 of 300000 points" in text_of(page, f"{area} .viewer-stats"), 30, what="the cloud drawn")
    assert "coloured by z" in text_of(page, f"{area} .viewer-stats")
    assert int(page.js(f"return document.querySelector('{area} canvas').dataset.points")) > 15000
    # what the page receives: 240 kB per cloud drawn (2 a second here), not the 4.8 MB clouds
    paints = int(page.js(f"return document.querySelector('{area} canvas').dataset.paints"))
    received = page.js(
        "return window.performance.getEntriesByType('resource').filter(e => e.name.includes('/cloud?'))"
        ".reduce((sum, e) => sum + e.encodedBodySize, 0)"
    )
    assert 12 * 20000 <= received <= 12 * 20000 * (paints + 2)
    assert pixels(page, f"{area} canvas") > 5000
    shot(page, area, "cloud")
    # The topic's rate and age lines are the drawing's (the clouds fetched by /cloud, 2 Hz here), not those of the
    # tree's subscription, which takes one whole cloud in 30 s (by CBOR): they read "1.7 s old" and grew to 30 s.
    opened = '.open-topic[data-topic="/test/cloud"]'
    wait_for(lambda: "Hz · " in text_of(page, f"{opened} .stats"), 10, what="the drawing's rate")
    ages = []
    for _ in range(10):
        ages.append(text_of(page, f"{opened} .age"))
        time.sleep(0.5)
    assert all(age.startswith("newest cloud drawn: ") and age.endswith("old (by its stamp)") for age in ages)
    assert max(seconds_of(age) for age in ages) < 2.0, ages
    stats = text_of(page, f"{opened} .stats")  # (over the last 5 s)
    assert "clouds drawn, fetched by /cloud; the tree's messages: one every 30000 ms" in stats
    assert 1.0 <= float(stats.split("average rate: ")[1].split(" Hz")[0]) <= 2.6, stats
    assert page.console_errors() == []


# ---- phone --------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("screen", ["phone", "desktop"])
def test_screenshots_of_the_laser_and_the_tf_tree(open_page, demo_sensors, screen):
    page = open_page(screen)
    laser = open_viewer(page, "/turtle1/scan", "laser")
    wait_for(lambda: "360 rays" in text_of(page, f"{laser} .viewer-stats"), 15, what="the scan")
    tf = open_viewer(page, "/tf", "tf")
    wait_for(lambda: "Hz" in text_of(page, f"{tf} .tf-frames"), 15, what="the tree")
    width = page.js("return document.documentElement.scrollWidth")
    assert width <= page.js("return window.innerWidth")  # nothing wider than the screen
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    for name, area in (("tf", tf), ("laser", laser)):
        page.js(f"document.querySelector('{area}').scrollIntoView()")
        page.driver.save_screenshot(str(ARTIFACTS / f"viewer-{name}-{screen}.png"))
    assert page.console_errors() == []


def test_the_map_cloud_diagnostics_and_gauges_on_a_phone(open_page, node, demo_sensors, cloud_topic, publishers):
    """On a phone (390x844): nothing wider than the screen, each viewer drawn; screenshots to look at."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from nav_msgs.msg import OccupancyGrid
    from sensor_msgs.msg import Imu

    publishers(node, "/test/map", OccupancyGrid, lambda n: grid(222, 222, 0.05), 0.5, latch=True)
    publishers(
        node,
        "/diagnostics",
        DiagnosticArray,
        lambda n: DiagnosticArray(
            status=[
                DiagnosticStatus(
                    level=1,
                    name="a rather long status name: wheel odometry",
                    message="slipping on gravel",
                    hardware_id="base",
                ),
                DiagnosticStatus(level=0, name="imu", message="ok"),
            ]
        ),
        2,
    )

    def imu(n):
        message = Imu()
        message.orientation.w = 1.0
        message.linear_acceleration.z = 9.81
        return message

    publishers(node, "/test/imu", Imu, imu, 50)
    page = open_page("phone")
    checks = {
        "/test/map": ("map", "robot turtle1"),
        "/test/cloud": ("cloud", "of 300000 points"),
        "/diagnostics": ("diagnostics", "2 statuses"),
        "/test/imu": ("gauges", "9.81"),
    }
    for topic, (viewer, seen) in checks.items():
        area = open_viewer(page, topic, viewer)
        wait_for(lambda: seen in text_of(page, area), 20, what=f"the {viewer} viewer of {topic} on a phone")
    assert page.js("return document.documentElement.scrollWidth") <= page.js("return window.innerWidth")
    for topic, (viewer, _) in checks.items():
        shot(page, f'.open-topic[data-topic="{topic}"] .viewer', f"{viewer}-phone")
    assert page.console_errors() == []
