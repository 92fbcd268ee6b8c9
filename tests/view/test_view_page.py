"""The live view's built-in page (bridges/view/page), served by horus-view on the port of its
WebSocket and driven in headless Chromium (Debian's chromium and chromium-driver, through
python3-selenium): the topic list with types and rates, a node of a running scheduler, a live
value that changes, a plot that fills, and the links to Foxglove and Lichtblick. Without Chromium
this suite fails: scripts/install-deps installs it."""
from __future__ import annotations

import json
import os
import urllib.parse

from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

# A scheduler with one node, "pacer", publishing CmdVel at 50 Hz with a changing linear speed.
PACER = """
import math, horus
from horus.msg import CmdVel
count = [0]
def tick(node):
    count[0] += 1
    node.send("cmd_vel", CmdVel(stamp_nanos=count[0], linear=math.sin(count[0] / 10),
                                angular=0.5))
horus.run(horus.Node(name="pacer", tick=tick, rate=50, pubs={"cmd_vel": CmdVel}), tick_rate=50)
"""


def wait_for(driver, condition, what: str, limit: float = 30):
    return WebDriverWait(driver, limit).until(lambda d: condition(d), f"waiting for {what}")


def topic_rows(driver) -> dict:
    """{topic: {"type", "rate"}} as the page's topic list shows them."""
    return driver.execute_script("""
        const rows = {};
        for (const row of document.querySelectorAll('#topics tbody tr[data-topic]')) {
          rows[row.dataset.topic] = {type: row.querySelector('td.type').textContent,
                                     rate: row.dataset.rate === undefined ? null
                                                                          : Number(row.dataset.rate)};
        }
        return rows;""")


def node_rows(driver) -> list:
    """[{"text", "health"}] of the page's node list, read at once: the list is redrawn as the
    graph changes, so an element found earlier may be gone by the time it is read."""
    return driver.execute_script("""
        return [...document.querySelectorAll('#nodes tr[data-node]')].map(
            (row) => ({text: row.innerText, health: row.dataset.health}));""")


def test_the_page_lists_topics_and_nodes_and_shows_a_live_value_and_plot(view_server, children,
                                                                         browser):
    pacer = children.python(PACER, dict(os.environ))
    browser.get(view_server.http_url)

    rows = wait_for(browser, lambda d: (r := topic_rows(d)).get("cmd_vel", {}).get("rate") and r,
                    "cmd_vel listed with a measured rate")
    assert rows["cmd_vel"]["type"] == "horus.msg.CmdVel", rows
    # Wide bounds: a loaded machine slows the publisher; a rate in the wrong unit is far outside.
    assert 10 <= rows["cmd_vel"]["rate"] <= 100, f"a 50 Hz topic shown at {rows['cmd_vel']} msg/s"
    assert browser.find_element(By.ID, "connection").get_attribute("data-state") == "open"

    nodes = wait_for(browser, node_rows, "a node in the node list")
    assert any("pacer" in row["text"] and "cmd_vel" in row["text"] for row in nodes), nodes
    assert "publishing" in [row["health"] for row in nodes], nodes

    browser.find_element(By.CSS_SELECTOR, "#topics tr[data-topic='cmd_vel']").click()
    value = browser.find_element(By.ID, "value")
    first = json.loads(wait_for(browser, lambda d: value.text, "the newest value of cmd_vel"))
    assert first["angular"] == 0.5 and -1 <= first["linear"] <= 1, first
    second = wait_for(browser, lambda d: (shown := json.loads(value.text))["stamp_nanos"] !=
                      first["stamp_nanos"] and shown, "a newer value of cmd_vel")
    assert int(second["stamp_nanos"]) > int(first["stamp_nanos"]), (first, second)

    plot = browser.find_element(By.ID, "plot")
    wait_for(browser, lambda d: int(plot.get_attribute("data-points")) > 10, "plotted points")
    assert plot.get_attribute("data-field") == "linear"
    assert pacer.poll() is None, pacer.errors.text()


def test_the_viewer_links_carry_the_websocket_url_and_token(view_server, browser):
    browser.get(view_server.http_url + "?token=s3cret")
    expected = f"ws://127.0.0.1:{view_server.port}/?token=s3cret"
    for link in ("open-foxglove", "open-lichtblick"):
        href = browser.find_element(By.ID, link).get_attribute("href")
        query = urllib.parse.parse_qs(urllib.parse.urlsplit(href).query)
        assert query == {"ds": ["foxglove-websocket"], "ds.url": [expected]}, href
    assert browser.find_element(By.ID, "open-foxglove").get_attribute("href").startswith(
        "https://app.foxglove.dev/?")


# A frame tree: odom -> base_link set at 50 Hz, a static lidar under base_link.
FRAME_WRITER = """
import time, horus
tree = horus.FrameTree()
tree.set_static_transform("base_link", "lidar", (0.2, 0.0, 0.1))
step = 0
while True:
    tree.set_transform("odom", "base_link", (0.01 * step, 0.0, 0.0))
    step += 1
    time.sleep(0.02)
"""


def test_the_page_lists_the_frames_with_parents_and_rates(view_server, children, browser):
    children.python(FRAME_WRITER, dict(os.environ))
    browser.get(view_server.http_url)
    rows = wait_for(browser, lambda d: (r := d.execute_script("""
        const rows = {};
        for (const row of document.querySelectorAll('#frames tbody tr[data-frame]')) {
          rows[row.dataset.frame] = {parent: row.dataset.parent, static: row.dataset.static,
                                     rate: row.dataset.rate === undefined ? null
                                                                          : Number(row.dataset.rate)};
        }
        return rows;""")).get("base_link", {}).get("rate") and "lidar" in r and r,
                    "the frames listed with a measured rate")
    assert rows["lidar"] == {"parent": "base_link", "static": "true", "rate": None}, rows
    assert rows["base_link"]["parent"] == "odom" and rows["base_link"]["static"] == "false", rows
    assert 10 <= rows["base_link"]["rate"] <= 100, f"a 50 Hz frame shown at {rows['base_link']}"
