"""The console on a bad link, as a driver sees it: the camera (by the bridge's JPEG stream when it serves one, else
the websocket), the age of what is shown, the link's health in the header, and the camera, the pose and the
joystick on one screen, a phone's too. Headless Chromium against a real bridge, turtlesim and its demo camera."""

import threading
import time

import pytest
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.keys import Keys
from selenium.webdriver.support.ui import Select

from harness import ARTIFACTS, wait_for
from page_actions import text_of
from sensor_messages import CAMERA, Publishing

pytestmark = pytest.mark.alone  # (they time what a driver sees: tools/test runs them with nothing beside them)


def options(page, select_id):
    return page.js(f"return [...document.getElementById('{select_id}').options].map(o => o.value)")


def show_camera(page, topic=CAMERA):
    wait_for(lambda: topic in options(page, "camera-topic"), 20, what=f"{topic} listed")
    Select(page.el("camera-topic")).select_by_value(topic)
    stats = ".camera-panel .camera-stats"
    wait_for(
        lambda: "fps" in text_of(page, stats) and not text_of(page, stats).startswith("0"), 15, what="frames arriving"
    )


def in_view(page, selector):
    """Whether the element is wholly inside the window, as the page is scrolled now."""
    return page.js(
        """const r = document.querySelector(arguments[0]).getBoundingClientRect();
        const view = document.documentElement;
        return r.width > 0 && r.height > 0 && r.top >= 0 && r.left >= 0 && r.bottom <= view.clientHeight
          && r.right <= view.clientWidth;""",
        selector,
    )


@pytest.mark.parametrize("screen", ["desktop", "phone"])
def test_the_camera_pose_and_joystick_are_on_one_screen(open_page, camera, screen):
    page = open_page(screen)
    show_camera(page)
    wait_for(lambda: "m/s" in text_of(page, ".readout"), 10, what="the pose and speed readout")
    assert page.js("return scrollY") == 0
    assert page.js("return document.documentElement.scrollWidth <= document.documentElement.clientWidth")
    for part in (
        ".camera-panel canvas.camera",
        ".camera-panel .camera-stats",
        ".readout",
        "#joystick",
        "#stop",
        "#world",
        ".link-health",
    ):
        assert in_view(page, part), f"{part} is not on screen"
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    time.sleep(1.5)  # (a second of link health)
    page.driver.save_screenshot(str(ARTIFACTS / f"driver-view-{screen}.png"))
    assert page.console_errors() == []


def open_topic(page, topic):
    """Opens a topic from the Topics tab's list, as a person clicks its name."""
    page.el("tab-button-topics").click()
    click = f"""const button = document.querySelector('#tab-topics tr[data-topic="{topic}"] button');
                if (button) button.click();
                return Boolean(button);"""
    wait_for(lambda: page.js(click), 20, what=f"{topic} listed")


def test_the_skipped_counter_counts_what_the_bridge_skipped_for_a_page_that_fell_behind(open_page, node):
    from std_msgs.msg import String

    big = "x" * 400_000
    flood = Publishing(node, "/bad_link/flood", String, lambda n: String(f"{n} {big}"), 50)  # 20 MB/s
    try:
        page = open_page()
        open_topic(page, "/bad_link/flood")
        wait_for(
            lambda: "Hz" in text_of(page, '.open-topic[data-topic="/bad_link/flood"] .stats'),
            15,
            what="the flood arriving",
        )
        assert page.js("return document.querySelector('.link-health .skipped b').textContent") == "0"
        # The page stops reading for 3 s (its main thread busy), as a slow link would: the bridge keeps only the
        # newest message of the topic meanwhile, and says how many it skipped.
        page.js("const end = Date.now() + 3000; while (Date.now() < end) {}")
        wait_for(
            lambda: int(page.js("return document.querySelector('.link-health .skipped b').textContent")) > 0,
            15,
            what="the skipped messages counted",
        )
    finally:
        flood.stop()
    assert "skipped" not in page.feedback()  # (counted in the strip, not written in the feedback list)


class Twists:
    """The Twists published on a topic, each with when it arrived (monotonic s)."""

    def __init__(self, node, topic):
        from geometry_msgs.msg import Twist

        self.received = []
        self.lock = threading.Lock()
        self.sub = node.Subscriber(topic, Twist, self._receive)

    def _receive(self, msg):
        with self.lock:
            self.received.append((time.monotonic(), msg.linear.x, msg.angular.z))

    def between(self, start, end):
        with self.lock:
            return [r for r in self.received if start <= r[0] <= end]


@pytest.fixture
def twists(node):
    recorders = []

    def listen(topic="/turtle1/cmd_vel"):
        recorders.append(Twists(node, topic))
        return recorders[-1]

    yield listen
    for recorder in recorders:
        recorder.sub.unregister()


def canvas_digest(page, selector=".camera-panel canvas.camera"):
    """A digest of the pixels the canvas shows, and its size."""
    return page.js(
        """const c = document.querySelector(arguments[0]);
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let h = 0;
        for (let i = 0; i < d.length; i += 4) h = (h * 31 + d[i] + 7 * d[i + 1] + 13 * d[i + 2]) | 0;
        return [c.width, c.height, h];""",
        selector,
    )


