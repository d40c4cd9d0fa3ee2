"""`rig console` driven in a real headless browser (Debian's chromium + chromedriver, selenium).

The console serves the simulated rig (`--sim`, a marker sensor) from a thread of this process;
the page is driven as a user would: the live frame updates, a jog button moves the stage and
the force trace responds, marker-flow arrows follow a shear, STOP halts a move, a second
browser is refused control, the run browser shows frame N and its wrench for a run recorded
here, and a `rig run-protocol` started as its own process shows live in the progress panel.
Screenshots go to a temporary folder, or to $TACTILE_SCREENSHOTS where set (the documentation's
are refreshed with TACTILE_SCREENSHOTS=docs/img): a test run never rewrites tracked files.

scripts/setup.sh installs chromium and chromium-driver where they are missing; without them
these tests skip locally and fail under CI (CI=true), so a missing install cannot pass silently.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

from acquisition import schema as S
from acquisition.run_file import open_for_reading
from cli.console.launch import console_options
from cli.console.server import serving_in_thread

pytestmark = pytest.mark.slow

_SHOTS: list[Path] = []  # the screenshot folder, made at the first screenshot


def screenshot(browser, name: str) -> None:
    """Save the page into $TACTILE_SCREENSHOTS (made if missing) or a temporary folder."""
    if not _SHOTS:
        where = os.environ.get("TACTILE_SCREENSHOTS")
        folder = Path(where).resolve() if where else Path(tempfile.mkdtemp(prefix="console-screenshots-"))
        folder.mkdir(parents=True, exist_ok=True)
        _SHOTS.append(folder)
    assert browser.save_screenshot(str(_SHOTS[0] / name)), f"screenshot {name} not saved in {_SHOTS[0]}"


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
    options.binary_location = CHROMIUM or ""
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1300"):
        options.add_argument(arg)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


def wait_for(driver, condition, message: str, timeout_s: float = WAIT_S):
    from selenium.webdriver.support.ui import WebDriverWait

    return WebDriverWait(driver, timeout_s, poll_frequency=0.05).until(lambda d: condition(d), message)


def page(driver, expr: str):
    return driver.execute_script(f"return {expr};")


def as_shown(value: float, digits: int = 3) -> str:
    """A number as the page prints it: fixed digits, never "-0.000"."""
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0 else text


QUICK_CHANGES = (
    ('name = "sphere10mm"', 'name = "console-quick"'),
    ("max_depth_mm = 1.6", "max_depth_mm = 0.4"),
    ("depth_step_mm = 0.4", "depth_step_mm = 0.4"),
    ("shear_mm = 2.0", "shear_mm = 0.2"),
    ("twist_deg = 5.0", "twist_deg = 1.0"),
    ("speed_mm_s = 0.01", "speed_mm_s = 0.2"),
    ("twist_speed_deg_s = 0.25", "twist_speed_deg_s = 2.0"),
)


def load_protocol_text(name: str = "sphere10mm") -> str:
    from protocols.spec import load_protocol

    return load_protocol(name).text


def record_quick_run(folder: Path, name: str = "console-quick", changes=()) -> Path:
    """A short simulated protocol run into ``folder`` (a press, a shear and a twist), named ``name``,
    with ``changes`` (old, new) made to the quick protocol's text."""
    from acquisition.executor import Acquisition
    from cli.simulated import monitor_interval_s, simulated_rig_for
    from protocols.plan import Plan
    from protocols.spec import load_protocol

    text = load_protocol("sphere10mm").text
    for old, new in (*QUICK_CHANGES, ('name = "console-quick"', f'name = "{name}"'), *changes):
        assert old in text, old
        text = text.replace(old, new)
    spec = folder / f"{name}.toml"
    spec.write_text(text)
    protocol = load_protocol(spec)
    out = folder / f"{name}.h5"
    with simulated_rig_for(protocol) as (rig, _sim, header):
        result = Acquisition(rig, Plan.of(protocol), monitor_interval_s=monitor_interval_s(protocol)).run(
            out, header=header
        )
    assert result.status == "complete", result
    return out


