"""Lichtblick (Foxglove Studio's open fork, v1.28.1 built from source outside the repository by
../shared/anchors/lichtblick/build.sh into $LICHTBLICK_DIR, default /tmp/lichtblick) in headless Chromium, with its
"Foxglove WebSocket" source on the bridge's second port (foxglove_port) and the demo's nodes: a layout with a 3D
panel (the laser, TF and the turtle's URDF with its mesh fetched from the bridge), a plot, an image, the
parameters (one edited and seen on the master), a service call and a Twist published. Screenshots go to
test/artifacts/lichtblick-*.png."""

import functools
import http.server
import json
import os
import threading
import time
from pathlib import Path

import pytest
from PIL import Image
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys

from conftest import Browser
from fixtures import bridge_fixture
from harness import REPO, free_port, wait_for

LICHTBLICK = Path(os.environ.get("LICHTBLICK_DIR", "/tmp/lichtblick")) / "web" / ".webpack"
ARTIFACTS = REPO / "test" / "artifacts"
SCREEN = {"width": 1600, "height": 1000, "pixelRatio": 1}
SHELL = (64, 140, 77)  # urdf/turtle.urdf's shell colour (0.25 0.55 0.3), as lit in the 3D panel: roughly
SKY = (69, 86, 255)  # turtlesim's background, in the camera's image

pytestmark = [
    pytest.mark.skipif(
        not (LICHTBLICK / "index.html").is_file(),
        reason=f"Lichtblick is not built in {LICHTBLICK} (../shared/anchors/lichtblick/build.sh)",
    ),
    pytest.mark.slow,
]

LAYOUT = {
    "configById": {
        "3D!scene": {
            "followTf": "turtle1",
            "topics": {
                "/turtle1/scan": {"visible": True, "pointSize": 4},
                "param:/robot_description": {"visible": True},
            },
            "cameraState": {
                "distance": 3,
                "phi": 50,
                "thetaOffset": 45,
                "targetOffset": [0, 0, 0],
                "target": [0, 0, 0],
                "targetOrientation": [0, 0, 0, 1],
                "perspective": True,
                "fovy": 45,
                "near": 0.01,
                "far": 5000,
            },
        },
        "Plot!pose": {"paths": [{"value": "/turtle1/pose.x", "enabled": True, "timestampMethod": "receiveTime"}]},
        "Image!camera": {"imageMode": {"imageTopic": "/turtle_camera/image_raw"}},
        "Parameters!params": {},
        "CallService!clear": {"serviceName": "/clear", "requestPayload": "{}"},
        "Publish!drive": {
            "topicName": "/turtle1/cmd_vel",
            "datatype": "geometry_msgs/Twist",
            "buttonText": "Publish",
            "value": json.dumps({"linear": {"x": 2.0, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 1.0}}),
        },
    },
    "globalVariables": {},
    "userNodes": {},
    "playbackConfig": {"speed": 1},
    "layout": {
        "direction": "row",
        "first": {
            "direction": "column",
            "first": "3D!scene",
            "second": {"direction": "row", "first": "Plot!pose", "second": "Image!camera"},
        },
        "second": {
            "direction": "column",
            "first": "Parameters!params",
            "second": {"direction": "column", "first": "CallService!clear", "second": "Publish!drive"},
        },
        "splitPercentage": 60,
    },
}


class _Files(http.server.SimpleHTTPRequestHandler):
    """Lichtblick's files, and the layout at /layout.json."""

    def do_GET(self):  # noqa: N802 (http.server's name)
        if self.path.startswith("/layout.json"):
            body = json.dumps(LAYOUT).encode()
            self.send_response(200)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)
            return
        super().do_GET()

    def log_message(self, *args):
        pass


@pytest.fixture(scope="module")
def demo(ros, sim):
    """The demo's nodes besides turtlesim: TF (and /robot_description), the camera, the laser."""
    procs = [ros.spawn(["rosrun", "turtlesim", name], name) for name in ("turtle_tf", "turtle_camera", "turtle_laser")]
    wait_for(lambda: "/turtle1/scan" in dict(ros.master().getTopicTypes()), 30, what="the laser")
    yield
    for proc in procs:
        proc.stop()


bridge = bridge_fixture("lichtblick_bridge", yields="bridge", needs=("demo",), foxglove_port=0)


