"""The page of ``tml serve`` in a real browser: headless Chromium from Debian's packages
(``chromium``, ``chromium-driver``), driven by Selenium, against a service flying the
embedded simulator.

The test uploads a mission with an error and sees the error's line, uploads a good one,
starts it, watches the vehicle's marker move and the task states change, pauses it (the
vehicle holds), resumes it, and sees the run complete; its screenshot is kept in
``test-artifacts/`` (or ``$TML_TEST_ARTIFACTS``). Skipped, saying why, only when no browser
can be had.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
import uvicorn
from serving import ROOT, SHORT, TYPO, FakeHangar, free_port, interrupted_run, simulated

from tml.serve.api import create_app
from tml.serve.service import Service, ServiceOptions
from tml.serve.storage import Storage, database_url

CHROMIUM, DRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
ARTIFACTS = Path(os.environ.get("TML_TEST_ARTIFACTS") or ROOT / "test-artifacts")
# A longer leg than SHORT's, so that the flight can be watched (and held) on its way.
LONG = SHORT.replace(b"(40,0,10)", b"(150,60,10)").replace(b"Short hop", b"Long hop")


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    webdriver = pytest.importorskip("selenium.webdriver")
    if not (shutil.which(CHROMIUM) and shutil.which(DRIVER)):
        pytest.skip("no headless browser: install Debian's chromium and chromium-driver")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    # As root Chromium needs --no-sandbox; with no network, background connections and
    # component updates only fail (docs/serve.md, testing the page).
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                 "--disable-quic", "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--window-size=1600,1000"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=webdriver.ChromeService(executable_path=DRIVER),
                              options=options)
    try:
        yield driver
    finally:
        driver.quit()


@contextlib.contextmanager
def served_page(service: Service) -> Iterator[str]:
    """``service`` served on a free port; its address. Stopped on leaving."""
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(create_app(service), host="127.0.0.1",
                                           port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    while not server.started and thread.is_alive():
        thread.join(0.05)
    try:
        yield f"http://127.0.0.1:{port}/"
    finally:
        server.should_exit = True
        thread.join(60)


@pytest.fixture
def page(tmp_path: Path) -> Iterator[str]:
    """A service on two simulated vehicles, served on a free port; its address."""
    with simulated(vehicles=2, speedup=8) as hangar:
        storage = Storage(database_url(None, tmp_path))
        service = Service(storage, hangar, ServiceOptions(stop_timeout=30))
        try:
            with served_page(service) as address:
                yield address
        finally:
            storage.close()


def wait(driver: Any, what: str, check: Any, timeout: float = 60) -> Any:
    """``check(driver)`` once it is true. The page redraws its lists and its map every
    second: an element found just before a redraw is gone after it (stale), and is looked
    for again."""
    from selenium.common.exceptions import StaleElementReferenceException
    from selenium.webdriver.support.ui import WebDriverWait

    return WebDriverWait(driver, timeout, poll_frequency=0.1,
                         ignored_exceptions=[StaleElementReferenceException]).until(
        lambda d: check(d), message=f"waiting for {what}")


def click(driver: Any, selector: str) -> None:
    from selenium.webdriver.common.by import By

    wait(driver, f"a click on {selector}",
         lambda d: d.find_element(By.CSS_SELECTOR, selector).click() or True)


def test_upload_fly_and_watch_a_mission_in_the_browser(browser: Any, page: str,
                                                       tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By

    driver = browser
    driver.get(page)
    wait(driver, "the vehicles' telemetry", lambda d: len(d.find_elements(
        By.CSS_SELECTOR, "#telemetry tbody tr")) == 2)

    # A mission with an error: the error is shown with its line, the line quoted.
    typo = tmp_path / "typo.xml"
    typo.write_bytes(TYPO)
    driver.find_element(By.ID, "mission-file").send_keys(str(typo))
    driver.find_element(By.ID, "upload").click()
    line = next(n for n, text in enumerate(TYPO.decode().splitlines(), 1) if "PIONT" in text)
    shown = wait(driver, "the validation error", lambda d: d.find_elements(
        By.CSS_SELECTOR, f"#upload-result .diagnostic[data-line='{line}']"))
    assert f"line {line}," in shown[0].text and "E201" in shown[0].text
    assert "GO_TO_PIONT" in shown[0].find_element(By.TAG_NAME, "pre").text

    # A good one, started on vehicle 1.
    good = tmp_path / "long.xml"
    good.write_bytes(LONG)
    driver.find_element(By.ID, "mission-file").clear()
    driver.find_element(By.ID, "mission-file").send_keys(str(good))
    driver.find_element(By.ID, "upload").click()
    wait(driver, "the upload", lambda d: "valid" in d.find_element(By.ID, "upload-result").text)
    wait(driver, "the mission in the list", lambda d: d.find_elements(
        By.CSS_SELECTOR, "#missions li.chosen"))
    click(driver, "#vehicle-choice input[value='1']")
    wait(driver, "vehicle 1 chosen", lambda d: d.find_element(
        By.CSS_SELECTOR, "#vehicle-choice input[value='1']").is_selected())
    click(driver, "#start")
    wait(driver, "the run to start", lambda d: "running" in d.find_element(
        By.ID, "run-status").text, timeout=120)

    # The take-off runs, then is done while the leg runs; the marker moves on the map.
    def task_state(d: Any, task: str) -> str:
        found = d.find_elements(By.CSS_SELECTOR,
                                f"#tasks li[data-task='{task}'] > .state[data-vehicle='1']")
        return str(found[0].text.split()[-1]) if found else ""

    wait(driver, "the take-off done", lambda d: task_state(d, "Up") == "done")
    wait(driver, "the leg running", lambda d: task_state(d, "Out") == "running")
    marker = "#map g.vehicle[data-vehicle='1']"
    before = float(wait(driver, "the marker", lambda d: d.find_element(
        By.CSS_SELECTOR, marker).get_attribute("data-north")))
    wait(driver, "the marker to move north", lambda d: float(d.find_element(
        By.CSS_SELECTOR, marker).get_attribute("data-north")) > before + 5)
    assert driver.find_elements(By.CSS_SELECTOR, "#map path.plan"), "the planned path is drawn"
    assert driver.find_elements(By.CSS_SELECTOR, "#map g.scale"), "the scale is drawn"
    assert driver.find_elements(By.CSS_SELECTOR, "#map g.north"), "the north arrow is drawn"

    # Pause: the vehicle holds (once it has braked, it stays where it is while its clock
    # runs on); resume: it flies on.
    click(driver, "#pause")
    wait(driver, "the run paused", lambda d: "paused" in d.find_element(By.ID, "run-status").text)
    wait(driver, "the leg still running", lambda d: task_state(d, "Out") == "running")
    def telemetry() -> dict[str, Any]:
        return dict(httpx.get(f"{page}vehicles/1").json())

    # Told to hold where it was, the vehicle brakes, comes back to that point and stays.
    told = telemetry()["time"]
    braked = wait(driver, "the vehicle to settle", lambda d: (
        lambda v: v if v["time"] > told + 20 else None)(telemetry()))
    later = wait(driver, "10 s of the vehicle's time",
                 lambda d: (lambda v: v if v["time"] > braked["time"] + 10 else None)(
                     telemetry()))
    assert later["position"] == pytest.approx(braked["position"], abs=0.5), "it holds"
    assert later["mode"] == braked["mode"]
    wait(driver, "the marker where the vehicle holds", lambda d: abs(float(d.find_element(
        By.CSS_SELECTOR, marker).get_attribute("data-north")) - later["position"][0]) < 0.5)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    driver.save_screenshot(str(ARTIFACTS / "serve-page-paused.png"))
    click(driver, "#resume")
    wait(driver, "the run resumed", lambda d: "running" in d.find_element(
        By.ID, "run-status").text)
    wait(driver, "the marker to move on", lambda d: float(d.find_element(
        By.CSS_SELECTOR, marker).get_attribute("data-north")) > later["position"][0] + 5)

    # The run completes: every task done, the track drawn, the outcome said.
    wait(driver, "the run to complete", lambda d: "completed" in d.find_element(
        By.ID, "run-status").text, timeout=180)
    wait(driver, "every task done", lambda d: [task_state(d, t) for t in ("Up", "Out", "Down")]
         == ["done"] * 3)
    assert driver.find_elements(By.CSS_SELECTOR, "#map path.track[data-vehicle='1']")
    assert "exit 0" in driver.find_element(By.ID, "run-status").text
    shot = ARTIFACTS / "serve-page.png"
    assert driver.save_screenshot(str(shot)) and shot.stat().st_size > 10_000


def test_an_interrupted_run_is_continued_from_the_page(browser: Any, tmp_path: Path) -> None:
    """A run the service was flying when it died: its Continue button starts the run that
    goes on from where it stood, shown at once, which completes without a second take-off."""
    from selenium.webdriver.common.by import By

    hangar = FakeHangar(count=1)
    storage = Storage(database_url(None, tmp_path))
    service = Service(storage, hangar, ServiceOptions(stop_timeout=30))
    mission_id = service.upload("short.xml", SHORT)["id"]
    old = interrupted_run(storage, hangar.fakes[0], mission_id)
    with served_page(service) as address:
        driver = browser
        driver.get(address)
        click(driver, f"#runs li[data-run='{old}']")
        wait(driver, "the interrupted run", lambda d: "interrupted" in d.find_element(
            By.ID, "run-status").text and d.find_element(By.ID, "continue").is_enabled())
        click(driver, "#continue")
        wait(driver, "the run that continues it to complete", lambda d: (
            "completed" in (status := d.find_element(By.ID, "run-status").text)
            and old not in status))
        states = {li.get_attribute("data-task"): li.find_element(By.CSS_SELECTOR,
                                                                 ".state").text.split()[-1]
                  for li in driver.find_elements(By.CSS_SELECTOR, "#tasks li[data-task]")}
        assert states == {"Up": "done", "Out": "done", "Down": "done"}
    storage.close()
