"""Headless Chromium from Debian, driven by Selenium with Debian's chromedriver (Selenium must never
download a browser or a driver). Each browser gets a fresh profile that is removed afterwards."""

import json
import shutil
import tempfile
import threading
from urllib.parse import urlsplit

import pytest
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

from chromium import CHROMIUM_FLAGS
from fixtures import bridge_fixture
from harness import wait_for
from sensor_messages import CAMERA

SCREENS = {
    "desktop": {"width": 1280, "height": 800, "pixelRatio": 1},
    "phone": {"width": 390, "height": 844, "pixelRatio": 3},
}


class Browser:
    """One Chromium with its own profile, started with CHROMIUM_FLAGS and `flags`; `driver` is the Selenium
    WebDriver."""

    def __init__(self, screen, mobile=False, flags=()):
        self.profile = tempfile.mkdtemp(prefix="chromium-profile-")
        options = webdriver.ChromeOptions()
        options.binary_location = "/usr/bin/chromium"
        for flag in (*CHROMIUM_FLAGS, *flags):
            options.add_argument(flag)
        options.add_argument(f"--user-data-dir={self.profile}")
        options.add_argument(f"--window-size={screen['width']},{screen['height']}")
        options.set_capability("goog:loggingPrefs", {"performance": "ALL", "browser": "ALL"})
        if mobile:
            options.add_experimental_option("mobileEmulation", {"deviceMetrics": {**screen, "touch": True}})
        self.driver = webdriver.Chrome(service=Service(executable_path="/usr/bin/chromedriver"), options=options)
        if not mobile:  # the exact viewport, whatever the window decorations
            self.driver.execute_cdp_cmd(
                "Emulation.setDeviceMetricsOverride",
                {
                    "width": screen["width"],
                    "height": screen["height"],
                    "deviceScaleFactor": screen["pixelRatio"],
                    "mobile": False,
                },
            )
        self.driver.set_script_timeout(20)

    def network_urls(self):
        """Every URL the page asked for since the last call: HTTP requests and websockets
        (Chrome's performance log), plus the page's own resource timing entries."""
        urls = set()
        for entry in self.driver.get_log("performance"):
            message = json.loads(entry["message"])["message"]
            if message["method"] == "Network.requestWillBeSent":
                urls.add(message["params"]["request"]["url"])
            elif message["method"] == "Network.webSocketCreated":
                urls.add(message["params"]["url"])
        urls.update(self.driver.execute_script("return performance.getEntriesByType('resource').map(e => e.name)"))
        return urls

    def console_errors(self):
        return [e for e in self.driver.get_log("browser") if e["level"] == "SEVERE"]

    def quit(self):
        try:
            self.driver.quit()
        finally:
            shutil.rmtree(self.profile, ignore_errors=True)


class Page(Browser):
    """The control page loaded from the bridge, connected."""

    def __init__(self, url, screen, mobile, flags=()):
        super().__init__(screen, mobile, flags)
        self.url = url
        self.driver.get("about:blank")
        self.network_urls()  # forget the browser's own start-up requests
        self.driver.get(url)
        self.wait_state("connected")

    def el(self, element_id):
        return self.driver.find_element(By.ID, element_id)

    def js(self, script, *args):
        return self.driver.execute_script(script, *args)

    def click(self, selector, timeout=20):
        """Clicks the first element matching selector, found and clicked in one step: a list redrawn between a
        look-up and a click leaves no stale element, and a sticky header over the element does not take it."""
        wait_for(
            lambda: self.js("const e = document.querySelector(arguments[0]); if (e) e.click(); return !!e;", selector),
            timeout,
            what=f"{selector} to click",
        )

    def tab(self, name):
        """Clicks a console tab's button as a person does, and waits for its panel (a click the layout moved away
        from, with no error from the driver, fails here by name); returns the panel."""
        self.el(f"tab-button-{name}").click()
        wait_for(
            lambda: self.el(f"tab-{name}").is_displayed(), 5, what=f"the {name} tab shown after its button's click"
        )
        return self.el(f"tab-{name}")

    def state(self):
        return self.el("conn").get_attribute("data-state")

    def wait_state(self, state, timeout=30):
        wait_for(lambda: self.state() == state, timeout, what=f"connection indicator {state!r}")

    def fill(self, element_id, text):
        field = self.el(element_id)
        field.clear()
        field.send_keys(text)

    def pose(self, name="turtle1"):
        """The pose the page's world view holds for a turtle, or None."""
        return self.js("return window.turtleView.poses[arguments[0]] || null", name)

    def feedback(self):
        return self.el("feedback").text

    def foreign_urls(self):
        """URLs the page requested that are not its own origin (http or ws to the same host:port)."""
        own = urlsplit(self.url).netloc
        return sorted(
            u for u in self.network_urls() if not (urlsplit(u).scheme in ("http", "ws") and urlsplit(u).netloc == own)
        )


class Recorder:
    """Every message of one ROS topic, received in this process."""

    def __init__(self, rospy, topic, msg_class):
        self.messages = []
        self.lock = threading.Lock()
        self.sub = rospy.Subscriber(topic, msg_class, self._receive)

    def _receive(self, msg):
        with self.lock:
            self.messages.append(msg)

    @property
    def last(self):
        with self.lock:
            return self.messages[-1] if self.messages else None

    def count(self):
        with self.lock:
            return len(self.messages)


@pytest.fixture
def open_browser():
    """open_browser(screen=SCREENS["desktop"], mobile=False) -> Browser; closed after the test."""
    browsers = []

    def open_(screen=SCREENS["desktop"], mobile=False):
        browsers.append(Browser(screen, mobile))
        return browsers[-1]

    yield open_
    for browser in browsers:
        browser.quit()


@pytest.fixture(scope="module")
def sim(ros):
    """turtlesim_node on the private master, with turtle1 up."""
    proc = ros.spawn(["rosrun", "turtlesim", "turtlesim_node"], "turtlesim_node")
    try:
        proc.wait_output("Spawning turtle [turtle1]", timeout=60)
        yield proc
    finally:  # (the next module's turtle1 must be its own)
        proc.stop()


@pytest.fixture(scope="module")
def camera(ros, sim):
    """The demo camera (turtle_camera) publishing CAMERA and its compressed twin."""
    proc = ros.spawn(["rosrun", "turtlesim", "turtle_camera"], "turtle_camera")
    try:
        wait_for(lambda: CAMERA in dict(ros.master().getTopicTypes()), 30, what="the camera")
        yield proc
    finally:
        proc.stop()


# the page's URL on a bridge shared by the module's tests
bridge_url = bridge_fixture(yields="url", needs=("sim",))


@pytest.fixture
def open_page(bridge_url):
    """open_page("desktop"|"phone", url=the shared bridge, flags=more Chromium flags) -> Page, connected; closed
    after the test."""
    pages = []

    def open_(screen="desktop", url=None, flags=()):
        pages.append(Page(url or bridge_url, SCREENS[screen], mobile=screen == "phone", flags=flags))
        return pages[-1]

    yield open_
    for page in pages:
        page.quit()


@pytest.fixture
def listen(node):
    """listen(topic, msg_class) -> Recorder; unsubscribed after the test."""
    recorders = []

    def listen_(topic, msg_class):
        recorders.append(Recorder(node, topic, msg_class))
        return recorders[-1]

    yield listen_
    for recorder in recorders:
        recorder.sub.unregister()
