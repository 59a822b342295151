"""The page in a real browser (headless Chromium driven by Selenium): it draws what native
`infer` draws with the same settings, keeps responding while it draws, and says clearly what is
wrong with a file that is no image. Run by scripts/web-tests.sh, which builds the page, serves it
and passes its address (WEB_URL) and the native program (INFER) here."""

import os
import subprocess
import time
from pathlib import Path

import pytest
from selenium import webdriver
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

ROOT = Path(__file__).resolve().parents[3]
PHOTO = ROOT / "assets" / "astronaut.jpg"
# A drawing at 500 paths takes seconds natively; the browser's single thread, more.
DRAW_TIMEOUT = 600


@pytest.fixture(scope="module")
def browser():
    options = webdriver.ChromeOptions()
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1280,1000",
                 "--force-device-scale-factor=1", "--hide-scrollbars"):
        options.add_argument(flag)
    service = webdriver.ChromeService(executable_path=os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver"))
    driver = webdriver.Chrome(options=options, service=service)
    driver.set_script_timeout(60)
    yield driver
    driver.quit()


@pytest.fixture
def page(browser):
    browser.get(os.environ["WEB_URL"])
    WebDriverWait(browser, 30).until(lambda d: d.execute_script("return document.readyState") == "complete")
    return browser


def state(driver):
    return driver.find_element(By.ID, "message").get_attribute("data-state")


def pick(driver, path):
    driver.find_element(By.ID, "file").send_keys(str(path))


def wait_drawn(driver):
    """Waits for the drawing to end; returns its state and how long the page's thread took, at
    most, to answer a script while the worker drew (the page must never freeze)."""
    slowest = 0.0
    deadline = time.monotonic() + DRAW_TIMEOUT
    while time.monotonic() < deadline:
        asked = time.monotonic()
        now = state(driver)
        slowest = max(slowest, time.monotonic() - asked)
        if now in ("done", "error"):
            return now, slowest
        time.sleep(0.1)
    pytest.fail(f"no drawing after {DRAW_TIMEOUT} s: {driver.find_element(By.ID, 'message').text}")


def downloaded_svg(driver):
    """The SVG the page's download link holds."""
    return driver.execute_async_script(
        "const done = arguments[arguments.length - 1];"
        "fetch(document.getElementById('download').href).then(r => r.text()).then(done);"
    )


def native_svg(tmp_path, *flags):
    out = tmp_path / "native.svg"
    subprocess.run([os.environ["INFER"], str(PHOTO), "-o", str(out), "--quiet", *flags], check=True)
    return out.read_text()


def test_the_page_draws_what_infer_draws_at_the_defaults(page, tmp_path):
    pick(page, PHOTO)
    outcome, slowest = wait_drawn(page)
    assert outcome == "done", page.find_element(By.ID, "message").text
    assert slowest < 1.0, f"the page froze for {slowest:.2f} s while drawing"
    svg = downloaded_svg(page)
    assert svg == native_svg(tmp_path)
    stats = page.find_element(By.ID, "stats").text
    assert " paths · " in stats and " dB PSNR · " in stats, stats
    print(f"\nbrowser: {stats}")
    if os.environ.get("SCREENSHOT"):
        page.save_screenshot(os.environ["SCREENSHOT"])


def test_the_controls_reach_the_job(page, tmp_path):
    for control in ("paths-auto", "curves"):
        page.find_element(By.ID, control).click()
    page.find_element(By.CSS_SELECTOR, "#fills option[value='flat']").click()
    pick(page, PHOTO)
    outcome, _ = wait_drawn(page)
    assert outcome == "done", page.find_element(By.ID, "message").text
    svg = downloaded_svg(page)
    assert svg == native_svg(tmp_path, "--paths", "auto", "--tolerance", "0", "--fills", "flat")


def test_a_file_that_is_no_image_gets_a_clear_message(page, tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("hello, not a picture\n")
    pick(page, notes)
    outcome, _ = wait_drawn(page)
    assert outcome == "error"
    assert page.find_element(By.ID, "message").text == "notes.txt: not an image in a known format"
    assert not page.find_element(By.ID, "download").is_displayed()