def assert_driven_while_held(received, start, end):
    """While a key or the joystick was held, Twists came 10 times a second, none of them a stop (the dead-man's
    zero: the lease lapsed), and the driver's release stopped the turtle."""
    held = [r for r in received if start + 0.3 <= r[0] <= end]
    assert len(held) >= 8 * (end - start - 0.3), f"{len(held)} Twists in {end - start - 0.3:.1f} s"
    assert all(x != 0 or z != 0 for _, x, z in held), "a zero Twist while driving: the lease lapsed"
    gaps = [b[0] - a[0] for a, b in zip(held, held[1:])]
    assert max(gaps) < 0.5, f"a {max(gaps):.2f} s gap between two Twists"


def test_the_camera_comes_by_the_bridges_jpeg_stream_and_driving_stays_responsive(open_page, camera, twists):
    received = twists()
    page = open_page()
    page.network_urls()
    show_camera(page)
    stats = text_of(page, ".camera-panel .camera-stats")
    assert "JPEG stream" in stats and " old" in stats, stats
    assert any(
        "/stream?topic=%2Fturtle_camera%2Fimage_raw" in url and "adaptive=1" in url for url in page.network_urls()
    )
    width, height, before = canvas_digest(page)
    assert width > 0 and height > 0
    page.js("""window.framesDrawn = 0;
        document.querySelector('.camera-panel canvas.camera').addEventListener('frame', () => window.framesDrawn++);""")
    page.js("document.activeElement.blur()")  # (the camera's list has the focus: keys do not drive while in it)
    start = time.monotonic()
    ActionChains(page.driver).key_down(Keys.ARROW_UP).perform()
    time.sleep(3)
    end = time.monotonic()
    ActionChains(page.driver).key_up(Keys.ARROW_UP).perform()
    assert_driven_while_held(received.between(0, time.monotonic() + 1), start, end)
    wait_for(lambda: received.received[-1][1:] == (0.0, 0.0), 2, what="the stop on release")
    assert page.js("return window.framesDrawn") >= 15  # the demo camera's 10 Hz, on screen
    wait_for(lambda: canvas_digest(page)[2] != before, 5, what="the turtle seen moving in the picture")


def test_the_joystick_held_still_keeps_driving(open_page, twists):
    received = twists()
    page = open_page()
    pad = page.el("joystick")
    page.js("arguments[0].scrollIntoView({block: 'center'})", pad)  # (not under the sticky header, as a user sees it)
    start = time.monotonic()
    ActionChains(page.driver).move_to_element_with_offset(pad, 0, -40).click_and_hold().perform()
    time.sleep(3)  # held without moving: no pointer event comes meanwhile
    end = time.monotonic()
    ActionChains(page.driver).release().perform()
    assert_driven_while_held(received.between(0, time.monotonic() + 1), start, end)
    wait_for(lambda: received.received[-1][1:] == (0.0, 0.0), 2, what="the stop on release")


def block_streams(page):
    """Reloads the page with the bridge's /streams refused, as a bridge without picture streams answers."""
    page.driver.execute_cdp_cmd("Network.enable", {})
    page.driver.execute_cdp_cmd("Network.setBlockedURLs", {"urls": ["*/streams?*"]})
    page.driver.refresh()
    page.wait_state("connected")


def test_without_picture_streams_the_camera_comes_over_the_websocket(open_page, camera):
    page = open_page()
    block_streams(page)
    page.network_urls()
    show_camera(page)
    stats = text_of(page, ".camera-panel .camera-stats")
    assert "rgb8 by websocket" in stats and " old" in stats, stats
    assert not any("/stream?" in url for url in page.network_urls())
    assert canvas_digest(page)[0] > 0


def test_the_age_of_an_open_topics_newest_message_is_shown_live(open_page, node, camera):
    from geometry_msgs.msg import PointStamped

    once = node.Publisher("/bad_link/point", PointStamped, queue_size=1, latch=True)
    try:
        point = PointStamped()
        point.header.stamp = node.Time.now()
        once.publish(point)
        page = open_page()
        open_topic(page, "/turtle1/pose")
        open_topic(page, "/bad_link/point")
        open_topic(page, CAMERA)  # (an Image's tree does not follow it: its pictures are drawn by its viewer)
        page.click(f'.open-topic[data-topic="{CAMERA}"] button.view[data-viewer="image"]')
        age = '.open-topic[data-topic="{}"] .age'.format
        wait_for(
            lambda: "since it arrived (it has no header.stamp)" in text_of(page, age("/turtle1/pose")),
            15,
            what="the pose's age, since it arrived",
        )
        wait_for(
            lambda: (
                "newest picture drawn: " in text_of(page, age(CAMERA))
                and "old (by its stamp)" in text_of(page, age(CAMERA))
            ),
            15,
            what="the camera's age",
        )
        wait_for(
            lambda: "old (by its header.stamp)" in text_of(page, age("/bad_link/point")), 15, what="the point's age"
        )
        # (its one message is shown as come: the stats said "waiting for a message" for up to a second more)
        assert "waiting" not in text_of(page, '.open-topic[data-topic="/bad_link/point"] .stats')

        def seconds(selector):
            value, unit = text_of(page, selector).split(": ")[1].split(" ")[:2]
            return float(value) / (1000 if unit == "ms" else 1)

        assert seconds(age("/turtle1/pose")) < 0.5 and seconds(age(CAMERA)) < 1.0
        first = seconds(age("/bad_link/point"))
        time.sleep(1.5)
        later = seconds(age("/bad_link/point"))
        assert 1.0 < later - first < 2.5  # one message, growing older on screen
    finally:
        once.unregister()


