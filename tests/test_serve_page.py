"""The page of ``tml serve`` in a real browser: headless Chromium from Debian's packages
(``chromium``, ``chromium-driver``), driven by Selenium, against a service flying the
embedded simulator.

One test uploads a mission with an error and sees the error's line, uploads a good one,
starts it, watches the vehicle's marker move and the task states change, pauses it (the
vehicle holds), resumes it, and sees the run complete. Another watches a fleet of two at
a phone's size and a laptop's, as an operator would read it. Screenshots are kept in
``test-artifacts/`` (or ``$TML_TEST_ARTIFACTS``). Skipped, saying why, only when no browser
can be had.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
import uvicorn
from mbtiles import NORTH_EAST, NORTH_WEST, SOUTH_EAST, SOUTH_WEST, quadrant_tiles, write_mbtiles
from serving import ROOT, SHORT, TYPO, FakeHangar, free_port, interrupted_run, simulated

from tml.serve.api import create_app
from tml.serve.service import Service, ServiceOptions
from tml.serve.storage import Storage, database_url
from tml.serve.tiles import TileSource, open_mbtiles, tile_url

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
def served_page(service: Service, tiles: TileSource | None = None) -> Iterator[str]:
    """``service`` served on a free port (its map over ``tiles``); its address. Stopped on
    leaving."""
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(create_app(service, tiles=tiles), host="127.0.0.1",
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


def confirm(driver: Any, word: str) -> None:
    """Answer the page's confirmation, which names the command, with its OK button."""
    from selenium.webdriver.common.by import By

    asked = wait(driver, f"the question before {word}", lambda d: d.find_elements(
        By.CSS_SELECTOR, "dialog#confirm[open]"))
    assert word in asked[0].text
    click(driver, "#confirm-ok")
    wait(driver, "the question closed", lambda d: not d.find_elements(
        By.CSS_SELECTOR, "dialog#confirm[open]"))