@pytest.fixture(scope="module")
def runs_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("runs")


@contextlib.contextmanager
def simulated_console(runs_dir: Path, sensor: str):
    """(url, options) of a console on its own simulated rig, served from a thread of this process."""
    _need_browser()
    options = console_options(config=None, sim=True, live=True, runs=[runs_dir], sensor=sensor)
    with serving_in_thread(options) as url:
        worker = options.worker
        assert worker is not None and worker.ready.wait(WAIT_S), "the simulated rig did not open"
        assert worker.error is None, worker.error
        yield url, options


@contextlib.contextmanager
def browser_at(url: str):
    driver = new_browser()
    try:
        driver.get(url)
        yield driver
    finally:
        driver.quit()


@pytest.fixture(scope="module")
def console(runs_dir):
    with simulated_console(runs_dir, "rgb_markers") as served:
        yield served


@pytest.fixture(scope="module")
def browser(console):
    with browser_at(console[0]) as driver:
        yield driver


def axis_position(driver, axis: str) -> float:
    return float(page(driver, f"window.rigConsole.axes['{axis}'].position"))


def take_control(driver):
    wait_for(driver, lambda d: d.find_element("id", "take-control").is_displayed(), "the live view is not shown")
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
    screenshot(browser, "console.png")
    jog_and_wait(browser, "z", "plus", "1")
    wait_for(
        browser,
        lambda d: abs(page(d, "window.rigConsole.wrench[2]") - fz0) < abs(fz_pressed - fz0) / 4,
        "the force did not go away when lifted",
    )
    jog_and_wait(browser, "z", "plus", "5")
    assert axis_position(browser, "z") == pytest.approx(z0, abs=0.01)


def flow_after(driver, frame_index: int) -> dict:
    """The page's summary of the first marker flow drawn for a frame after ``frame_index``."""
    wait_for(
        driver,
        lambda d: (page(d, "window.rigConsole.flow && window.rigConsole.flow.index") or -1) > frame_index,
        "no marker flow drawn",
    )
    return page(driver, "window.rigConsole.flow")


def overlay_green_pixels(driver) -> int:
    return page(
        driver,
        "(() => { const c = document.getElementById('flow-overlay'); const d = c.getContext('2d')"
        ".getImageData(0, 0, c.width, c.height).data; let n = 0;"
        " for (let i = 0; i < d.length; i += 4) if (d[i+3] > 0 && d[i+1] > 200 && d[i] < 80) n++; return n; })()",
    )


