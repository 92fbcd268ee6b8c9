"""The built-in page's parameters (bridges/view/page), in headless Chromium as test_view_page.py:
a node process's parameters are listed, filtered by node, and one is set from the page; a value
out of range is refused with the reason among the server's messages."""
from __future__ import annotations

import os

import pytest
from selenium.webdriver.common.by import By
from test_view_page import wait_for
from test_view_params import MOTOR
from processes import wait_line


def parameter_values(driver) -> dict:
    """{"NODE.PARAMETER": value text} of the rows the page shows."""
    return driver.execute_script("""
        const shown = {};
        for (const row of document.querySelectorAll('#parameters tr[data-parameter]')) {
          if (!row.hidden) shown[row.dataset.parameter] = row.dataset.value;
        }
        return shown;""")


def set_from_page(driver, name: str, text: str) -> None:
    field = driver.find_element(By.CSS_SELECTOR, f'#parameters tr[data-parameter="{name}"] input')
    field.clear()
    field.send_keys(text)
    driver.find_element(By.CSS_SELECTOR,
                        f'#parameters tr[data-parameter="{name}"] button.set').click()


@pytest.fixture
def motor(namespace, children):
    process = children.python(MOTOR, dict(os.environ))
    wait_line(process, "ready")
    return process


def test_the_page_lists_parameters_and_sets_one(motor, view_server, browser):
    browser.get(view_server.http_url)
    shown = wait_for(browser, lambda d: len(values := parameter_values(d)) == 5 and values,
                     "motor's five parameters listed")
    assert shown["motor.max_speed"] == "1" and shown["motor.profile"] == "eco", shown
    assert shown["motor.gains"] == "[1,0.5,0]", shown

    set_from_page(browser, "motor.max_speed", "1.25")
    wait_for(browser, lambda d: parameter_values(d)["motor.max_speed"] == "1.25",
             "max_speed shown at its new value")
    set_from_page(browser, "motor.profile", "sport")
    wait_for(browser, lambda d: parameter_values(d)["motor.profile"] == "sport",
             "profile shown at its new value")

    set_from_page(browser, "motor.max_speed", "7")
    wait_for(browser, lambda d: "above the maximum 2" in d.find_element(By.ID, "log").text,
             "the refusal's reason among the server's messages")
    assert parameter_values(browser)["motor.max_speed"] == "1.25"

    # The node chooser: the only node, and back to every node.
    chooser = browser.find_element(By.ID, "parameter-node")
    assert [option.get_attribute("value")
            for option in chooser.find_elements(By.TAG_NAME, "option")] == ["", "motor"]
