"""The bad-link benchmark's clients (bench/badlink.py runs them inside the network namespace, behind the shaped
link). One role per process:

  ws       a rosbridge websocket client (Tornado's) subscribed to the rover's small topic and camera, offering
           permessage-deflate as browsers and roslibjs in Node (the `ws` package) do, unless --no-deflate:
             --style roslibjs  both topics as roslibjs 1.x subscribes by default: JSON, compression "none",
                               throttle_rate 0, queue_length 0
             --style careful   the camera as CBOR with throttle_rate 66 and queue_length 1; the small topic as
                               above; status ops from the level "warning" up (set_level)
           it records, for every message, when it arrived (wall time) and its stamp (the small topic's data, the
           camera's header.stamp), and the frame's size (unpacked); and the bytes the connection read in all
           (`wire_bytes`, Tornado's count: fewer than the messages' with deflate)
  console  headless Chromium (Debian's, with Debian's chromedriver, through Selenium: run it with the test venv's
           python) on a page: --mode bridge, the console (the Camera panel showing the camera, the small topic
           opened in the Topics panel, both on screen); --mode plain, bench/plain_server.py's page. It injects
           bench/badlink_page.js, which reads the picture's age from its pixels and the small topic's from its text
  driver   drives: advertises /rover/cmd_vel and publishes a Twist at 20 Hz (linear.x 1.0, its send time in
           linear.z), watching the camera meanwhile as the careful client does (CBOR, throttle_rate 66,
           queue_length 1), until it is killed or its link is cut; it offers permessage-deflate as ws does
  sink     reads a TCP stream and reports its goodput (the link's raw capacity)

Protocol: READY when connected and subscribed; then each line on stdin is a command: `result` prints
`RESULT <json>` (everything recorded, wall times in seconds), `shot <path>` saves a screenshot (console),
`quit` ends."""

import argparse
import asyncio
import base64
import json
import shutil
import socket
import sys
import tempfile
import threading
import time
from pathlib import Path

BENCH = Path(__file__).resolve().parent


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("role", choices=["ws", "console", "sink", "driver"])
    p.add_argument("--url")
    p.add_argument("--style", choices=["roslibjs", "careful"], default="roslibjs")
    p.add_argument("--mode", choices=["bridge", "plain"], default="bridge")
    p.add_argument("--small", default="/rover/stamp")
    p.add_argument("--camera", default="/rover/camera")
    p.add_argument("--cmd-vel", default="/rover/cmd_vel")
    p.add_argument("--listen", help="sink: address:port")
    p.add_argument("--window", default="1280,1100", help="console: the browser's viewport, width,height")
    p.add_argument("--phone", action="store_true", help="console: a phone's screen (390x844 at 3x, touch)")
    p.add_argument(
        "--no-deflate",
        action="store_true",
        help="ws, driver: offer no permessage-deflate (browsers and roslibjs in Node offer it)",
    )
    a = p.parse_args()
    {
        "ws": lambda: asyncio.run(ws_client(a)),
        "console": lambda: console(a),
        "sink": lambda: sink(a),
        "driver": lambda: asyncio.run(driver(a)),
    }[a.role]()


def commands():
    """The lines of stdin, read in a thread (so that the event loop or the browser never waits for them)."""
    lines = []
    event = threading.Event()

    def read():
        for line in sys.stdin:
            lines.append(line.split())
            event.set()
        lines.append(["quit"])
        event.set()

    threading.Thread(target=read, daemon=True).start()
    return lines, event


def report(**values):
    print("RESULT " + json.dumps(values), flush=True)


# ---- ws ----------------------------------------------------------------------------------------------------


def subscribe_ops(a):
    roslibjs = {"compression": "none", "throttle_rate": 0, "queue_length": 0}
    camera = roslibjs if a.style == "roslibjs" else {"compression": "cbor", "throttle_rate": 66, "queue_length": 1}
    return [
        {"op": "subscribe", "id": f"subscribe:{a.small}:1", "type": "std_msgs/Float64", "topic": a.small, **roslibjs},
        {"op": "subscribe", "id": f"subscribe:{a.camera}:2", "type": "sensor_msgs/Image", "topic": a.camera, **camera},
    ]