def test_upload_fly_and_watch_a_mission_in_the_browser(browser: Any, page: str,
                                                       tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By

    driver = browser
    driver.get(page)
    wait(driver, "the vehicles' telemetry", lambda d: len(d.find_elements(
        By.CSS_SELECTOR, "#telemetry .vehicle-card")) == 2)

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
    assert shown[0].find_element(By.TAG_NAME, "mark").text == "<action", "the column marked"

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
    confirm(driver, "Start")
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
    assert driver.find_elements(By.CSS_SELECTOR, "#map path.grid"), "on a grid"
    assert not driver.find_element(By.ID, "tile-map").is_displayed(), "no tiles: no tile map"

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
    confirm(driver, "Resume")
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


def test_rtl_from_a_vehicle_card_asks_then_brings_the_vehicle_home(browser: Any,
                                                                   page: str) -> None:
    from selenium.webdriver.common.by import By

    driver = browser
    driver.get(page)
    # Vehicle 1 flies a run (its own safe state: land) out along a long leg.
    mission = httpx.post(f"{page}missions", content=LONG,
                         headers={"Content-Type": "application/xml"}).json()["id"]
    run = httpx.post(f"{page}runs", json={"mission": mission, "vehicles": [1],
                                          "safe_state": "land"}).json()["id"]
    card = ".vehicle-card[data-vehicle='1']"

    def field(d: Any, name: str) -> str:
        return str(d.find_element(By.CSS_SELECTOR, f"{card} [data-field='{name}']").text)

    wait(driver, "vehicle 1 flying", lambda d: field(d, "armed") == "armed, flying"
         and float(httpx.get(f"{page}vehicles/1").json()["position"][2]) > 5, timeout=180)

    # RTL asks first, naming the vehicle and the run that holds it; cancelled, nothing is sent.
    click(driver, f"{card} button[data-command='rtl']")
    asked = wait(driver, "the question", lambda d: d.find_elements(
        By.CSS_SELECTOR, "dialog#confirm[open]"))
    assert "RTL vehicle 1?" in asked[0].text and f"Run {run}" in asked[0].text
    click(driver, "#confirm-cancel")
    wait(driver, "the question closed", lambda d: not d.find_elements(
        By.CSS_SELECTOR, "dialog#confirm[open]"))
    assert httpx.get(f"{page}vehicles/1").json()["command"] is None

    click(driver, f"{card} button[data-command='rtl']")
    confirm(driver, "RTL vehicle 1")
    wait(driver, "the card showing RTL", lambda d: field(d, "mode") == "RTL")
    wait(driver, "the card showing it landed", lambda d: field(d, "armed") in (
        "disarmed", "armed, on the ground"), timeout=180)
    ended = httpx.get(f"{page}runs/{run}").json()
    assert ended["status"] == "taken" and "operator command: rtl" in ended["reason"]
    wait(driver, "the card saying the command done", lambda d: field(d, "command").startswith(
        "RTL: done (mode RTL"))
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    driver.save_screenshot(str(ARTIFACTS / "serve-page-rtl.png"))


def test_an_interrupted_run_is_continued_from_the_page(browser: Any, tmp_path: Path) -> None:
    """A run the service was flying when it died: its Continue button starts the run that
    goes on from where it stood, shown at once, which completes without a second take-off."""
    from selenium.webdriver.common.by import By

    hangar = FakeHangar(count=1)
    storage = Storage(database_url(None, tmp_path))
    service = Service(storage, hangar, ServiceOptions(stop_timeout=30))
    mission_id = service.upload("short.xml", SHORT).id
    old = interrupted_run(storage, hangar.fakes[0], mission_id)
    with served_page(service) as address:
        driver = browser
        driver.get(address)
        click(driver, f"#runs li[data-run='{old}']")
        wait(driver, "the interrupted run", lambda d: "interrupted" in d.find_element(
            By.ID, "run-status").text and d.find_element(By.ID, "continue").is_enabled())
        click(driver, "#continue")
        confirm(driver, "Continue")
        wait(driver, "the run that continues it to complete", lambda d: (
            "completed" in (status := d.find_element(By.ID, "run-status").text)
            and old not in status))
        states = wait(driver, "the task states", lambda d: {
            li.get_attribute("data-task"): li.find_element(By.CSS_SELECTOR,
                                                           ".state").text.split()[-1]
            for li in d.find_elements(By.CSS_SELECTOR, "#tasks li[data-task]")})
        assert states == {"Up": "done", "Out": "done", "Down": "done"}
    storage.close()


# Two vehicles up, out side by side, holding there long enough to be paused on the way.
FLEET = b"""<mission name="Fleet hold">
  <task name="Up"><action name="TAKE_OFF"><argument name="altitude" value="10"/></action></task>
  <task name="Out">
    <action name="GO_TO_POINT"><argument name="point" value="(60,30,10)"/></action>
  </task>
  <task name="Hold"><action name="WAIT"><argument name="duration" value="300"/></action></task>
  <task name="Down"><action name="LAND"/></task>
</mission>
"""
SIZES = {"phone": (390, 844), "laptop": (1280, 900)}


def show_at(driver: Any, width: int, height: int) -> None:
    """The page's viewport at ``width`` x ``height`` CSS pixels (a phone's with its meta
    viewport below 600)."""
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {
        "width": width, "height": height, "deviceScaleFactor": 1, "mobile": width < 600})


def layout(driver: Any) -> dict[str, Any]:
    """What an operator would see wrong in the layout, measured by the browser."""
    return dict(driver.execute_script("""
        const over = (e) => e.scrollWidth > e.clientWidth + 1;
        const map = document.querySelector('#map').getBoundingClientRect();
        return {
          scrollWidth: document.documentElement.scrollWidth, innerWidth: innerWidth,
          map: [map.width, map.height],
          cut: [...document.querySelectorAll(
              '.vehicle-card, .vehicle-card dd, ul.log li, #run-bar, #upload-result pre')]
            .filter(over).map((e) => e.id || e.className || e.tagName),
          offscreen: [...document.querySelectorAll('.vehicle-card, #run-bar button')]
            .filter((e) => e.getBoundingClientRect().right > innerWidth + 1)
            .map((e) => e.id || e.className)};"""))