@pytest.mark.realtime  # jogs from the page on a rig served on real time
def test_marker_flow_arrows_follow_the_shear(browser):
    """Marker sensor: no arrows at rest; pressed and sheared along +x, then along -x, the
    arrows' mean motion is along x and flips sign with the shear."""
    wait_for(browser, lambda d: page(d, "'x' in window.rigConsole.axes"), "no axes shown")
    assert browser.find_element("id", "marker-flow-label").is_displayed()
    browser.find_element("id", "marker-flow").click()
    rest = flow_after(browser, page(browser, "window.rigConsole.frameIndex"))
    assert rest["matched"] >= 300, rest  # the 20 x 20 grid, the edges aside
    assert rest["arrows"] == 0, rest  # nothing moved yet: no arrows
    take_control(browser)
    x0 = axis_position(browser, "x")
    jog_and_wait(browser, "z", "minus", "5")
    jog_and_wait(browser, "z", "minus", "1")  # ~0.9 mm into the gel
    select_step(browser, "0.1")
    sheared = {}
    for sign, direction, clicks in ((1, "plus", 3), (-1, "minus", 6)):
        for _ in range(clicks):
            jog_and_wait(browser, "x", direction, "0.1")
        flow = flow_after(browser, page(browser, "window.rigConsole.frameIndex"))
        assert flow["arrows"] > 20, flow
        assert abs(flow["meanDx"]) > 0.3 and abs(flow["meanDx"]) > 3 * abs(flow["meanDy"]), flow
        sheared[sign] = flow
        assert overlay_green_pixels(browser) > 50  # the arrows are on the canvas
        said = browser.find_element("id", "flow-info").text
        assert f"{flow['matched']} of {flow['markers']} markers matched, {flow['arrows']} of them moved" in said
        if sign == 1:
            screenshot(browser, "console_markers.png")
    assert sheared[1]["meanDx"] * sheared[-1]["meanDx"] < 0, sheared  # the arrows turned with the shear
    jog_and_wait(browser, "x", "plus", "0.1")
    jog_and_wait(browser, "x", "plus", "0.1")
    jog_and_wait(browser, "x", "plus", "0.1")
    jog_and_wait(browser, "z", "plus", "1")
    jog_and_wait(browser, "z", "plus", "5")
    assert axis_position(browser, "x") == pytest.approx(x0, abs=0.01)
    browser.find_element("id", "marker-flow").click()
    assert overlay_green_pixels(browser) == 0  # off: the overlay is cleared


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
    for name, value, unit in zip(("Fx", "Fy", "Fz", "Mx", "My", "Mz"), wrench, ("N",) * 3 + ("N·mm",) * 3):
        assert f"{name} {as_shown(value)} {unit}" in text
    assert f"frame #{n} of {n_frames}" in browser.find_element("id", "run-frame-label").text
    assert not browser.find_element("id", "run-flow-label").is_displayed()  # an rgb run: no markers to follow
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
    screenshot(browser, "run_browser.png")


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


def _refusals(ws, messages) -> list[str]:
    """Send each message; the text of the ``refused`` answer to each (other messages skipped)."""
    import json

    answers = []
    for message in messages:
        ws.send(message)
        while True:
            reply = ws.recv(timeout=WAIT_S)
            if isinstance(reply, str) and json.loads(reply).get("type") == "refused":
                answers.append(json.loads(reply)["text"])
                break
    return answers


def test_malformed_messages_are_refused_never_a_traceback(tmp_path, capfd):
    """Issue 25: valid JSON that is not an object (and worse) once ended in `AttributeError: 'list'
    object has no attribute 'get'` on the server's stderr. Each is answered, the link lives on."""
    import json

    from cli.console.server import MALFORMED

    ws_client = pytest.importorskip("websockets.sync.client")
    options = console_options(config=None, sim=False, live=False, runs=[tmp_path])
    with serving_in_thread(options) as url, ws_client.connect(url.replace("http://", "ws://") + "ws") as ws:
        malformed = ["[1, 2]", "3", '"stop"', "null", "not json", "{", "[" * 100_000, b"\x00binary"]
        assert _refusals(ws, malformed) == [MALFORMED] * len(malformed)
        ws.send(json.dumps({"type": "take_control"}))  # still served
        while not (isinstance(reply := ws.recv(timeout=WAIT_S), str) and json.loads(reply).get("you") is True):
            pass
    err = capfd.readouterr().err
    assert "Traceback" not in err and "AttributeError" not in err, err


def test_fields_of_the_wrong_type_are_refused(console, capfd):
    """A command with a field of the wrong type reaches neither the rig nor a traceback."""
    import json

    ws_client = pytest.importorskip("websockets.sync.client")
    url, options = console
    errors_before = options.worker.errors_seen
    with ws_client.connect(url.replace("http://", "ws://") + "ws") as ws:
        answers = _refusals(
            ws,
            [
                json.dumps({"type": "jog", "axis": ["x"], "step": 1}),
                json.dumps({"type": "home", "axis": 5}),
                json.dumps({"type": {"a": 1}}),
                json.dumps({"type": "run_protocol", "name": ["x"], "origin": "here"}),
            ],
        )
    assert answers[:3] == [
        "jog refused: axis ['x'] is not an axis name",
        "home refused: axis 5 is not an axis name",
        "unknown command {'a': 1}",
    ]
    assert answers[3].startswith("run_protocol refused")  # not this page's control, whatever else
    assert options.worker.errors_seen == errors_before
    err = capfd.readouterr().err
    assert "Traceback" not in err, err