def deflate_offer(a):
    """Tornado's compression_options: {} offers permessage-deflate (`permessage-deflate; client_max_window_bits`,
    as Chromium and ws offer it), None offers nothing."""
    return None if a.no_deflate else {}


async def ws_client(a):
    import cbor2
    from tornado.websocket import websocket_connect

    small, camera, statuses, closed = [], [], [], []

    def on_frame(frame):
        now = time.time()
        if frame is None:
            closed.append(now)
            return
        if isinstance(frame, bytes):
            op = cbor2.loads(frame)
        else:
            op = json.loads(frame)
        kind = op.get("op")
        if kind == "publish":
            msg = op.get("msg") or {}
            if op.get("topic") == a.small:
                small.append((now, msg["data"], len(frame)))
            elif op.get("topic") == a.camera:
                stamp = msg["header"]["stamp"]
                camera.append((now, stamp["secs"] + stamp["nsecs"] / 1e9, len(frame)))
        elif kind == "status":
            statuses.append((now, str(op.get("msg"))[:300]))
        else:
            statuses.append((now, f"op {kind}"))

    ws = await websocket_connect(
        a.url, max_message_size=64 << 20, on_message_callback=on_frame, compression_options=deflate_offer(a)
    )
    if a.style == "careful":  # (it wants to hear what its link cost it: the bridge tells that as warnings)
        await ws.write_message(json.dumps({"op": "set_level", "level": "warning"}))
    for op in subscribe_ops(a):
        await ws.write_message(json.dumps(op))
    print("READY", flush=True)
    lines, event = commands()
    while True:
        while not lines:
            await asyncio.sleep(0.05)
        words = lines.pop(0)
        if words[:1] == ["result"]:
            report(
                small=small,
                camera=camera,
                statuses=statuses[:20],
                status_count=len(statuses),
                closed=closed,
                deflate=ws.headers.get("Sec-WebSocket-Extensions"),
                wire_bytes=ws.protocol._wire_bytes_in,
            )  # (Tornado's own count of what the socket read)
        elif words[:1] == ["quit"]:
            break
    ws.close()