@pytest.mark.timeout(600)
def test_a_fleet_in_flight_on_a_phone_and_a_laptop(browser: Any, page: str,
                                                    tmp_path: Path) -> None:
    """Two vehicles flying one run, seen at a phone's size and a laptop's: nothing wider
    than the screen, a map of a real size, the legend in the tracks' colours, the task
    states labelled with their vehicles, the fleet in one frame, the events in mission
    time from the log's own stamps, and an abort that asks first."""
    from selenium.webdriver.common.by import By

    driver = browser
    client = httpx.Client(base_url=page, timeout=30)
    mission = client.post("/missions?filename=fleet.xml", content=FLEET,
                          headers={"Content-Type": "application/xml"}).json()["id"]
    run = client.post("/runs", json={"mission": mission, "vehicles": [1, 2]}).json()["id"]

    def holding(_d: Any) -> bool:
        tasks = client.get(f"/runs/{run}").json()["tasks"]
        return all(tasks[v]["Hold"] == "running" for v in ("1", "2"))

    # Paused while both hold out there: the mission's clock stands still, so nothing on the
    # page changes but the vehicles' telemetry, however long the checks below take.
    wait(driver, "both vehicles out and holding", holding, timeout=180)
    assert client.post(f"/runs/{run}/pause").status_code == 200
    log = [json.loads(line) for line in client.get(f"/runs/{run}/log").text.splitlines()]
    started = next(r["t"] for r in log if r["kind"] == "mission")
    take_off = next(r for r in log if r["kind"] == "autopilot" and r.get("vehicle") == 1
                    and r["text"] == "Takeoff")
    # Its mission time: the line's own, or (a log without it) its run time less the start's.
    take_off_at = take_off["mission_time"] if take_off.get("mission_time") is not None \
        else take_off["t"] - started

    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    typo = tmp_path / "typo.xml"
    typo.write_bytes(TYPO.replace(b'value="(40,0,10)"', b'value="(40,0,10)"' + b' ' * 40
                                  + b'xmlns:a="urn:a-line-longer-than-a-phone-is-wide"'))
    try:
        for name, (width, height) in SIZES.items():
            show_at(driver, width, height)
            driver.get(page)
            # The run flying is shown without being chosen.
            wait(driver, "the run shown by default", lambda d: run in (
                text := d.find_element(By.ID, "run-status").text) and "paused" in text)
            for vid in ("1", "2"):
                wait(driver, f"vehicle {vid}'s track and plan", lambda d, v=vid: all(
                    d.find_elements(By.CSS_SELECTOR, f"#map path.{kind}[data-vehicle='{v}']")
                    for kind in ("track", "plan")))
            wait(driver, "the messages of the log", lambda d: d.find_elements(
                By.CSS_SELECTOR, "#messages li"))

            # An error upload at this size: its lines wrap, none is cut.
            driver.find_element(By.ID, "mission-file").clear()
            driver.find_element(By.ID, "mission-file").send_keys(str(typo))
            driver.find_element(By.ID, "upload").click()
            wait(driver, "the validation error", lambda d: d.find_elements(
                By.CSS_SELECTOR, "#upload-result .diagnostic pre"))

            seen = layout(driver)
            assert seen["scrollWidth"] <= seen["innerWidth"], f"{name}: sideways scroll: {seen}"
            assert seen["cut"] == [] and seen["offscreen"] == [], f"{name}: {seen}"
            assert seen["map"][1] > (300 if name == "phone" else 500), f"{name}: {seen['map']}"

            # The legend tells each vehicle's colour as its track and plan are drawn, and
            # the flown and planned styles apart.
            def styles(d: Any, vid: str) -> dict[str, Any]:
                keys = d.find_elements(By.CSS_SELECTOR, f"#legend li[data-vehicle='{vid}'] line")
                track = d.find_element(By.CSS_SELECTOR, f"#map path.track[data-vehicle='{vid}']")
                plan = d.find_element(By.CSS_SELECTOR, f"#map path.plan[data-vehicle='{vid}']")
                return {"keys": [(k.get_attribute("stroke"),
                                  bool(k.get_attribute("stroke-dasharray"))) for k in keys],
                        "track": (track.get_attribute("stroke"),
                                  bool(track.get_attribute("stroke-dasharray"))),
                        "plan": (plan.get_attribute("stroke"),
                                 bool(plan.get_attribute("stroke-dasharray")))}

            colours = {}
            for vid in ("1", "2"):
                drawn = wait(driver, f"vehicle {vid}'s styles", lambda d, v=vid: styles(d, v))
                colour = drawn["track"][0]
                assert drawn["keys"] == [(colour, False), (colour, True)], drawn
                assert drawn["track"] == (colour, False) and drawn["plan"] == (colour, True)
                colours[vid] = colour
            assert colours["1"] != colours["2"], "each vehicle its own colour"

            # Task states say whose they are.
            for vid in ("1", "2"):
                badges = wait(driver, "the task badges", lambda d, v=vid: [b.text for b in (
                    d.find_elements(By.CSS_SELECTOR, f"#tasks .state[data-vehicle='{v}']"))])
                assert len(badges) == 4 and all(b.startswith(f"vehicle {vid}: ")
                                                for b in badges), badges

            # One frame: vehicle 2's home is 5 m east of vehicle 1's (the simulator boots a
            # fleet in a row), not on top of it.
            homes = wait(driver, "the homes", lambda d: {
                h.get_attribute("data-vehicle"): (float(h.get_attribute("data-north")),
                                                  float(h.get_attribute("data-east")))
                for h in d.find_elements(By.CSS_SELECTOR, "#map circle.home")})
            assert homes["1"] == pytest.approx((0.0, 0.0), abs=0.05)
            assert homes["2"] == pytest.approx((0.0, 5.0), abs=0.1)

            # Mission time, from the log's own stamp, the same at every load.
            said = wait(driver, "the take-off message", lambda d: next(
                (li.find_element(By.CSS_SELECTOR, ".t").text
                 for li in d.find_elements(By.CSS_SELECTOR, "#messages li")
                 if "vehicle 1: Takeoff" in li.text), None))
            assert float(said.removesuffix(" s")) == pytest.approx(take_off_at, abs=0.051)
            driver.execute_script("window.scrollTo(0, 0)")
            shot = ARTIFACTS / f"page-{width}x{height}.png"
            assert driver.save_screenshot(str(shot)) and shot.stat().st_size > 10_000

        # Abort asks first: cancelled, nothing is sent; confirmed, the run aborts.
        click(driver, "#abort")
        asked = wait(driver, "the question", lambda d: d.find_elements(
            By.CSS_SELECTOR, "dialog#confirm[open]"))
        assert "Abort" in asked[0].text and "vehicles 1, 2" in asked[0].text
        click(driver, "#confirm-cancel")
        wait(driver, "the question closed", lambda d: not d.find_elements(
            By.CSS_SELECTOR, "dialog#confirm[open]"))
        assert client.get(f"/runs/{run}").json()["status"] == "paused"
        assert not [r for r in map(json.loads, client.get(f"/runs/{run}/log").text.splitlines())
                    if r["kind"] == "safety"], "no safe state was commanded"
        click(driver, "#abort")
        confirm(driver, "Abort")
        wait(driver, "the run aborted", lambda d: "aborted" in d.find_element(
            By.ID, "run-status").text, timeout=180)
    finally:
        driver.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
        client.close()