def test_the_page_says_this_console_holds_the_rig(browser):
    wait_for(browser, lambda d: "rig held by this console" in d.find_element("id", "rig-status").text, "no holder")
    assert browser.find_element("id", "rig-status").text == f"rig held by this console (pid {os.getpid()})"


def test_the_page_names_the_process_holding_the_rig(tmp_path):
    """Another process holds the rig (`rig sim serve` in one process, a holder in another):
    the console serves on, and its page names the holder instead of looking live."""
    _need_browser()
    from test_device_ownership import holding, served

    with served(tmp_path) as (cfg, _server), holding(tmp_path, cfg) as holder:
        options = console_options(config=cfg, sim=False, live=True, runs=[tmp_path])
        with serving_in_thread(options) as url:
            worker = options.worker
            assert worker is not None and worker.ready.wait(WAIT_S)
            assert worker.rig_status["state"] == "busy" and worker.rig_status["holder_pid"] == holder.pid
            driver = new_browser()
            try:
                driver.get(url)
                pill = lambda d: d.find_element("id", "rig-status").text
                wait_for(driver, lambda d: pill(d).endswith(f" held by pid {holder.pid}"), "the holder is not named")
                assert pill(driver).startswith("rig busy: /dev/pts/")
                assert driver.find_element("id", "link-status").text == "no rig"
                assert not driver.find_element("id", "live").is_displayed()  # no frame, no jog buttons
                said = driver.find_element("id", "rig-error").text  # the whole line: the holder's command too
                assert f" is held by pid {holder.pid} (python " in said and "holder.py" in said, said
                assert said.endswith("stop that process first"), said
                screenshot(driver, "console_rig_busy.png")
            finally:
                driver.quit()


RIG = str(Path(__import__("sys").executable).parent / "rig")