async def driver(a):
    from tornado.websocket import websocket_connect

    ws = await websocket_connect(
        a.url, max_message_size=64 << 20, on_message_callback=lambda frame: None, compression_options=deflate_offer(a)
    )
    ws.stream.set_nodelay(True)
    await ws.write_message(json.dumps({"op": "advertise", "topic": a.cmd_vel, "type": "geometry_msgs/Twist"}))
    await ws.write_message(
        json.dumps(
            {
                "op": "subscribe",
                "topic": a.camera,
                "type": "sensor_msgs/Image",
                "compression": "cbor",
                "throttle_rate": 66,
                "queue_length": 1,
            }
        )
    )
    period, due, n = 0.05, time.monotonic(), 0
    while True:
        twist = {"linear": {"x": 1.0, "y": 0.0, "z": time.time()}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
        ws.write_message(json.dumps({"op": "publish", "topic": a.cmd_vel, "msg": twist}))  # (a dead link: queued)
        n += 1
        if n == 10:
            print("READY", flush=True)
        due += period
        await asyncio.sleep(max(0.0, due - time.monotonic()))


# ---- console -----------------------------------------------------------------------------------------------

# (beside the tests' flags: the page keeps its full pace while nothing looks at it)
KEEP_PACE = [
    "--disable-background-timer-throttling",
    "--disable-renderer-backgrounding",
    "--disable-backgrounding-occluded-windows",
]


def wait(what, predicate, timeout=60):
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise SystemExit(f"console: timed out after {timeout} s waiting for {what}")
        time.sleep(0.2)


def open_console(driver, a):
    """The console as a driver sets it up: the small topic opened in the Topics panel, the camera chosen in the
    Camera panel, both shown at once (the console's tabs show one at a time: the Topics tab is kept visible
    beside the Camera tab, as bench/page_bench.py does)."""
    wait(
        "the page connected",
        lambda: driver.execute_script("return document.querySelector('#conn')?.dataset.state") == "connected",
    )
    open_small = (
        """const row = document.querySelector('tr[data-topic="%s"] button');
                    if (row) row.click(); return Boolean(row);"""
        % a.small
    )
    wait(f"{a.small} listed in Topics", lambda: driver.execute_script(open_small))
    choose = """const button = document.getElementById('tab-button-camera'); if (button) button.click();
                const select = document.getElementById('camera-topic');
                if (!select || ![...select.options].some(o => o.value === '%s')) return false;
                select.value = '%s'; select.dispatchEvent(new Event('change'));
                const topics = document.getElementById('tab-topics'); if (topics) topics.hidden = false;
                return true;""" % (a.camera, a.camera)
    wait(f"{a.camera} listed in Camera", lambda: driver.execute_script(choose))


def console(a):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    from chromium import CHROMIUM_FLAGS  # (testkit/, on the roles' PYTHONPATH: the browser tests' flags)

    profile = tempfile.mkdtemp(prefix="badlink-chromium-")
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for flag in (*CHROMIUM_FLAGS, *KEEP_PACE):
        options.add_argument(flag)
    width, height = (390, 844) if a.phone else map(int, a.window.split(","))
    options.add_argument(f"--user-data-dir={profile}")
    options.add_argument(f"--window-size={width},{height}")
    if a.phone:  # (as test/browser's phone screen)
        options.add_experimental_option(
            "mobileEmulation", {"deviceMetrics": {"width": width, "height": height, "pixelRatio": 3, "touch": True}}
        )
    driver = webdriver.Chrome(service=Service(executable_path="/usr/bin/chromedriver"), options=options)
    try:
        if not a.phone:
            driver.execute_cdp_cmd(
                "Emulation.setDeviceMetricsOverride",
                {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False},
            )
        driver.set_script_timeout(30)
        driver.get(a.url)
        if a.mode == "bridge":
            open_console(driver, a)
        small_selectors = [f'.open-topic[data-topic="{a.small}"] .message', "#small"]
        driver.execute_script(
            f"window.badlinkConfig = {json.dumps({'smallSelectors': small_selectors})};\n"
            + (BENCH / "badlink_page.js").read_text()
        )
        wait(
            "a camera picture with a readable stamp",
            lambda: driver.execute_script("return window.badlink.camera.length > 0"),
            timeout=90,
        )
        print("READY", flush=True)
        lines, event = commands()
        while True:
            event.wait(1.0)
            event.clear()
            while lines:
                words = lines.pop(0)
                if words[:1] == ["result"]:
                    got = driver.execute_script("return window.badlink")
                    report(
                        camera=[[t / 1000, age / 1000] for t, age in got["camera"]],
                        small=[[t / 1000, age / 1000] for t, age in got["small"]],
                        frames=[t / 1000 for t in got["frames"]],
                        readouts=got["readouts"][-40:],
                        in_view=[[t / 1000, camera, small] for t, camera, small in got["inView"]],
                        element=got["element"],
                    )
                elif words[:1] == ["shot"]:  # the whole page, not only the viewport (from its top: a sticky
                    driver.execute_script("window.scrollTo(0, 0)")  # header would be drawn where it is scrolled to)
                    time.sleep(0.3)
                    shot = driver.execute_cdp_cmd(
                        "Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True}
                    )
                    Path(words[1]).write_bytes(base64.b64decode(shot["data"]))
                    print(f"SHOT {words[1]}", flush=True)
                elif words[:1] == ["quit"]:
                    return
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


# ---- sink --------------------------------------------------------------------------------------------------


def sink(a):
    host, port = a.listen.rsplit(":", 1)
    server = socket.create_server((host, int(port)))
    print("READY", flush=True)
    conn, _ = server.accept()
    total, first = 0, None
    while True:
        data = conn.recv(1 << 16)
        if not data:
            break
        if first is None:
            first = time.monotonic()
        total += len(data)
    seconds = time.monotonic() - first if first else 0
    report(bytes=total, seconds=seconds, mbit=total * 8 / seconds / 1e6 if seconds else 0)


if __name__ == "__main__":
    main()