# --- the map over tiles ----------------------------------------------------------------------

@contextlib.contextmanager
def tiled_page(tmp_path: Path, tiles: Any) -> Iterator[tuple[str, Any]]:
    """A service on one simulated vehicle, its map over the tiles ``tiles(home)`` gives
    (home: the vehicle's, once known); its address and that home."""
    with simulated(vehicles=1, speedup=8) as hangar:
        wake = threading.Event()
        hangar.subscribe(wake)
        vehicle = hangar.vehicles[1]
        for _ in range(600):  # news comes several times a second: at most a minute or so
            if vehicle.state().home is not None:
                break
            hangar.wait(wake, 0.5)
        home = vehicle.state().home
        assert home is not None, "the simulated vehicle says where its home is"
        storage = Storage(database_url(None, tmp_path))
        service = Service(storage, hangar, ServiceOptions(stop_timeout=30))
        try:
            with served_page(service, tiles(home)) as address:
                yield address, home
        finally:
            storage.close()


def colours_around(driver: Any, selector: str, offset: int) -> dict[str, tuple[int, ...]]:
    """The colours of the screenshot ``offset`` pixels diagonally off the centre of the
    element ``selector`` (north-east, north-west, south-east, south-west of it)."""
    import io

    from PIL import Image

    x, y = driver.execute_script(
        "const r = document.querySelector(arguments[0]).getBoundingClientRect();"
        "return [r.left + r.width / 2, r.top + r.height / 2];", selector)
    shot = Image.open(io.BytesIO(driver.get_screenshot_as_png())).convert("RGB")
    ratio = shot.width / driver.execute_script("return innerWidth;")
    at = {"north-east": (offset, -offset), "north-west": (-offset, -offset),
          "south-east": (offset, offset), "south-west": (-offset, offset)}
    return {name: shot.getpixel((round((x + dx) * ratio), round((y + dy) * ratio)))
            for name, (dx, dy) in at.items()}


