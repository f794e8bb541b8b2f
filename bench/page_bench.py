"""The page under load, in headless Chromium (Debian's), two ways:

1. The console showing a 100 Hz topic's live tree, a plot of one of its fields, and a 30 Hz 640x480 rgb8 camera,
   all at once: the page's frame rate (requestAnimationFrame callbacks per second) and the age of each camera frame
   when the page draws it (its header stamp against the clock; publisher, bridge and browser share this machine's
   clock). Compared in the same run with the same camera shown the way roslibjs pages usually do it: a plain
   subscription (JSON, the image data as base64, no throttling), decoded into an ImageData and drawn on a canvas.
2. A robot's console (issue 23): the Laser viewer of a 1081-ray scan at 40 Hz, the TF tree of 50 frames at 100 Hz
   and the camera, all at once, opened as the browser tests do (testkit/page_actions.py), from the same publishers
   (testkit/sensor_messages.py): frames/s in each second of the run (median and lowest), the longest frame, the scans
   published, reaching the page and drawn, and the CPU of the bridge, Chromium and the publishers beside the load
   average. Compared with the same page with nothing open, in the same run (its own rate on this machine).

Run by bench/suite.py (needs a roscore: ROS_MASTER_URI); prints markdown tables. Uses the test venv's Selenium.
--screenshot PATH keeps a full-page picture of the robot's console while measured."""

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import rosgraph
import rospy
from geometry_msgs.msg import PoseStamped
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from sensor_msgs.msg import Image, LaserScan
from tf2_msgs.msg import TFMessage

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "testkit"))
import harness  # noqa: E402
from chromium import CHROMIUM_FLAGS  # noqa: E402
from page_actions import open_viewer, text_of  # noqa: E402  (the viewers opened as a person does, as the tests do)
from reporting import markdown  # noqa: E402
from sensor_messages import Publishing, moving_frames, wide_scan  # noqa: E402

WIDTH, HEIGHT = 640, 480
MEASURE_S = 10.0
TREE_TOPIC, CAMERA_TOPIC = "/bench_page/pose", "/bench_page/camera"
SCAN_TOPIC, SCAN_HZ, TF_HZ = "/bench_page/scan", 40, 100

# In the page: the time of each animation frame (camera frames' ages are recorded by show_console_camera).
PROBE = """
window.benchFrameTimes = [];
(function count(now) { window.benchFrameTimes.push(now); requestAnimationFrame(count); })(performance.now());
"""
# The usual roslibjs camera: a JSON subscription, base64 decoded into an ImageData, drawn at once.
JSON_CAMERA = """
const ros = new ROSLIB.Ros({ url: `ws://${location.host}/` });
const canvas = document.createElement('canvas');
canvas.width = %d; canvas.height = %d;
document.body.prepend(canvas);
const context = canvas.getContext('2d');
window.benchAges = [];
new ROSLIB.Topic({ ros, name: '%s', messageType: 'sensor_msgs/Image' }).subscribe(message => {
  const bytes = Uint8Array.from(atob(message.data), c => c.charCodeAt(0));
  const pixels = new ImageData(message.width, message.height);
  for (let i = 0, j = 0; i < bytes.length; i += 3, j += 4) {
    pixels.data[j] = bytes[i]; pixels.data[j + 1] = bytes[i + 1]; pixels.data[j + 2] = bytes[i + 2];
    pixels.data[j + 3] = 255;
  }
  context.putImageData(pixels, 0, 0);
  const stamp = message.header.stamp;
  window.benchAges.push(Date.now() / 1000 - (stamp.secs + stamp.nsecs / 1e9));
});
""" % (WIDTH, HEIGHT, CAMERA_TOPIC)


