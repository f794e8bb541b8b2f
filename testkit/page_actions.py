"""What a person does on the console page, for the browser tests and the page bench alike (a page: an object with
`driver`, Selenium's WebDriver, and `js(script, *args)`)."""

from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.common.by import By

from harness import wait_for


def text_of(page, selector):
    """The displayed text of the first element `selector` finds, or "" if none. The page may replace that element
    between finding it and reading it (a table redrawn as messages come): it is then found again."""
    while True:
        found = page.driver.find_elements(By.CSS_SELECTOR, selector)
        try:
            return found[0].text if found else ""
        except StaleElementReferenceException:
            continue


def open_topic(page, topic):
    """Opens a topic from the Topics tab's list, as a person clicks its name."""
    page.js("document.getElementById('tab-button-topics').click()")  # (a click, wherever the page is scrolled)
    click = f"""const button = document.querySelector('#tab-topics tr[data-topic="{topic}"] button');
                if (button) button.click();
                return Boolean(button);"""
    wait_for(lambda: page.js(click), 20, what=f"{topic} listed")


def open_viewer(page, topic, viewer):
    """Opens topic and shows its viewer; returns the CSS selector of the viewer's area."""
    open_topic(page, topic)
    opened = f'.open-topic[data-topic="{topic}"]'
    button = f'{opened} button.view[data-viewer="{viewer}"]'
    wait_for(lambda: page.driver.find_elements(By.CSS_SELECTOR, button), 10, what=f"the {viewer} viewer offered")
    page.js("document.querySelector(arguments[0]).click()", button)
    return f"{opened} .viewer"
