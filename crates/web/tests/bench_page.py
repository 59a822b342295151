"""The page's drawing time against native `infer` on one thread, image by image (run by
scripts/web-bench.sh, which builds and serves the page and passes WEB_URL and INFER). The page's
figure is the worker's, from the image's bytes to the SVG (decoding included; the module's
download and start, and the first drawing's reading of the weights, excluded by a warm-up
drawing); native is `infer --metrics`' `seconds.total`. Medians of ROUNDS runs (default 3)."""

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from selenium import webdriver
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

sys.path.insert(0, str(Path(__file__).parent))
from test_page import PHOTO, pick, state  # noqa: E402  (the tests' own machinery)

ROUNDS = int(os.environ.get("ROUNDS", "3"))
DRAW_TIMEOUT = 600


def draw(driver, path):
    """Feeds `path` to the page and returns the seconds the page shows for it."""
    # The page clears its figure only once it has read the file: clear it first, so that the
    # wait below is for this drawing's.
    driver.execute_script("document.getElementById('stats').textContent = ''")
    driver.find_element(By.ID, "file").clear()
    pick(driver, path)
    WebDriverWait(driver, DRAW_TIMEOUT, poll_frequency=0.05).until(
        lambda d: state(d) in ("done", "error") and d.find_element(By.ID, "stats").text)
    stats = driver.find_element(By.ID, "stats").text
    if state(driver) != "done":
        sys.exit(f"{path}: {driver.find_element(By.ID, 'message').text}")
    return float(stats.rsplit("·", 1)[1].strip().removesuffix(" s"))


def native(path):
    with tempfile.TemporaryDirectory() as folder:
        metrics = Path(folder) / "m.json"
        subprocess.run([os.environ["INFER"], str(path), "-o", str(Path(folder) / "out.svg"), "--quiet",
                        "--metrics", str(metrics)], check=True, env={**os.environ, "RAYON_NUM_THREADS": "1"})
        return json.loads(metrics.read_text())["seconds"]["total"]


def main(images):
    options = webdriver.ChromeOptions()
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu"):
        options.add_argument(flag)
    service = webdriver.ChromeService(executable_path=os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver"))
    driver = webdriver.Chrome(options=options, service=service)
    try:
        driver.get(os.environ["WEB_URL"])
        WebDriverWait(driver, 30).until(lambda d: d.execute_script("return document.readyState") == "complete")
        draw(driver, PHOTO)  # the warm-up: the first drawing reads the networks' weights
        totals = [0.0, 0.0]
        for image in images:
            page = statistics.median(draw(driver, Path(image).resolve()) for _ in range(ROUNDS))
            local = statistics.median(native(image) for _ in range(ROUNDS))
            totals = [totals[0] + page, totals[1] + local]
            print(f"{Path(image).stem}\tpage {page:.2f} s\tnative {local:.2f} s\tratio {page / local:.2f}", flush=True)
        print(f"all\tpage {totals[0]:.2f} s\tnative {totals[1]:.2f} s\tratio {totals[0] / totals[1]:.2f}")
    finally:
        driver.quit()


if __name__ == "__main__":
    main(sys.argv[1:])
