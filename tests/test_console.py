"""`rig console` driven in a real headless browser (Debian's chromium + chromedriver, selenium).

The console serves the simulated rig (`--sim`) from a thread of this process; the page is
driven as a user would: the live frame updates, a jog button moves the stage and the force
trace responds, STOP halts a move, a second browser is refused control, and the run browser
shows frame N and its wrench for a run recorded here. Screenshots go to docs/img/.

scripts/setup.sh installs chromium and chromium-driver where they are missing; without them
these tests skip locally and fail under CI (CI=true), so a missing install cannot pass silently.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from acquisition import schema as S
from acquisition.run_file import open_for_reading
from cli.console.launch import console_options
from cli.console.server import serving_in_thread

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
IMG = ROOT / "docs" / "img"
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
WAIT_S = 60.0  # generous: two shared cores, a contact solve per frame


def _need_browser():
    if CHROMIUM and CHROMEDRIVER:
        return
    if os.environ.get("CI"):
        pytest.fail("chromium / chromedriver missing on CI: scripts/setup.sh installs them")
    pytest.skip("chromium and chromium-driver are not installed (bash scripts/setup.sh installs them)")


def new_browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1300"):
        options.add_argument(arg)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


def wait_for(driver, condition, message: str, timeout_s: float = WAIT_S):
    from selenium.webdriver.support.ui import WebDriverWait

    return WebDriverWait(driver, timeout_s, poll_frequency=0.05).until(lambda d: condition(d), message)


def page(driver, expr: str):
    return driver.execute_script(f"return {expr};")


QUICK_CHANGES = (
    ('name = "sphere10mm"', 'name = "console-quick"'),
    ("max_depth_mm = 1.6", "max_depth_mm = 0.4"),
    ("depth_step_mm = 0.4", "depth_step_mm = 0.4"),
    ("shear_mm = 2.0", "shear_mm = 0.2"),
    ("twist_deg = 5.0", "twist_deg = 1.0"),
    ("speed_mm_s = 0.01", "speed_mm_s = 0.2"),
    ("twist_speed_deg_s = 0.25", "twist_speed_deg_s = 2.0"),
)


def record_quick_run(folder: Path) -> Path:
    """A short simulated protocol run into ``folder`` (a press, a shear and a twist)."""
    from acquisition.executor import Acquisition
    from cli.simulated import monitor_interval_s, simulated_rig_for
    from protocols.plan import Plan
    from protocols.spec import load_protocol

    text = load_protocol("sphere10mm").text
    for old, new in QUICK_CHANGES:
        assert old in text, old
        text = text.replace(old, new)
    spec = folder / "console-quick.toml"
    spec.write_text(text)
    protocol = load_protocol(spec)
    out = folder / "console-quick.h5"
    with simulated_rig_for(protocol) as (rig, _sim, header):
        result = Acquisition(rig, Plan.of(protocol), monitor_interval_s=monitor_interval_s(protocol)).run(
            out, header=header
        )
    assert result.status == "complete", result
    return out


@pytest.fixture(scope="module")
def runs_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("runs")


@pytest.fixture(scope="module")
def console(runs_dir):
    _need_browser()
    options = console_options(config=None, sim=True, live=True, runs=[runs_dir])
    with serving_in_thread(options) as url:
        worker = options.worker
        assert worker is not None and worker.ready.wait(WAIT_S), "the simulated rig did not open"
        assert worker.error is None, worker.error
        yield url, options


@pytest.fixture(scope="module")
def browser(console):
    driver = new_browser()
    try:
        driver.get(console[0])
        yield driver
    finally:
        driver.quit()


def axis_position(driver, axis: str) -> float:
    return float(page(driver, f"window.rigConsole.axes['{axis}'].position"))


def take_control(driver):
    driver.find_element("id", "take-control").click()
    wait_for(driver, lambda d: page(d, "window.rigConsole.control && window.rigConsole.control.you"), "no control")


def select_step(driver, value: str):
    from selenium.webdriver.support.ui import Select

    Select(driver.find_element("id", "step")).select_by_value(value)


def test_live_frame_updates(browser):
    wait_for(browser, lambda d: page(d, "window.rigConsole.frames") >= 3, "no frames drawn")
    first = page(browser, "window.rigConsole.frameIndex")
    wait_for(browser, lambda d: page(d, "window.rigConsole.frameIndex") > first + 2, "the frame did not update")
    canvas = browser.find_element("id", "live-frame")
    assert int(canvas.get_attribute("data-index")) > first
    # the canvas shows an image, not a blank: the gel's pixels vary
    spread = page(
        browser,
        "(() => { const c = document.getElementById('live-frame'); const d = c.getContext('2d')"
        ".getImageData(0, 0, c.width, c.height).data; let lo = 255, hi = 0;"
        " for (let i = 0; i < d.length; i += 4) { lo = Math.min(lo, d[i+1]); hi = Math.max(hi, d[i+1]); }"
        " return hi - lo; })()",
    )
    assert spread > 10


def jog_and_wait(driver, axis: str, direction: str, step: str) -> float:
    """Click one jog button with ``step`` selected; wait until the axis is there."""
    select_step(driver, step)
    start = axis_position(driver, axis)
    target = start + (float(step) if direction == "plus" else -float(step))
    done = lambda d: sum(e.split(" ", 1)[-1].startswith(f"{axis} = ") for e in page(d, "window.rigConsole.events"))
    before = done(driver)
    driver.find_element("id", f"jog-{axis}-{direction}").click()
    wait_for(driver, lambda d: done(d) > before, f"the {axis} jog did not finish")  # the session has settled
    wait_for(driver, lambda d: abs(axis_position(d, axis) - target) < 0.01, f"{axis} did not reach {target}")
    return target


def test_jog_moves_the_stage_and_the_force_trace_responds(browser):
    wait_for(browser, lambda d: page(d, "'z' in window.rigConsole.axes"), "no axes shown")
    take_control(browser)
    z0 = axis_position(browser, "z")
    fz0 = page(browser, "window.rigConsole.wrench[2]")
    # the simulated rig starts 5 mm above the gel (find-contact: touched ~0.12 mm below z = 0)
    jog_and_wait(browser, "z", "minus", "5")
    assert abs(page(browser, "window.rigConsole.wrench[2]") - fz0) < 0.2  # not touching yet
    jog_and_wait(browser, "z", "minus", "1")  # ~0.9 mm into the gel
    wait_for(
        browser, lambda d: abs(page(d, "window.rigConsole.wrench[2]") - fz0) > 0.5, "the force trace did not respond"
    )
    fz_pressed = page(browser, "window.rigConsole.wrench[2]")
    # the trace holds the press: its Fz series reaches the value shown
    trace = page(browser, "window.rigConsole.liveFz()")
    assert max(abs(v - fz0) for v in trace) > 0.5
    browser.save_screenshot(str(IMG / "console.png"))
    jog_and_wait(browser, "z", "plus", "1")
    wait_for(
        browser,
        lambda d: abs(page(d, "window.rigConsole.wrench[2]") - fz0) < abs(fz_pressed - fz0) / 4,
        "the force did not go away when lifted",
    )
    jog_and_wait(browser, "z", "plus", "5")
    assert axis_position(browser, "z") == pytest.approx(z0, abs=0.01)


def test_stop_halts_a_move_in_progress(browser):
    take_control(browser)
    select_step(browser, "5")  # 5 mm at the jog speed of 1 mm/s: five seconds to stop it in
    x0 = axis_position(browser, "x")
    browser.find_element("id", "jog-x-plus").click()
    wait_for(browser, lambda d: d.find_element("id", "axis-x").get_attribute("class") == "busy", "x never moved")
    browser.find_element("id", "stop").click()
    wait_for(browser, lambda d: any("x stopped at" in e for e in page(d, "window.rigConsole.events")), "no stop")
    wait_for(browser, lambda d: d.find_element("id", "axis-x").get_attribute("class") == "idle", "x still busy")
    x_end = axis_position(browser, "x")
    assert x0 < x_end < x0 + 4.5, (x0, x_end)
    select_step(browser, "1")
    browser.find_element("id", "jog-x-minus").click()  # the next jog is accepted: the session is not stuck
    wait_for(browser, lambda d: abs(axis_position(d, "x") - (x_end - 1.0)) < 0.01, "no jog after the stop")


def test_a_second_browser_is_refused_control(browser, console):
    take_control(browser)
    second = new_browser()
    try:
        second.get(console[0])
        wait_for(second, lambda d: page(d, "window.rigConsole.control !== null"), "second page not connected")
        assert "controlled by" in second.find_element("id", "control-status").text
        second.find_element("id", "take-control").click()
        wait_for(second, lambda d: "refused" in d.find_element("id", "control-msg").text, "not refused")
        assert "one controller at a time" in second.find_element("id", "control-msg").text
        assert page(second, "window.rigConsole.control.you") is False
        # its jog buttons are disabled, and a jog sent anyway is refused by the server
        assert not second.find_element("id", "jog-x-plus").is_enabled()
        x = axis_position(browser, "x")
        page(second, "(window.rigConsole.send({type: 'jog', axis: 'x', step: 1}), true)")
        wait_for(second, lambda d: "take control first" in d.find_element("id", "control-msg").text, "jog taken")
        assert axis_position(browser, "x") == pytest.approx(x, abs=1e-3)
    finally:
        second.quit()


def test_run_browser_shows_frame_n_and_its_wrench(browser, runs_dir):
    path = record_quick_run(runs_dir)
    with open_for_reading(path) as f:
        n_frames = f[S.FRAMES].shape[0]
        n = n_frames // 2
        wrench = np.asarray(f[S.WRENCH][n])
        frame = np.asarray(f[S.FRAMES][n])
    assert n_frames >= 6
    browser.find_element("id", "run-refresh").click()
    wait_for(browser, lambda d: path.name in d.find_element("id", "run-select").text, "run not listed")
    from selenium.webdriver.support.ui import Select

    Select(browser.find_element("id", "run-select")).select_by_value(path.name)
    wait_for(browser, lambda d: page(d, "window.rigConsole.run && window.rigConsole.run.frames") == n_frames, "no run")
    browser.execute_script(
        "const s = document.getElementById('run-slider'); s.value = arguments[0]; s.dispatchEvent(new Event('input'));",
        n,
    )
    wait_for(browser, lambda d: d.find_element("id", "run-frame").get_attribute("data-index") == str(n), "no frame")
    text = browser.find_element("id", "run-wrench").text
    for name, value in zip(("Fx", "Fy", "Fz", "Mx", "My", "Mz"), wrench):
        assert f"{name} {value:.3f}" in text
    assert f"frame {n} of {n_frames}" in browser.find_element("id", "run-frame-label").text
    # the image shown is frame n itself (decoded by the browser, compared pixel by pixel)
    shown = page(
        browser,
        "(() => { const img = document.getElementById('run-frame'); const c = document.createElement('canvas');"
        " c.width = img.naturalWidth; c.height = img.naturalHeight; const g = c.getContext('2d');"
        " g.drawImage(img, 0, 0); return Array.from(g.getImageData(0, 0, c.width, c.height).data); })()",
    )
    rgba = np.asarray(shown, dtype=np.uint8).reshape(frame.shape[0], frame.shape[1], 4)
    assert np.array_equal(rgba[..., :3], frame[..., ::-1])  # the file is BGR, the page RGB (PNG: lossless)
    browser.execute_script("document.getElementById('browser').scrollIntoView()")
    browser.save_screenshot(str(IMG / "run_browser.png"))


def test_off_loopback_every_request_needs_the_token(tmp_path):
    """No browser needed: the token gate and the run-browser-only console (`dataset view`)."""
    import urllib.error
    import urllib.request

    options = console_options(config=None, sim=False, live=False, runs=[tmp_path], token="s3cret-token")
    with serving_in_thread(options) as url:
        base = url.split("?")[0]
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(base + "api/info", timeout=10)
        assert refused.value.code == 403
        with urllib.request.urlopen(base + "api/info?token=s3cret-token", timeout=10) as ok:
            assert ok.status == 200
            assert "rig_console_token=s3cret-token" in ok.headers["set-cookie"]
            assert b'"live":false' in ok.read()
        request = urllib.request.Request(base + "api/runs", headers={"Cookie": "rig_console_token=s3cret-token"})
        with urllib.request.urlopen(request, timeout=10) as ok:
            assert ok.read() == b"[]"
        # a name that is not a listed run file is never opened, whatever path it spells
        request = urllib.request.Request(
            base + "api/run?name=../../etc/passwd", headers={"Cookie": "rig_console_token=s3cret-token"}
        )
        with pytest.raises(urllib.error.HTTPError) as unknown:
            urllib.request.urlopen(request, timeout=10)
        assert unknown.value.code == 404
