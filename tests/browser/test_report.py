"""The experiment report (report.html) in a headless Chromium, driven through Selenium.

The page is loaded from disk with the network out of reach; the tests check that it logs no
errors, that its animation plays, scrubs and switches runs, and that at a contact frame the drawn
whisker is bent away from its rest shape.

The report comes from $VIBRISSA_REPORT (a report.html) or is written here by the command line
(`vibrissa experiment e2 --particles 24 --report`; the binary is $VIBRISSA_BIN or
target/release/vibrissa). Chromium is /usr/bin/chromium with /usr/bin/chromedriver (or
$VIBRISSA_CHROMIUM and $VIBRISSA_CHROMEDRIVER). Without Chromium, Selenium or the binary the tests
skip, unless VIBRISSA_REQUIRE_BROWSER=1, when they fail. With $VIBRISSA_SCREENSHOT set, a
screenshot of the page at a contact frame is saved there.
"""

import math
import os
import pathlib
import shutil
import subprocess
import time

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
REQUIRED = os.environ.get("VIBRISSA_REQUIRE_BROWSER") == "1"
CHROMIUM = os.environ.get("VIBRISSA_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("VIBRISSA_CHROMEDRIVER", "/usr/bin/chromedriver")


def unavailable(why):
    """Skips, or fails when the browser test is required."""
    if REQUIRED:
        pytest.fail(f"{why} (VIBRISSA_REQUIRE_BROWSER=1)")
    pytest.skip(why)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    given = os.environ.get("VIBRISSA_REPORT")
    if given:
        path = pathlib.Path(given)
        if not path.is_file():
            unavailable(f"VIBRISSA_REPORT={given} is not a file")
        return path
    binary = pathlib.Path(os.environ.get("VIBRISSA_BIN", ROOT / "target" / "release" / "vibrissa"))
    if not binary.is_file():
        unavailable(f"{binary}: build the command line first (cargo build --release)")
    out = tmp_path_factory.mktemp("e2")
    subprocess.run(
        [binary, "experiment", "e2", "--particles", "24", "--report", "--out", out],
        check=True,
        capture_output=True,
    )
    return out / "report.html"


@pytest.fixture(scope="module")
def browser():
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.options import Options
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        unavailable("selenium is not installed (pip install selenium)")
    for path in (CHROMIUM, CHROMEDRIVER):
        if not (os.path.isfile(path) or shutil.which(path)):
            unavailable(f"{path} not found (apt-get install chromium chromium-driver)")
    options = Options()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1000,1300", "--hide-scrollbars"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    yield driver
    driver.quit()


@pytest.fixture()
def page(browser, report):
    browser.get(report.resolve().as_uri())
    browser.get_log("browser")  # start each test with an empty log
    return browser


def js(driver, expression):
    return driver.execute_script("return " + expression)


def wait_for(condition, seconds=5.0):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.05)
    return condition()


def test_the_page_loads_without_errors(browser, report):
    browser.get(report.resolve().as_uri())
    assert js(browser, "typeof window.vibrissaReport") == "object"
    severe = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert severe == []
    assert js(browser, "document.querySelectorAll('table.methods tbody tr').length") >= 9
    assert js(browser, "document.querySelectorAll('figure svg, figure img').length") >= 5


def test_play_advances_the_frame_and_pause_holds_it(page):
    assert js(page, "vibrissaReport.frame()") == 0
    assert js(page, "vibrissaReport.frames()") > 10
    page.find_element("id", "play").click()
    assert wait_for(lambda: js(page, "vibrissaReport.frame()") >= 3)
    assert js(page, "vibrissaReport.playing()")
    # The slider follows the frame: both read in one script, so that no frame passes between
    # the two readings however busy the machine is.
    frame, scrub = js(
        page, "[vibrissaReport.frame(), Number(document.getElementById('scrub').value)]"
    )
    assert abs(scrub - frame) <= 1
    page.find_element("id", "play").click()
    held = js(page, "vibrissaReport.frame()")
    time.sleep(0.3)
    assert js(page, "vibrissaReport.frame()") == held
    assert not js(page, "vibrissaReport.playing()")
    assert js(page, "document.getElementById('whisker').dataset.frame") == str(held)


def test_the_slider_scrubs_and_the_selector_switches_runs(page):
    page.execute_script(
        "var s = document.getElementById('scrub'); s.value = 20;"
        "s.dispatchEvent(new Event('input'));"
    )
    assert js(page, "vibrissaReport.frame()") == 20
    runs = js(page, "vibrissaReport.runs()")
    assert len(runs) == 4
    page.execute_script(
        "var r = document.getElementById('run'); r.value = '2';"
        "r.dispatchEvent(new Event('change'));"
    )
    assert js(page, "vibrissaReport.run()") == runs[2]
    assert js(page, "vibrissaReport.frame()") == 0


def dark_pixels_near(driver, canvas, point, radius=3):
    """How many pixels of `canvas` within `radius` px of `point` are dark (the whisker's)."""
    return js(
        driver,
        f"""(function () {{
            var c = document.getElementById('{canvas}').getContext('2d');
            var x = Math.round({point[0]}), y = Math.round({point[1]}), r = {radius};
            var d = c.getImageData(x - r, y - r, 2 * r + 1, 2 * r + 1).data, n = 0;
            for (var i = 0; i < d.length; i += 4) {{
                if (d[i] < 80 && d[i + 1] < 80 && d[i + 2] < 80) {{ n++; }}
            }}
            return n;
        }})()""",
    )


def test_at_a_contact_frame_the_drawn_whisker_is_bent(page):
    # At rest the drawn tip is the rest tip.
    page.execute_script("vibrissaReport.seek(0)")
    tip, rest = js(page, "vibrissaReport.drawnTip()"), js(page, "vibrissaReport.restTip()")
    assert math.dist(tip, rest) < 1.0
    contact = js(page, "vibrissaReport.contactFrames()")
    assert contact, "the run touches the box"
    frame = contact[len(contact) // 2]
    page.execute_script(f"vibrissaReport.seek({frame})")
    tip, rest = js(page, "vibrissaReport.drawnTip()"), js(page, "vibrissaReport.restTip()")
    # The tip is drawn well away from where it rests, and something dark is drawn there.
    assert math.dist(tip, rest) > 10.0, (tip, rest)
    assert dark_pixels_near(page, "whisker", tip) > 0
    assert dark_pixels_near(page, "whisker", rest) == 0
    # The particle filter's cloud is drawn beside it.
    assert js(page, "vibrissaReport.hasCloud()")
    blue = js(
        page,
        """(function () {
            var c = document.getElementById('cloud');
            var d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data, n = 0;
            for (var i = 0; i < d.length; i += 4) { if (d[i + 2] > d[i] + 40) { n++; } }
            return n;
        })()""",
    )
    assert blue > 15, "at least one dot of the cloud"
    shot = os.environ.get("VIBRISSA_SCREENSHOT")
    if shot:
        page.execute_script("document.getElementById('animation').scrollIntoView()")
        page.save_screenshot(shot)
        assert pathlib.Path(shot).stat().st_size > 10_000
    severe = [e for e in page.get_log("browser") if e["level"] == "SEVERE"]
    assert severe == []