def test_a_terminal_run_protocol_shows_live_in_the_progress_panel(browser, runs_dir):
    """`rig run-protocol ... --sim` as its own process (as from a terminal) writing into the
    console's runs folder: the panel shows its phase, frame count and ETA changing, then how
    it ended; the latest pair shown is the file's own; the sidecar is gone at the end."""
    import subprocess

    from cli.console.run_progress import sidecar_path
    from protocols.plan import Plan
    from protocols.spec import load_protocol

    text = load_protocol_text()
    for old, new in QUICK_CHANGES:
        text = text.replace(old, new)
    text = text.replace('name = "console-quick"', 'name = "console-progress"').replace(
        "speed_mm_s = 0.2",
        "speed_mm_s = 0.025",  # 72 frames: long enough for many looks on any machine
    )
    spec = runs_dir / "console-progress.toml"
    spec.write_text(text)
    n_frames = Plan.of(load_protocol(spec)).frame_count
    browser.execute_script("window.rigConsole.progressEveryMs = 250;")
    out = runs_dir / "progress-markers.h5"
    proc = subprocess.Popen(
        [RIG, "run-protocol", str(spec), "--sim", "--out", str(out), "--set", "protocol.sensor=rgb_markers"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        entry = lambda d: next((p for p in page(d, "window.rigConsole.progress") if p["run"] == out.name), None)
        # the page's entry and its card's text, read in one go (the page updates both at once)
        snapshot = (
            "(() => { const p = window.rigConsole.progress.find((e) => e.run === arguments[0]);"
            " const c = document.querySelector(`.progress-card[data-run='${arguments[0]}']`);"
            " return [p || null, c ? c.innerText : '', c ? c.querySelector('img').dataset.index || '' : '']; })()"
        )
        wait_for(browser, lambda d: (entry(d) or {}).get("frame", 0) >= 1, "the run never showed in the panel")
        seen: list[dict] = []
        shot = False
        while True:
            p, card_text, img_index = wait_for(
                browser,
                lambda d: (
                    (snap := d.execute_script(f"return {snapshot};", out.name))[0]
                    and (snap[0].get("finished") or not seen or snap[0]["frame"] != seen[-1]["frame"])
                    and snap
                ),
                "the panel stopped updating",
            )
            if p.get("finished"):
                break
            assert not p.get("error") and not p["stale"], p
            # one frame count: the file's (the latest pair's and the run browser's too), not the sidecar's
            assert f"{p['committed']} / {n_frames} written" in card_text and p["phase"] in card_text, (p, card_text)
            assert p["committed"] == 0 or f"frame #{p['committed'] - 1}:" in card_text, card_text
            assert "ETA" in card_text
            seen.append(p)
            if not shot and p["frame"] >= n_frames // 3 and img_index:
                browser.execute_script("window.scrollTo(0, 0)")
                screenshot(browser, "console_progress.png")
                shot = True
        assert proc.wait(120) == 0, proc.stderr.read() if proc.stderr else ""
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(60)
    frames = [p["frame"] for p in seen]
    assert len(set(frames)) >= 3 and frames == sorted(frames) and frames[-1] <= n_frames, frames
    assert len({p["phase"] for p in seen}) >= 2, [p["phase"] for p in seen]  # press, shear, ...
    etas = [p["eta_s"] for p in seen]
    assert etas[-1] < etas[0], etas  # the ETA counts down
    assert all(p["protocol"] == "console-progress" and p["frames"] == n_frames for p in seen)
    assert {p["depth_mm"] for p in seen} == {0.4}  # the one level of this protocol
    assert shot, f"never saw frame {n_frames // 3} of {n_frames} in the panel"
    # the end: the sidecar is gone, the panel says how the run ended (from the file)
    assert not sidecar_path(out).exists()
    done = wait_for(
        browser, lambda d: (e := entry(d)) and e.get("finished") and e.get("committed") == n_frames and e, "end"
    )
    assert done["file_status"] == "complete"
    card = browser.find_element("css selector", f'.progress-card[data-run="{out.name}"]')
    wait_for(browser, lambda d: "complete" in card.text, "the panel does not say complete")
    # the latest pair shown is the file's last frame and its wrench
    with open_for_reading(out) as f:
        wrench = np.asarray(f[S.WRENCH][n_frames - 1])
    wait_for(browser, lambda d: f"frame #{n_frames - 1}:" in card.text, "the last pair is not shown")
    for name, value in zip(("Fx", "Fy", "Fz", "Mx", "My", "Mz"), wrench):
        assert f"{name} {as_shown(value)} " in card.text


def test_run_browser_marker_flow_against_the_reference(browser, runs_dir):
    """The marker run of the progress test in the run browser: marker flow of frame N."""
    from selenium.webdriver.support.ui import Select

    name = "progress-markers.h5"
    if not (runs_dir / name).exists():
        pytest.skip("needs the run of the progress test")
    browser.find_element("id", "run-refresh").click()
    wait_for(browser, lambda d: name in d.find_element("id", "run-select").text, "run not listed")
    Select(browser.find_element("id", "run-select")).select_by_value(name)
    wait_for(browser, lambda d: (page(d, "window.rigConsole.run") or {}).get("name") == name, "run not opened")
    assert browser.find_element("id", "run-flow-label").is_displayed()
    browser.find_element("id", "run-flow").click()
    flows = {}
    for i in (0, 24):  # frame 0: first touch; 24: pressed and sheared
        browser.execute_script(
            "const s = document.getElementById('run-slider'); s.value = arguments[0];"
            " s.dispatchEvent(new Event('input'));",
            i,
        )
        shown = lambda d, i=i: (page(d, "window.rigConsole.runFlow") or {}).get("index") == i
        wait_for(browser, shown, f"no flow of frame {i}")
        flows[i] = page(browser, "window.rigConsole.runFlow")
    assert flows[24]["arrows"] > 20 and flows[24]["arrows"] > flows[0]["arrows"], flows
    browser.execute_script("document.getElementById('browser').scrollIntoView()")
    screenshot(browser, "run_browser_markers.png")


@pytest.mark.realtime  # a stop pressed while the run runs, on real time
def test_a_protocol_started_from_the_page_ends_interrupted_on_stop(browser, runs_dir):
    """The controller starts a library protocol (on --sim on its own simulated rig, on simulated
    time, as `rig run-protocol --sim`); the progress panel follows it, a jog meanwhile is refused,
    STOP ends it as Ctrl-C would: the stages stop, z is lifted, the file ends `interrupted` naming
    who stopped it, and the console is usable again."""
    from selenium.webdriver.support.ui import Select

    from cli.console.run_progress import sidecar_path

    take_control(browser)
    assert "sphere10mm" in [o.text for o in Select(browser.find_element("id", "protocol-select")).options]
    Select(browser.find_element("id", "protocol-select")).select_by_value("sphere10mm")
    browser.find_element("id", "protocol-origin").clear()
    browser.find_element("id", "protocol-origin").send_keys("0,0,0,0")
    before = set(runs_dir.glob("sphere10mm-*.h5"))
    console_z = axis_position(browser, "z")  # the console's own rig: the protocol runs on a rig of its own
    browser.find_element("id", "run-protocol").click()
    mine = lambda d: next(
        (p for p in page(d, "window.rigConsole.progress") if p["run"].startswith("sphere10mm-") and "frame" in p), None
    )
    # on simulated time: the approach and the first frames take a moment, then many frames a second
    wait_for(browser, lambda d: (mine(d) or {}).get("frame", 0) >= 3, "the run never showed progress", 120)
    p = mine(browser)
    assert p["protocol"] == "sphere10mm" and p["phase"] in ("press", "shear", "return") and p["frames"] > 100
    (out,) = set(runs_dir.glob("sphere10mm-*.h5")) - before
    page(browser, "(window.rigConsole.send({type: 'jog', axis: 'x', step: 1}), true)")
    wait_for(browser, lambda d: "a protocol is running" in d.find_element("id", "control-msg").text, "jog taken")
    browser.find_element("id", "stop").click()
    ended = lambda d: [e for e in page(d, "window.rigConsole.events") if "protocol sphere10mm: " in e]
    wait_for(browser, ended, "the run did not end", 120)
    assert "interrupted" in ended(browser)[-1] and "STOP from 127.0.0.1" in ended(browser)[-1]
    with open_for_reading(out) as f:
        status, reason = f[S.STATUS][()].decode(), f[S.STATUS_REASON][()].decode()
        n = f[S.FRAMES].shape[0]
    assert status == "interrupted" and "STOP from 127.0.0.1" in reason, (status, reason)
    assert 3 <= n < p["frames"]
    assert not sidecar_path(out).exists()
    # the axes shown are the protocol's rig's as it ended, z lifted to its approach height, and said so
    wait_for(browser, lambda d: axis_position(d, "z") >= 1.0 - 0.01, "z was not lifted to the approach height")
    assert "own simulated rig as it ended" in browser.find_element("id", "axes-source").text
    # the console goes on: jogging works again, on the console's own rig, which the axes show again
    select_step(browser, "1")
    browser.find_element("id", "jog-z-plus").click()
    wait_for(browser, lambda d: abs(axis_position(d, "z") - (console_z + 1.0)) < 0.01, "z did not jog on")
    assert "this console's rig" in browser.find_element("id", "axes-source").text