@pytest.fixture(scope="module")
def lichtblick():
    """Lichtblick's web app served on a free port of 127.0.0.1."""
    server = http.server.ThreadingHTTPServer(
        ("127.0.0.1", free_port()), functools.partial(_Files, directory=str(LICHTBLICK))
    )
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def shot(browser, name):
    ARTIFACTS.mkdir(exist_ok=True)
    path = ARTIFACTS / f"lichtblick-{name}.png"
    browser.driver.save_screenshot(str(path))
    return Image.open(path).convert("RGB")


def panel(browser, kind):
    return browser.driver.find_element(By.CSS_SELECTOR, f'[data-testid^="panel-mouseenter-container {kind}!"]')


def pixels_near(image, box, colour, tolerance=40):
    """How many pixels of image's box are within tolerance of colour (each channel)."""
    region = image.crop(box)
    return sum(all(abs(a - b) <= tolerance for a, b in zip(p, colour)) for p in region.getdata())


def box_of(element):
    r = element.rect
    return (int(r["x"]), int(r["y"]), int(r["x"] + r["width"]), int(r["y"] + r["height"]))


def test_lichtblick_shows_and_drives_the_demo_over_the_foxglove_protocol(ros, bridge, lichtblick):
    master = ros.master()
    master.setParam("/lichtblick_test/speed", 1.5)
    port = master.getParam("/lichtblick_bridge/actual_foxglove_port")
    browser = Browser(SCREEN, flags=("--enable-unsafe-swiftshader",))
    try:
        driver = browser.driver
        driver.get(
            f"{lichtblick}/?ds=foxglove-websocket&ds.url=ws://127.0.0.1:{port}&layoutUrl={lichtblick}/layout.json"
        )
        wait_for(lambda: "turtlesim rosbridge (ROS 1)" in driver.page_source, 60, what="Lichtblick connected")

        # the 3D panel draws the turtle's URDF (its mesh, fetched from the bridge) where TF puts turtle1; the
        # image panel shows the camera; parameters are listed
        scene, image = panel(browser, "3D"), panel(browser, "Image")
        wait_for(
            lambda: pixels_near(shot(browser, "scene"), box_of(scene), SHELL) > 300,
            90,
            interval=2,
            what="the turtle's shell in the 3D panel",
        )
        wait_for(
            lambda: pixels_near(shot(browser, "scene"), box_of(image), SKY, 25) > 5000,
            30,
            interval=2,
            what="the camera's picture",
        )
        params = panel(browser, "Parameters")
        wait_for(lambda: "/lichtblick_test/speed" in params.text, 30, what="the parameters")

        # a parameter edited in the panel reaches the master
        row = params.find_element(By.XPATH, ".//tr[.//*[@title='/lichtblick_test/speed']]")
        field = row.find_element(By.CSS_SELECTOR, "input, textarea")
        field.send_keys(Keys.CONTROL, "a")
        field.send_keys("2.5")
        wait_for(
            lambda: row.find_elements(By.CSS_SELECTOR, "button[aria-label='Submit change']"),
            10,
            what="the submit button",
        )
        row.find_element(By.CSS_SELECTOR, "button[aria-label='Submit change']").click()
        wait_for(lambda: master.getParam("/lichtblick_test/speed") == 2.5, 15, what="the edit on the master")

        # a service call answered
        panel(browser, "CallService").find_element(By.CSS_SELECTOR, '[data-testid="call-service-button"]').click()
        wait_for(
            lambda: "{}" in panel(browser, "CallService").text.split("Response", 1)[-1], 15, what="/clear's response"
        )

        # a Twist published drives the turtle
        before = float(ros.run(["rostopic", "echo", "-n", "1", "/turtle1/pose/x"]).stdout.split()[0])
        publish = panel(browser, "Publish").find_element(By.XPATH, ".//button[normalize-space()='Publish']")
        for _ in range(5):
            ActionChains(driver).move_to_element(publish).click().perform()
            time.sleep(0.3)
        wait_for(
            lambda: float(ros.run(["rostopic", "echo", "-n", "1", "/turtle1/pose/x"]).stdout.split()[0]) != before,
            15,
            what="the turtle moved",
        )
        body = driver.find_element(By.TAG_NAME, "body").text
        assert "has changed during the server's runtime" not in body
        shot(browser, "after")
    except BaseException:
        shot(browser, "failed")
        raise
    finally:
        browser.quit()
