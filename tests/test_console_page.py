"""What a person sees on `rig console` (issue 28), in headless chromium as tests/test_console.py drives it:
a protocol started from the page on --sim runs on simulated time (as `rig run-protocol --sim`), with
its duration, frames and disk shown first and --set values checked as the command line checks them;
a rig that does not open is said plainly (no "live"); the charts' legends carry units and values and
every axis has ticks; the jog buttons hold their labels; the frame rate is a one-second average; the
run browser's condition panel is the object at the frame's pose. Each screenshot is asserted on.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_console import (
    WAIT_S,
    _need_browser,
    browser_at,
    new_browser,
    page,
    record_quick_run,
    screenshot,
    simulated_console,
    take_control,
    wait_for,
)

from acquisition import schema as S
from acquisition.run_reader import RunReader
from cli.console.launch import console_options
from cli.console.server import serving_in_thread

pytestmark = pytest.mark.slow

RIG = str(Path(sys.executable).parent / "rig")
FAST = "motion.speed_mm_s=0.4"  # sphere10mm in 301 frames (5 min of protocol time)


@pytest.fixture(scope="module")
def rgb_console(tmp_path_factory):
    """(browser, runs folder) on a console of an rgb simulated rig, for this module's tests."""
    runs = tmp_path_factory.mktemp("page-runs")
    with simulated_console(runs, "rgb") as (url, _options), browser_at(url) as driver:
        yield driver, runs


def test_legends_have_units_and_values_and_every_axis_has_ticks(rgb_console):
    browser, _runs = rgb_console
    wait_for(browser, lambda d: page(d, "window.rigConsole.frames") >= 40, "no frames drawn")
    wait_for(browser, lambda d: len(page(d, "window.rigConsole.liveFz()")) > 20, "no wrench trace")
    legends = {
        name: browser.find_element("id", f"live-{name}").find_element("class name", "u-legend").text
        for name in ("forces", "moments")
    }
    for label in ("Fx (N)", "Fy (N)", "Fz (N)"):
        assert label in legends["forces"], legends
    for label in ("Mx (N·mm)", "My (N·mm)", "Mz (N·mm)"):
        assert label in legends["moments"], legends
    assert "--" not in legends["forces"] + legends["moments"], legends  # values, not uPlot's blanks
    fz = page(browser, "window.rigConsole.wrench[2]")
    assert f"{fz:.2f}"[:3] in legends["forces"]  # the newest value, shown while the cursor is off the chart
    for chart in ("forces", "moments"):
        for axis in (0, 1):
            ticks = page(browser, f"window.rigConsole.charts.{chart}.axes[{axis}]._values.filter((v) => v !== '')")
            assert len(ticks) >= 3, (chart, axis, ticks)  # the N·mm chart once had only "0"
    now = browser.find_element("id", "wrench-now").text
    assert " N " in now + " " and "N·mm" in now, now  # the current values carry their units
    # every jog button holds its label (theta's once spilled out)
    spill = page(
        browser,
        "Array.from(document.querySelectorAll('#jog button')).filter((b) => b.scrollWidth > b.clientWidth)"
        ".map((b) => b.id)",
    )
    assert spill == [], spill
    # frames drawn over the last second: a 25 fps camera never reads 217 fps
    fps = page(browser, "window.rigConsole.fps")
    assert fps is not None and 5 <= fps <= 30, fps
    assert "fps (drawn, last second)" in browser.find_element("id", "frame-info").text
    pills = [e.text for e in browser.find_elements("css selector", "header .pill") if e.is_displayed()]
    assert pills[:2] == ["live", f"rig held by this console (pid {__import__('os').getpid()})"], pills
    screenshot(browser, "console_charts.png")