def test_a_value_is_shown_at_the_next_animation_frame_after_it_arrives(open_page, node):
    """Each value of a 10 Hz topic is on screen within a few animation frames of its publication (the tree was
    redrawn 150 ms after a message came, showing half of them, each late)."""
    from std_msgs.msg import String

    clock = Publishing(node, "/bad_link/clock", String, lambda n: String(f"{time.time():.3f}"), 10)
    try:
        page = open_page()
        open_topic(page, "/bad_link/clock")
        leaf = '.open-topic[data-topic="/bad_link/clock"] .message'
        wait_for(lambda: "data" in text_of(page, leaf), 15, what="the first value")
        page.js(
            r"""window.shown = [];
            const area = document.querySelector(arguments[0]);
            let last = '';
            const look = () => {
              const match = /(\d{9,}\.\d+)/.exec(area.textContent);
              if (match && match[1] !== last) {
                last = match[1];
                shown.push(Date.now() - Number(match[1]) * 1000);
              }
              requestAnimationFrame(look);
            };
            requestAnimationFrame(look);""",
            leaf,
        )
        time.sleep(4)
        shown = sorted(page.js("return window.shown"))
    finally:
        clock.stop()
    assert len(shown) >= 32, f"{len(shown)} of ~40 values shown"  # every one of them, about
    assert shown[len(shown) // 2] < 60, f"shown {shown[len(shown) // 2]:.0f} ms after publication (median)"


def test_the_link_health_strip_shows_round_trip_and_bytes_per_second(open_page, camera):
    page = open_page("phone")
    show_camera(page)
    rtt = ".link-health .rtt b"
    wait_for(lambda: text_of(page, rtt).endswith(" ms"), 10, what="a round trip")
    assert 0 <= float(text_of(page, rtt).split()[0]) < 1000
    wait_for(lambda: "B/s" in text_of(page, ".link-health .rate b"), 5, what="bytes per second")
    assert text_of(page, ".link-health .rate b") != "0 B/s"  # (the camera, at least)


def test_the_pages_parsers_read_streams_and_the_bridges_reports(open_page):
    """The multipart reader cut anywhere (every split of a stream), and the status messages that count."""
    page = open_page()
    result = page.driver.execute_async_script(r"""const done = arguments[arguments.length - 1];
        Promise.all([import('/multipart.js'), import('/panels/link.js')])
        .then(([{ MultipartReader }, { linkReport }]) => {
          const text = '--b\r\nContent-Type: image/jpeg\r\nContent-Length: 5\r\nX-Timestamp: 12.500000\r\n\r\n' +
            'ab\r\n-\r\n--b\r\nContent-Type: image/jpeg\r\nContent-Length: 0\r\n\r\n\r\n--b\r\n' +
            'Content-Type: text/plain\r\n\r\nno length\r\n--b--\r\n';
          const bytes = Uint8Array.from(text, c => c.charCodeAt(0));
          const reads = [];
          for (let cut = 0; cut <= bytes.length; cut++) {
            const parts = [];
            const reader = new MultipartReader('b', ({ headers, body }) =>
              parts.push([String.fromCharCode(...body), headers.get('x-timestamp') ?? null]));
            reader.push(bytes.subarray(0, cut));
            reader.push(bytes.subarray(cut));
            reads.push(JSON.stringify([parts, reader.ended]));
          }
          const reports = [
            { level: 'warning', msg: 'skipped 3 older message(s), the newest of each topic kept (the link is ...)' },
            { level: 'error', msg: 'dropped 2 whole message(s): client too slow' },
            { level: 'error', msg: 'refused 1 message(s) larger than the outgoing bound' },
            { level: 'error', msg: 'publish: unknown topic' },
            { level: 'warning', msg: 'skipping nothing' },
          ].map(linkReport);
          done({ reads: [...new Set(reads)], reports });
        }, error => done(String(error)));""")
    assert result["reads"] == ['[[["ab\\r\\n-","12.500000"],["",null],["no length",null]],true]']
    assert result["reports"] == [
        {"skipped": 3, "lost": 0},
        {"skipped": 0, "lost": 2},
        {"skipped": 0, "lost": 1},
        None,
        None,
    ]
