"""permessage-deflate with Chromium, which offers it on every websocket: the bridge takes the offer with no context
kept either way, and what it deflates (small messages on the loop, big ones on its deflate thread) Chromium unpacks
whole."""

import hashlib
import random

from fixtures import bridge_fixture
from harness import wait_for

ANSWER = "permessage-deflate; server_no_context_takeover; client_no_context_takeover"

OPEN = """
window.got = []; window.extensions = null;
const ws = new WebSocket(`ws://${location.host}/`);
ws.onopen = () => {
  window.extensions = ws.extensions;
  ws.send(JSON.stringify({op: "subscribe", topic: arguments[0], type: "std_msgs/String"}));
};
ws.onmessage = (event) => window.got.push(JSON.parse(event.data));
"""


# a bridge that deflates every message (use_compression), as it does a slow link's big ones
compressing_bridge = bridge_fixture("deflate_browser_bridge", yields="url", use_compression="true")


def test_chromium_is_answered_with_no_context_either_way(open_browser, bridge_url):
    browser = open_browser()
    browser.driver.get(bridge_url)
    browser.driver.execute_script(OPEN, "/deflate_browser/none")
    assert (
        wait_for(lambda: browser.driver.execute_script("return window.extensions"), 15, what="the websocket open")
        == ANSWER
    )


def test_what_the_bridge_deflates_chromium_unpacks_whole(open_browser, compressing_bridge, node):
    from std_msgs.msg import String

    rng = random.Random(7)
    words = ["pose", "scan", "map", "camera", "odom", "tf", "battery", "goal"]
    texts = [" ".join(rng.choice(words) + str(rng.randrange(1000)) for _ in range(n)) for n in (10, 60_000, 150_000)]
    publisher = node.Publisher("/deflate_browser/text", String, queue_size=10)
    browser = open_browser()
    try:
        browser.driver.get(compressing_bridge)
        browser.driver.execute_script(OPEN, "/deflate_browser/text")
        assert (
            wait_for(lambda: browser.driver.execute_script("return window.extensions"), 15, what="the websocket open")
            == ANSWER
        )
        wait_for(lambda: publisher.get_num_connections(), 15, what="the bridge to subscribe")
        for text in texts:  # 60 B, 500 kB and 1.2 MB: the big ones deflated on the bridge's deflate thread
            publisher.publish(String(text))
        digests = """return window.got.filter(m => m.op === "publish").map(m => m.msg.data)"""
        got = wait_for(
            lambda: len(browser.driver.execute_script(digests)) >= 3 and browser.driver.execute_script(digests),
            30,
            what="the three messages in the page",
        )
    finally:
        publisher.unregister()
    assert [hashlib.sha1(text.encode()).hexdigest() for text in got] == [
        hashlib.sha1(text.encode()).hexdigest() for text in texts
    ]