def cli_seconds(tmp: Path) -> float:
    start = time.monotonic()
    done = subprocess.run(
        [RIG, "run-protocol", "sphere10mm", "--sim", "--set", FAST, "--out", str(tmp / "cli.h5")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    return time.monotonic() - start


@pytest.mark.realtime  # its time is compared with the command line's, both on real time
def test_a_page_started_sim_protocol_runs_on_simulated_time(rgb_console, tmp_path):
    """sphere10mm at 0.4 mm/s is 5 min 08 s of protocol time: from the page it takes about what
    `rig run-protocol --sim` takes, not 5 minutes; the plan and --set are shown and checked first."""
    browser, runs_dir = rgb_console
    from selenium.webdriver.support.ui import Select

    take_control(browser)
    Select(browser.find_element("id", "protocol-select")).select_by_value("sphere10mm")
    settings = browser.find_element("id", "protocol-set")
    settings.clear()
    settings.send_keys("motion.speed_mm_s=fast")  # as the command line: refused, naming the key
    plan = lambda d: d.find_element("id", "protocol-plan")
    wait_for(browser, lambda d: "speed_mm_s" in plan(d).text and "error" in plan(d).get_attribute("class"), "no error")
    browser.find_element("id", "run-protocol").click()
    wait_for(browser, lambda d: "run protocol refused" in d.find_element("id", "control-msg").text, "bad --set taken")
    settings.clear()
    settings.send_keys(FAST)
    wait_for(browser, lambda d: "301 frames" in plan(d).text, "the plan was not shown")
    text = plan(browser).text
    assert "5m08s of protocol time" in text and "at 1 Hz" in text and "MB on disk" in text, text
    assert "simulated time" in text, text
    screenshot(browser, "console_protocol.png")
    before = set(runs_dir.glob("sphere10mm-*.h5"))
    start = time.monotonic()
    browser.find_element("id", "run-protocol").click()
    ended = lambda d: [e for e in page(d, "window.rigConsole.events") if "protocol sphere10mm: " in e]
    wait_for(browser, ended, "the run did not end", 300)
    page_s = time.monotonic() - start
    assert "complete, 301 frames" in ended(browser)[-1], ended(browser)
    (out,) = set(runs_dir.glob("sphere10mm-*.h5")) - before
    with RunReader.open(out) as run:
        assert run.n == 301 and run.status == "complete"
        assert "started from rig console --sim" in run.text(S.ATTR_RIG_CONFIG)
    cli_s = cli_seconds(tmp_path)
    # simulated time: far under the 308 s of protocol time, and within a few x of the command line
    # (which also pays a process start; the page's run shares the machine with a live console)
    assert page_s < 120 and page_s < 3 * cli_s + 15, (page_s, cli_s)
    print(f"page-started run {page_s:.1f} s, rig run-protocol --sim {cli_s:.1f} s (308 s of protocol time)")


def test_a_rig_that_does_not_open_is_said_plainly(tmp_path):
    """A config whose devices are not there: no "live", no live view, the error naming the port."""
    _need_browser()
    cfg = tmp_path / "rig.toml"
    cfg.write_text(Path("docs/rig.example.toml").read_text().replace("/dev/", str(tmp_path / "absent") + "/"))
    options = console_options(config=cfg, sim=False, live=True, runs=[tmp_path])
    with serving_in_thread(options) as url:
        assert options.worker is not None and options.worker.ready.wait(WAIT_S)
        assert options.worker.rig_status["state"] == "failed"
        driver = new_browser()
        try:
            driver.get(url)
            wait_for(driver, lambda d: d.find_element("id", "link-status").text == "no rig", "not said")
            pills = [e.text for e in driver.find_elements("css selector", "header .pill") if e.is_displayed()]
            assert pills == ["no rig", "rig failed to open"], pills  # no "live" badge
            assert not driver.find_element("id", "live").is_displayed()  # no black frame, no empty plots
            error = driver.find_element("id", "rig-error").text
            assert error.startswith("the rig did not open: ") and str(tmp_path / "absent") in error, error
            assert driver.find_element("id", "browser").is_displayed()  # the run browser still works
            screenshot(driver, "console_no_rig.png")
        finally:
            driver.quit()


def test_rig_console_without_a_config_refuses_to_start(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from cli.rig_app import app

    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("RIG_CONFIG", raising=False)
    result = CliRunner().invoke(app, ["console", "--port", "0"])
    assert result.exit_code == 1
    assert result.output.startswith("error: no rig config:") and "--sim" in result.output, result.output
    assert "console at" not in result.output and "Traceback" not in result.output


def test_a_port_in_use_names_the_option(tmp_path):
    import socket

    from typer.testing import CliRunner

    from cli.rig_app import app

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = CliRunner().invoke(app, ["console", "--sim", "--port", str(port), "--runs", str(tmp_path)])
    assert result.exit_code == 1
    line = result.output.strip()
    assert line.startswith(f"error: cannot listen on 127.0.0.1:{port}:") and "--port" in line, line
    assert "OSError" not in line and len(line.splitlines()) == 1


def record_sheared_run(folder: Path) -> Path:
    """A short simulated run whose shear takes the indenter 1.5 mm off the centre."""
    return record_quick_run(folder, "console-sheared", [("shear_mm = 0.2", "shear_mm = 1.5")])


def shown_image(driver, element_id: str) -> np.ndarray:
    data = page(
        driver,
        f"(() => {{ const img = document.getElementById('{element_id}'); const c = document.createElement('canvas');"
        " c.width = img.naturalWidth; c.height = img.naturalHeight; const g = c.getContext('2d');"
        " g.drawImage(img, 0, 0); return [c.width, c.height, Array.from(g.getImageData(0, 0, c.width, c.height).data)];"
        " })()",
    )
    width, height, rgba = data
    return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[..., :3][..., ::-1]  # back to BGR


def test_the_condition_panel_shows_the_object_at_the_frames_pose(rgb_console):
    browser, runs_dir = rgb_console
    from selenium.webdriver.support.ui import Select

    from dataset.condition import condition_image

    path = record_sheared_run(runs_dir)
    with RunReader.open(path) as run:
        poses = np.asarray(run.rows[S.POSE_MEASURED])
        obj, mm_per_px, width = run.image(S.OBJECT_IMAGE), run.number(S.ATTR_MM_PER_PX), run.frame_shape[1]
    i = int(np.argmax(np.hypot(poses[:, 0], poses[:, 1])))  # the frame furthest off the centre
    x, y, theta = poses[i, 0], poses[i, 1], poses[i, 3]
    assert np.hypot(x, y) > 1.0, poses[i]
    browser.find_element("id", "run-refresh").click()
    wait_for(browser, lambda d: path.name in d.find_element("id", "run-select").text, "run not listed")
    Select(browser.find_element("id", "run-select")).select_by_value(path.name)
    wait_for(browser, lambda d: (page(d, "window.rigConsole.run") or {}).get("name") == path.name, "run not opened")
    browser.execute_script(
        "const s = document.getElementById('run-slider'); s.value = arguments[0]; s.dispatchEvent(new Event('input'));",
        i,
    )
    panel = lambda d: d.find_element("id", "run-object").get_attribute("data-index")
    wait_for(browser, lambda d: panel(d) == str(i), "the condition of the frame was not shown")
    shown = shown_image(browser, "run-object")
    expected = condition_image(obj, x, y, theta, mm_per_px, width, width)
    assert np.array_equal(shown, expected)  # the model's own placement, pixel for pixel (PNG)
    # and where a person looks: the object's centre sits at the pose (+x right, +y up), not at the centre
    weight = shown.astype(np.float64).sum(axis=2)
    weight -= np.median(np.concatenate([weight[0], weight[-1]]))
    weight = np.clip(weight, 0, None)
    rows, cols = np.mgrid[0 : weight.shape[0], 0 : weight.shape[1]]
    cx, cy = (weight * cols).sum() / weight.sum(), (weight * rows).sum() / weight.sum()
    centre = (width - 1) / 2
    assert abs((cx - centre) * mm_per_px - x) < 0.1 and abs(-(cy - centre) * mm_per_px - y) < 0.1, (cx, cy, x, y)
    caption = browser.find_element("id", "run-object-caption").text
    assert f"x {x:.3f} mm" in caption.replace("-0.000", "0.000") and f"y {y:.3f} mm" in caption, caption
    legend = browser.find_element("id", "run-pose").find_element("class name", "u-legend").text
    assert "x (mm)" in legend and "θ (deg)" in legend and f"{x:.3f}" in legend, legend  # the slider's frame
    browser.execute_script("document.getElementById('browser').scrollIntoView()")
    screenshot(browser, "run_browser_condition.png")