def test_the_map_shows_an_mbtiles_file_under_the_mission_at_the_right_place(
        browser: Any, tmp_path: Path) -> None:
    """Tiles made here, coloured by quadrant around the vehicle's home (Web Mercator,
    computed by the test), served from an MBTiles file: around the home marker the page
    draws, each quadrant shows its own colour, so the tiles are under the mission where
    they belong (a row not flipped, or a tile misplaced, shows another colour)."""
    from selenium.webdriver.common.by import By

    def tiles(home: Any) -> TileSource:
        path = write_mbtiles(tmp_path / "field.mbtiles", quadrant_tiles(
            home.latitude, home.longitude, range(17, 21)), {"attribution": "Test field"})
        return open_mbtiles(path)

    expected = {"north-east": NORTH_EAST, "north-west": NORTH_WEST,
                "south-east": SOUTH_EAST, "south-west": SOUTH_WEST}
    home = "#tile-map path.home[data-vehicle='1']"
    seen: dict[str, Any] = {}

    def settled(d: Any) -> bool:
        seen.update(colours_around(d, home, 30))
        return all(max(abs(a - b) for a, b in zip(seen[k], colour, strict=True)) <= 8
                   for k, colour in expected.items())

    driver = browser
    with tiled_page(tmp_path, tiles) as (page, _home):
        client = httpx.Client(base_url=page, timeout=30)
        try:
            mission = client.post("/missions?filename=long.xml", content=LONG,
                                  headers={"Content-Type": "application/xml"}).json()["id"]
            assert client.post("/runs", json={"mission": mission, "vehicles": [1]}
                               ).status_code == 201
            for name, (width, height) in SIZES.items():
                show_at(driver, width, height)
                driver.get(page)
                wait(driver, "the planned path over the tiles", lambda d: d.find_elements(
                    By.CSS_SELECTOR, "#tile-map path.plan[data-vehicle='1']"))
                wait(driver, "the vehicle over the tiles", lambda d: d.find_elements(
                    By.CSS_SELECTOR, "#tile-map .vehicle[data-vehicle='1']"))
                assert not driver.find_element(By.ID, "map").is_displayed()
                assert driver.find_element(By.ID, "frame").text == \
                    "Over the tiles of the --tiles file, north up."
                assert "Test field" in driver.find_element(
                    By.CSS_SELECTOR, "#tile-map .leaflet-control-attribution").text
                assert driver.find_elements(By.CSS_SELECTOR, "#tile-map .leaflet-control-scale")
                assert driver.find_elements(By.CSS_SELECTOR, "#tile-map svg.north")
                driver.execute_script(
                    "document.querySelector('#tile-map').scrollIntoView({block: 'center'})")
                # Tiles fade in: wait for the colours to settle, then they must be these.
                try:
                    wait(driver, "the quadrants' colours around home", settled, timeout=30)
                except Exception:
                    pytest.fail(f"{name}: around home the tiles show {seen}, not {expected}")
                ARTIFACTS.mkdir(parents=True, exist_ok=True)
                shot = ARTIFACTS / f"serve-page-tiles-{name}.png"
                assert driver.save_screenshot(str(shot)) and shot.stat().st_size > 10_000
                assert driver.find_element(By.ID, "tile-problem").is_displayed() is False
        finally:
            driver.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
            client.close()


@contextlib.contextmanager
def tile_server(answer: bool) -> Iterator[str]:
    """A tile server on a free port that answers every request 500 (``answer``), or one
    that takes connections and never answers; its URL template."""
    import http.server
    import socket

    class Failing(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            self.send_error(500, "tile store down")

        def log_message(self, *args: Any) -> None:
            pass

    if answer:
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Failing)
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        try:
            yield f"http://127.0.0.1:{server.server_address[1]}/{{z}}/{{x}}/{{y}}.png"
        finally:
            server.shutdown()
            server.server_close()
        return
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(64)  # the kernel takes the connections; no one ever answers
        yield f"http://127.0.0.1:{silent.getsockname()[1]}/{{z}}/{{x}}/{{y}}.png"


@pytest.mark.parametrize(("answer", "said"), [
    (True, "The tiles from 127.0.0.1:{port} do not load ("),
    (False, "127.0.0.1:{port} has not answered for "),
])
def test_a_tile_server_that_fails_is_said_and_the_mission_is_drawn_on(
        browser: Any, tmp_path: Path, answer: bool, said: str) -> None:
    from selenium.webdriver.common.by import By

    driver = browser
    with tile_server(answer) as url:
        port = url.split(":")[2].split("/")[0]
        with tiled_page(tmp_path, lambda _home: tile_url(url, "Nobody")) as (page, _home):
            driver.get(page)
            problem = wait(driver, "the tiles' problem said", lambda d: (lambda e: e.text if (
                e.is_displayed() and e.text) else None)(d.find_element(By.ID, "tile-problem")))
            assert problem.startswith(said.format(port=port)), problem
            assert problem.endswith("the mission is drawn without them.") or \
                problem.endswith("the mission is drawn without tiles."), problem
            # Nothing lost: the vehicle and its home are drawn, the map can be used.
            assert driver.find_elements(By.CSS_SELECTOR, "#tile-map .vehicle[data-vehicle='1']")
            assert driver.find_elements(By.CSS_SELECTOR, "#tile-map path.home")
            assert driver.find_elements(By.CSS_SELECTOR, "#telemetry .vehicle-card")
