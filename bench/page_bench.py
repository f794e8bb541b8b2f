"""The page under load, in headless Chromium (Debian's): the console showing a 100 Hz topic's live tree, a plot
of one of its fields, and a 30 Hz 640x480 rgb8 camera, all at once. Measures the page's frame rate
(requestAnimationFrame callbacks per second) and the age of each camera frame when the page draws it (its
header stamp against the clock; publisher, bridge and browser share this machine's clock).

Compared in the same run with the same camera shown the way roslibjs pages usually do it: a plain subscription
(JSON, the image data as base64, no throttling), decoded into an ImageData and drawn on a canvas.

Run by bench/suite.py (needs a roscore: ROS_MASTER_URI); prints a markdown table. Uses the test venv's Selenium."""
import statistics
import sys
import threading
import time
from pathlib import Path

import rosgraph
import rospy
from geometry_msgs.msg import PoseStamped
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from sensor_msgs.msg import Image

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "test"))
import harness  # noqa: E402

WIDTH, HEIGHT = 640, 480
MEASURE_S = 10.0
TREE_TOPIC, CAMERA_TOPIC = "/bench_page/pose", "/bench_page/camera"
CHROMIUM_FLAGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                  "--no-first-run", "--disable-background-networking", "--window-size=1280,1600"]

# In the page: count animation frames, and record each camera frame's age when drawn.
PROBE = """
window.benchFrames = 0;
(function count() { window.benchFrames++; requestAnimationFrame(count); })();
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


def publish(topic, msg_class, rate, make, stop):
    publisher = rospy.Publisher(topic, msg_class, queue_size=1)

    def run():
        period, next_time, n = 1.0 / rate, time.monotonic(), 0
        while not stop.is_set():
            msg = make(n)
            msg.header.stamp = rospy.Time.now()
            publisher.publish(msg)
            n += 1
            next_time += period
            time.sleep(max(0.0, next_time - time.monotonic()))
    threading.Thread(target=run, daemon=True).start()


def frames():
    """Four camera pictures (made once: making them must not cost the publisher each time)."""
    pictures = [bytes([(x * 255 // WIDTH + shift) % 256 for x in range(WIDTH)] * 3) * HEIGHT
                for shift in (0, 64, 128, 192)]

    def make(n):
        return Image(height=HEIGHT, width=WIDTH, encoding="rgb8", step=WIDTH * 3, data=pictures[n % 4])
    return make


def pose(n):
    msg = PoseStamped()
    msg.pose.position.x, msg.pose.orientation.w = n * 0.01, 1.0
    return msg


def open_console(driver, url):
    driver.get(url)
    harness.wait_for(lambda: driver.execute_script(
        "return document.querySelector('#conn')?.dataset.state") == "connected", 30, what="the page connected")
    driver.execute_script(PROBE)


def show_tree_and_plot(driver):
    """Opens the 100 Hz topic in the Topics tab and plots its pose.position.x, as a person clicks them."""
    click = """const row = document.querySelector('#tab-topics tr[data-topic="%s"] button');
               if (row) row.click(); return Boolean(row);""" % TREE_TOPIC
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
        CAMERA_TOPIC, CAMERA_TOPIC)
    harness.wait_for(lambda: driver.execute_script(choose), 30, what="the camera listed")
    driver.execute_script("""
      window.benchAges = [];
      document.querySelector('.camera-panel canvas.camera')
        .addEventListener('frame', event => window.benchAges.push(event.detail.age));""")


def measure(driver):
    driver.execute_script("window.benchAges = []; window.benchFrames = 0;")
    time.sleep(MEASURE_S)
    frames_counted, ages = driver.execute_script("return [window.benchFrames, window.benchAges];")
    ages_ms = sorted(age * 1000 for age in ages) or [float("nan")]
    return {"fps": frames_counted / MEASURE_S, "camera_fps": len(ages) / MEASURE_S,
            "age_p50": statistics.median(ages_ms), "age_p95": ages_ms[int(0.95 * (len(ages_ms) - 1))],
            "age_max": ages_ms[-1]}


def browser():
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(executable_path="/usr/bin/chromedriver"), options=options)


def main():
    rospy.init_node("page_bench", anonymous=True, disable_signals=True)
    ros = harness.RosMaster(harness.make_workdir("page-bench-"))  # for starting the bridge: the roscore is
    ros.uri = ros.env["ROS_MASTER_URI"] = rosgraph.get_master_uri()  # bench/suite.py's, already running
    stop = threading.Event()
    bridge, port = harness.start_bridge(ros, node_name="page_bench_bridge")
    url = f"http://127.0.0.1:{port}/"
    results = {}
    try:
        publish(TREE_TOPIC, PoseStamped, 100, pose, stop)
        publish(CAMERA_TOPIC, Image, 30, frames(), stop)
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
                results[variant] = measure(driver)
            finally:
                driver.quit()
    finally:
        stop.set()
        bridge.stop()
        ros.stop()
    print_table(results)


def print_table(results):
    names = {"console": "the console's camera (the bridge's JPEG stream, adaptive; newest frame only)",
             "json": "a usual roslibjs camera (JSON, base64, every frame)"}
    print("| camera shown with a 100 Hz topic tree and a plot | page frames/s | camera frames drawn/s | "
          "frame age p50 / p95 / max | goal |")
    print("|---|---:|---:|---:|---|")
    for variant, got in results.items():
        met = got["fps"] >= 50 and got["age_max"] <= 100
        goal = ("met" if met else "**missed**") if variant == "console" else "(for comparison)"
        print(f"| {names[variant]} | {got['fps']:.0f} | {got['camera_fps']:.1f} | {got['age_p50']:.0f} / "
              f"{got['age_p95']:.0f} / {got['age_max']:.0f} ms | {goal} |")
    print(f"\nGoal: at least 50 page frames/s and no camera frame older than 100 ms when drawn; {MEASURE_S:.0f} s "
          "each, after 3 s to settle. Both panels (Topics and Camera) shown at once.")


if __name__ == "__main__":
    main()