def frames():
    """Four camera pictures (made once: making them must not cost the publisher each time)."""
    pictures = [
        bytes([(x * 255 // WIDTH + shift) % 256 for x in range(WIDTH)] * 3) * HEIGHT for shift in (0, 64, 128, 192)
    ]

    def make(n):
        msg = Image(height=HEIGHT, width=WIDTH, encoding="rgb8", step=WIDTH * 3, data=pictures[n % 4])
        msg.header.stamp = rospy.Time.now()
        return msg

    return make


def pose(n):
    msg = PoseStamped()
    msg.header.stamp = rospy.Time.now()
    msg.pose.position.x, msg.pose.orientation.w = n * 0.01, 1.0
    return msg


def open_console(driver, url):
    driver.get(url)
    harness.wait_for(
        lambda: driver.execute_script("return document.querySelector('#conn')?.dataset.state") == "connected",
        30,
        what="the page connected",
    )
    driver.execute_script(PROBE)


def show_tree_and_plot(driver):
    """Opens the 100 Hz topic in the Topics tab and plots its pose.position.x, as a person clicks them."""
    click = (
        """const row = document.querySelector('#tab-topics tr[data-topic="%s"] button');
               if (row) row.click(); return Boolean(row);"""
        % TREE_TOPIC
    )
    harness.wait_for(lambda: driver.execute_script(click), 30, what=f"{TREE_TOPIC} listed")
    plot_x = """const leaf = [...document.querySelectorAll('.open-topic li.plottable')]
                  .find(li => li.dataset.path === JSON.stringify(['pose', 'position', 'x']));
                if (leaf) leaf.click(); return Boolean(leaf);"""
    harness.wait_for(lambda: driver.execute_script(plot_x), 30, what="the field to plot")


def show_console_camera(driver):
    """The console's camera (in the world's card) on CAMERA_TOPIC, with the Topics tab open beside it."""
    driver.execute_script("document.getElementById('tab-topics').hidden = false;")
    choose = """const select = document.getElementById('camera-topic');
                if (![...select.options].some(o => o.value === '%s')) return false;
                select.value = '%s'; select.dispatchEvent(new Event('change')); return true;""" % (
        CAMERA_TOPIC,
        CAMERA_TOPIC,
    )
    harness.wait_for(lambda: driver.execute_script(choose), 30, what="the camera listed")
    driver.execute_script("""
      window.benchAges = [];
      document.querySelector('.camera-panel canvas.camera')
        .addEventListener('frame', event => window.benchAges.push(event.detail.age));""")


class Console:
    """The page in a Chromium, as testkit/page_actions.py's helpers take it (driver, js)."""

    def __init__(self, driver):
        self.driver = driver

    def js(self, script, *args):
        return self.driver.execute_script(script, *args)


class CpuShare:
    """The CPU of some processes from now on, in % of one core (those that end meanwhile are left out)."""

    def __init__(self, pids):
        self.started, self.before = time.monotonic(), self._read(pids)

    @staticmethod
    def _read(pids):
        seconds = {}
        for pid in pids:
            try:
                seconds[pid] = harness.ProcStat(pid).cpu_seconds()
            except OSError:
                pass
        return seconds

    def percent(self):
        now = self._read(self.before)
        spent = sum(now[pid] - self.before[pid] for pid in now)
        return 100 * spent / (time.monotonic() - self.started)


def show_robot_console(console):
    """The Laser and TF tree viewers opened from the Topics tab, as a person clicks them, and the camera."""
    laser = open_viewer(console, SCAN_TOPIC, "laser")
    tf = open_viewer(console, "/tf", "tf")
    show_console_camera(console.driver)
    harness.wait_for(lambda: "1081 rays" in text_of(console, f"{laser} .viewer-stats"), 30, what="scans drawn")
    harness.wait_for(lambda: "moving_49" in text_of(console, f"{tf} .tf-frames"), 30, what="the 50 frames listed")
    harness.wait_for(lambda: console.js("return window.benchAges.length"), 30, what="camera frames drawn")
    return f"{laser} canvas"


def laser_counts(console, canvas):
    """(scans that reached the laser viewer, scans it drew) so far."""
    return console.js(
        "const c = document.querySelector(arguments[0]); "
        "return [Number(c.dataset.received), Number(c.dataset.paints)];",
        canvas,
    )


def measure(console, cpu_of, laser_canvas=None, scans=None):
    """MEASURE_S seconds of the page as it is: frames, camera frames, scans, the processes' CPU, the load."""
    console.js("window.benchAges = []; window.benchFrameTimes = [];")
    published = scans.published if scans else 0
    counted = laser_counts(console, laser_canvas) if laser_canvas else (0, 0)
    cpu = {name: CpuShare(pids) for name, pids in cpu_of.items()}
    time.sleep(MEASURE_S)
    times, ages = console.js("return [window.benchFrameTimes, window.benchAges];")
    got = {
        "fps": len(times) / MEASURE_S,
        "camera_fps": len(ages) / MEASURE_S,
        "cpu": {name: share.percent() for name, share in cpu.items()},
        "load": os.getloadavg()[0],
    }
    got.update(frame_rates(times))
    ages_ms = sorted(age * 1000 for age in ages) or [float("nan")]
    got.update(age_p50=statistics.median(ages_ms), age_p95=ages_ms[int(0.95 * (len(ages_ms) - 1))], age_max=ages_ms[-1])
    if laser_canvas:
        received, drawn = (after - before for after, before in zip(laser_counts(console, laser_canvas), counted))
        got["scans"] = {
            "published": (scans.published - published) / MEASURE_S,
            "received": received / MEASURE_S,
            "drawn": drawn / MEASURE_S,
        }
    return got


def frame_rates(times):
    """Animation frames counted in each whole second from the first: their median and lowest; the longest frame."""
    if len(times) < 2:
        return {"fps_p50": 0, "fps_min": 0, "longest_ms": float("nan")}
    per_second = [0] * int(MEASURE_S)
    for t in times:
        second = int((t - times[0]) // 1000)
        if second < len(per_second):
            per_second[second] += 1
    return {
        "fps_p50": statistics.median(per_second),
        "fps_min": min(per_second),
        "longest_ms": max(b - a for a, b in zip(times, times[1:])),
    }


def browser():
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for flag in (*CHROMIUM_FLAGS, "--window-size=1280,1600"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(executable_path="/usr/bin/chromedriver"), options=options)


def main():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--screenshot", type=Path, help="a PNG of the robot's console while measured")
    a = p.parse_args()
    rospy.init_node("page_bench", anonymous=True, disable_signals=True)
    ros = harness.RosMaster(harness.make_workdir("page-bench-"))  # for starting the bridge: the roscore is
    ros.uri = ros.env["ROS_MASTER_URI"] = rosgraph.get_master_uri()  # bench/suite.py's, already running
    bridge, port = harness.start_bridge(ros, node_name="page_bench_bridge")
    url = f"http://127.0.0.1:{port}/"
    bridge_pid = harness.node_pid(ros, "/page_bench_bridge")
    publishing = [Publishing(rospy, CAMERA_TOPIC, Image, frames(), 30)]
    results = {}
    try:
        publishing.append(Publishing(rospy, TREE_TOPIC, PoseStamped, pose, 100))
        for variant in ("console", "json"):
            driver = browser()
            try:
                open_console(driver, url)
                show_tree_and_plot(driver)
                if variant == "console":
                    show_console_camera(driver)
                else:
                    driver.execute_script(JSON_CAMERA)
                time.sleep(3)  # settle
                results[variant] = measure(Console(driver), {})
            finally:
                driver.quit()
        publishing.pop().stop()  # (the tree's topic)
        scans = Publishing(rospy, SCAN_TOPIC, LaserScan, lambda n: wide_scan(n, rospy.Time.now()), SCAN_HZ)
        publishing += [scans, Publishing(rospy, "/tf", TFMessage, lambda n: moving_frames(n, rospy.Time.now()), TF_HZ)]
        for variant in ("idle", "robot"):
            driver = browser()
            try:
                console = Console(driver)
                open_console(driver, url)
                canvas = show_robot_console(console) if variant == "robot" else None
                time.sleep(3)  # settle
                cpu_of = {
                    "bridge": [bridge_pid],
                    "chromium": harness.descendants(driver.service.process.pid),
                    "publishers": [os.getpid()],
                }
                results[variant] = measure(console, cpu_of, canvas, scans if canvas else None)
                if canvas and a.screenshot:
                    save_full_page(driver, a.screenshot)
            finally:
                driver.quit()
    finally:
        for each in publishing:
            each.stop()
        bridge.stop()
        ros.stop()
    print_tables(results)


def save_full_page(driver, path):
    import base64

    shot = driver.execute_cdp_cmd("Page.captureScreenshot", {"captureBeyondViewport": True})
    path.write_bytes(base64.b64decode(shot["data"]))


def print_tables(results):
    names = {
        "console": "the console's camera (the bridge's JPEG stream, adaptive; newest frame only)",
        "json": "a usual roslibjs camera (JSON, base64, every frame)",
    }
    rows = []
    for variant in ("console", "json"):
        got = results[variant]
        met = got["fps"] >= 50 and got["age_max"] <= 100
        rows.append(
            [
                names[variant],
                f"{got['fps']:.0f}",
                f"{got['camera_fps']:.1f}",
                f"{got['age_p50']:.0f} / {got['age_p95']:.0f} / {got['age_max']:.0f} ms",
                ("met" if met else "**missed**") if variant == "console" else "(for comparison)",
            ]
        )
    head = [
        "camera shown with a 100 Hz topic tree and a plot",
        "page frames/s",
        "camera frames drawn/s",
        "frame age p50 / p95 / max",
        "goal",
    ]
    print(markdown(head, ["---", "---:", "---:", "---:", "---"], rows))
    print(
        f"\nGoal: at least 50 page frames/s and no camera frame older than 100 ms when drawn; {MEASURE_S:.0f} s "
        "each, after 3 s to settle. Both panels (Topics and Camera) shown at once.\n"
    )
    idle, robot = results["idle"], results["robot"]
    rows = []
    for name, got in (
        ("nothing (the page connected, the same publishers running)", idle),
        (
            f"Laser (1081 rays, {SCAN_HZ} Hz), TF tree ({TF_HZ} Hz, 50 frames), camera ({WIDTH}x{HEIGHT} rgb8, 30 Hz)",
            robot,
        ),
    ):
        scans = got.get("scans")
        cpu = got["cpu"]
        versus = f" ({got['fps_p50'] / idle['fps_p50']:.2f}x)" if got is robot and idle["fps_p50"] else ""
        rows.append(
            [
                name,
                f"{got['fps_p50']:.0f} / {got['fps_min']:.0f}{versus}",
                f"{got['longest_ms']:.0f} ms",
                f"{scans['published']:.1f} / {scans['received']:.1f} / {scans['drawn']:.1f}" if scans else "",
                f"{got['camera_fps']:.1f}, {got['age_p50']:.0f} / {got['age_max']:.0f} ms" if scans else "",
                f"{cpu['bridge']:.0f} / {cpu['chromium']:.0f} / {cpu['publishers']:.0f}",
                f"{got['load']:.1f}",
                ("met" if got["fps_min"] >= 50 else "**missed**") if scans else "(baseline)",
            ]
        )
    head = [
        "a robot's console: shown at once",
        "page frames/s, median / lowest second (vs nothing shown)",
        "longest frame",
        "scans/s published / reaching the page / drawn",
        "camera frames drawn/s, age p50 / max",
        "CPU, % of a core: bridge / Chromium / publishers",
        "load (1 min)",
        "goal",
    ]
    print(markdown(head, ["---"] + ["---:"] * 6 + ["---"], rows))
    print(
        f"\nGoal: the page keeps at least 50 frames/s (every second of the {MEASURE_S:.0f} s, after 3 s to settle) "
        "with the three shown at once. Scans not drawn: those merged on the way (the viewer asks the bridge for "
        "one per animation frame at most) or two in one animation frame (the newest drawn)."
    )


if __name__ == "__main__":
    main()
