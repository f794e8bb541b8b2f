"""A page served without its libraries (web/vendor/ missing: a clone where tools/setup was not run) says what
is missing and how to get it, instead of "Connecting…" forever; the bridge says so in its log when it starts."""

import shutil

import pytest

from fixtures import From, bridge_fixture
from harness import REPO, wait_for


@pytest.fixture
def web_root(tmp_path):
    """The page's folder without its libraries."""
    root = tmp_path / "web"
    shutil.copytree(REPO / "web", root, ignore=shutil.ignore_patterns("vendor", "node_modules"))
    return root


bare_bridge = bridge_fixture("bare_bridge", scope="function", yields="bridge", web_root=From("web_root"))


def test_a_page_without_its_libraries_says_what_is_missing(sim, open_browser, bare_bridge):
    bridge = bare_bridge.proc
    wait_for(lambda: "roslib.min.js" in bridge.output(), 10, what="the bridge's warning")
    warning = next(line for line in bridge.output().splitlines() if "roslib.min.js" in line)
    assert "WARN" in warning and "uPlot.esm.js" in warning and "bash tools/setup" in warning
    browser = open_browser()
    browser.driver.get(bare_bridge.url)
    banner = lambda: browser.driver.execute_script("return document.body.innerText")
    wait_for(lambda: "could not be loaded" in banner(), 10, what="the page's message")
    assert "roslib.min.js, uPlot.esm.js, uPlot.min.css could not" in banner() and "bash tools/setup" in banner()
    assert "Connecting" not in browser.driver.execute_script("return document.getElementById('conn').innerText")
