"""The console's tools (issue 23): the bag recorder, dynamic_reconfigure and actions, each driven in headless
Chromium as a person uses it, against a real bridge (with its bag recorder on), turtlesim and the test nodes of
test/nodes/; and the view kept in the address across a reload and a copied link."""
import urllib.request
from pathlib import Path

import pytest
from selenium.webdriver.common.by import By

from harness import ARTIFACTS, start_bridge, wait_for

NODES = Path(__file__).resolve().parent.parent / "nodes"


@pytest.fixture(scope="module")
def bag_folder(tmp_path_factory):
    return tmp_path_factory.mktemp("bags")


@pytest.fixture(scope="module")
def bridge_url(ros, sim, bag_folder):
    """This module's bridge records bags (the shared one of conftest.py does not)."""
    proc, port = start_bridge(ros, node_name="rosbridge_tools", bag_folder=str(bag_folder))
    yield f"http://127.0.0.1:{port}/"
    proc.stop()


def tab(page, name):
    page.el(f"tab-button-{name}").click()
    return page.el(f"tab-{name}")


def text_of(page, selector):
    found = page.driver.find_elements(By.CSS_SELECTOR, selector)
    return found[0].text if found else ""


def click(page, selector):
    """Clicks the first element matching selector, found and clicked in one step (lists are redrawn)."""
    wait_for(lambda: page.js("const e = document.querySelector(arguments[0]); if (e) e.click(); return Boolean(e);",
                             selector), 20, what=f"{selector} to click")


def shot(page, name):
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.driver.save_screenshot(str(ARTIFACTS / f"{name}.png"))


def bag_rows(page):
    return page.js("""return [...document.querySelectorAll('#tab-bags .bag-list tr[data-bag]')].map(r => ({
        name: r.dataset.bag, size: r.querySelector('.bag-size').textContent, href: r.querySelector('a').href}))""")


# ---- bags ------------------------------------------------------------------------------------------------------

def test_record_two_seconds_of_the_pose_and_download_the_bag(open_page):
    page = open_page()
    tab(page, "bags")
    click(page, '#tab-bags input[type=checkbox][value="/turtle1/pose"]')
    assert "bag=%2Fturtle1%2Fpose" in page.driver.current_url
    click(page, "#tab-bags .bag-start")
    wait_for(lambda: "Recording" in text_of(page, "#tab-bags .bag-recording"), 10, what="the recording shown")
    wait_for(lambda: " 0 messages" not in text_of(page, "#tab-bags .bag-recording"), 10, what="messages counted")
    page.js("return new Promise(r => setTimeout(r, 2000))")
    shot(page, "bags-recording-desktop")
    click(page, "#tab-bags .bag-stop")
    wait_for(lambda: "Last:" in text_of(page, "#tab-bags .bag-last"), 10, what="the last recording's line")
    last = text_of(page, "#tab-bags .bag-last")
    messages = int(last.split(", ")[1].split(" messages")[0])
    assert 80 < messages < 400  # 62.5 Hz for about 2 s (and the time to click)
    assert "0 dropped" in last
    rows = wait_for(lambda: [r for r in bag_rows(page) if "recording" not in r["size"] and r["size"] != "0 B"] or None,
                    10, what="the bag listed with its size")
    bag = rows[0]
    assert bag["name"].endswith(".bag") and ("kB" in bag["size"] or "MB" in bag["size"])
    assert bag["href"].endswith(f"/bags/{bag['name']}")
    with urllib.request.urlopen(bag["href"], timeout=10) as answer:
        assert answer.read(13) == b"#ROSBAG V2.0\n"
    assert page.console_errors() == []


def test_black_box_save_and_delete_with_confirm(open_page, bag_folder):
    page = open_page()
    tab(page, "bags")
    click(page, '#tab-bags input[type=checkbox][value="/turtle1/pose"]')
    click(page, "#tab-bags .blackbox-keep")
    wait_for(lambda: "messages" in text_of(page, "#tab-bags .blackbox-state")
             and not text_of(page, "#tab-bags .blackbox-state").split(": ")[-1].startswith("0 "), 10,
             what="the black box filling")
    before = {r["name"] for r in bag_rows(page)}
    click(page, "#tab-bags .blackbox-save")
    wait_for(lambda: "saved" in text_of(page, "#tab-bags .bag-result"), 10, what="saved")
    saved = wait_for(lambda: [r for r in bag_rows(page) if r["name"] not in before and r["name"].startswith("blackbox")]
                     or None, 10, what="the black box's bag listed")[0]
    assert (bag_folder / saved["name"]).read_bytes().startswith(b"#ROSBAG V2.0")
    shot(page, "bags-desktop")
    click(page, "#tab-bags .blackbox-off")
    # Delete asks first: Cancel keeps the bag, Delete removes it
    row = f'#tab-bags tr[data-bag="{saved["name"]}"]'
    click(page, f"{row} .bag-delete")
    assert "cannot be undone" in text_of(page, f"{row} .confirm")
    click(page, f"{row} .confirm .cancel")
    assert (bag_folder / saved["name"]).exists()
    click(page, f"{row} .bag-delete")
    click(page, f"{row} .confirm .yes")
    wait_for(lambda: not (bag_folder / saved["name"]).exists(), 10, what="the bag deleted")
    wait_for(lambda: saved["name"] not in {r["name"] for r in bag_rows(page)}, 10, what="the bag gone from the list")


def test_a_bridge_without_recorder_says_how_to_turn_it_on(ros, open_page):
    proc, port = start_bridge(ros, node_name="rosbridge_nobags")
    try:
        page = open_page(url=f"http://127.0.0.1:{port}/?tab=bags")
        wait_for(lambda: "bag_folder" in text_of(page, "#tab-bags .bag-off"), 10, what="the recorder off, said")
        assert not page.el("tab-bags").find_element(By.CSS_SELECTOR, ".bag-tools").is_displayed()
    finally:
        proc.stop()


@pytest.mark.parametrize("screen", ["desktop", "phone"])
def test_bags_screenshots(open_page, screen):
    page = open_page(screen)
    tab(page, "bags")
    click(page, '#tab-bags input[type=checkbox][value="/turtle1/pose"]')
    wait_for(lambda: text_of(page, "#tab-bags .bag-list tbody"), 10, what="the bags listed")
    page.js("document.querySelector('.console').scrollIntoView()")
    shot(page, f"tools-bags-{screen}")
    assert page.console_errors() == []
