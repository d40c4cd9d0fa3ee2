"""The console tells the truth while a protocol started from the page runs (issue 37): a "running
protocol" badge instead of "live", the run's own newest frame, every control the server would refuse
disabled with the reason, the tare state beside the wrench; after STOP the axes of the rig that moved
(the protocol's own simulated rig, as it ended), said so; the run browser's phase names in their own
bands after the slider moves, and charts and legends whole at 800 px. Screenshots at 1280 and 800 px,
each asserted on.
"""

from __future__ import annotations

import re

import pytest
from test_console import WAIT_S, browser_at, page, screenshot, simulated_console, take_control, wait_for

pytestmark = pytest.mark.slow

SLOW = "motion.speed_mm_s=0.2"  # sphere10mm in about 600 frames: long enough to look at it running
WIDTHS = (1280, 800)


def _shots(browser, name: str) -> None:
    browser.execute_script("window.scrollTo(0, 0)")
    for width in WIDTHS:
        browser.set_window_size(width, 1100)
        page(browser, "window.dispatchEvent(new Event('resize'))")
        screenshot(browser, f"{name}_{width}.png")
    browser.set_window_size(WIDTHS[0], 1100)


def _disabled_controls(browser) -> list[dict]:
    return page(
        browser,
        "Array.from(document.querySelectorAll('.needs-control')).map((b) => ({id: b.id, disabled: b.disabled, "
        "title: b.title}))",
    )


def test_a_page_started_protocol_is_shown_as_it_runs_and_as_it_ended(tmp_path):
    from selenium.webdriver.support.ui import Select

    runs = tmp_path / "runs"
    with simulated_console(runs, "rgb") as (url, _options), browser_at(url) as browser:
        browser.set_window_size(WIDTHS[0], 1100)
        take_control(browser)
        idle = [b for b in _disabled_controls(browser) if b["disabled"]]
        assert not idle, idle  # with control and nothing running, every control is usable
        Select(browser.find_element("id", "protocol-select")).select_by_value("sphere10mm")
        settings = browser.find_element("id", "protocol-set")
        settings.clear()
        settings.send_keys(SLOW)
        wait_for(browser, lambda d: "frames at 1 Hz" in d.find_element("id", "protocol-plan").text, "no plan")
        browser.find_element("id", "run-protocol").click()

        # running: pressed into the gel, the run's own frame shown
        def pressed(d):
            p = page(d, "window.rigConsole.protocol")
            return (
                p
                and p["frame"] >= 5
                and p["phase"] in ("press", "shear", "twist")
                and page(d, "window.rigConsole.runFrame")
            )

        wait_for(browser, pressed, "the protocol did not reach its press", 180)
        protocol = page(browser, "window.rigConsole.protocol")
        pill = browser.find_element("id", "link-status")
        assert pill.text == "running protocol sphere10mm" and "run" in pill.get_attribute("class"), pill.text
        assert "live" not in [e.text for e in browser.find_elements("css selector", "header .pill")]
        controls = _disabled_controls(browser)
        assert {"zero", "home", "run-protocol", "jog-z-minus"} <= {b["id"] for b in controls}
        for b in controls:
            assert b["disabled"] and "protocol sphere10mm is running" in b["title"], b
        lock = browser.find_element("id", "lock-msg")
        assert lock.is_displayed() and lock.text == "controls locked: protocol sphere10mm is running (STOP ends it)"
        assert browser.find_element("id", "stop").is_enabled()
        canvas = browser.find_element("id", "live-frame")
        shown = page(browser, "window.rigConsole.runFrame")
        assert canvas.get_attribute("data-run") == protocol["run"] == shown["run"]
        assert 0 <= shown["index"] <= page(browser, "window.rigConsole.protocol.frame")
        info = browser.find_element("id", "frame-info").text
        assert f"of {protocol['run']}" in info and "the protocol's newest frame" in info and "paused" in info, info
        tare = page(browser, "window.rigConsole.tare")
        tare_pill = browser.find_element("id", "tare-state").text
        assert tare_pill == ("tared" if tare["tared"] else "untared: raw gauge reading (zero gauge to tare)")
        assert "simulated rig" in browser.find_element("id", "axes-source").text
        # a moment trace of gauge noise (about 1 N·mm) is drawn over at least 20 N·mm: a line, not a solid bar
        span = page(
            browser, "window.rigConsole.charts.moments.scales.y.max - window.rigConsole.charts.moments.scales.y.min"
        )
        assert span >= 20, span
        _shots(browser, "console_running")

        # STOP: the file ends interrupted; the axes shown are the protocol's rig's as it ended
        browser.find_element("id", "stop").click()
        ended = lambda d: [e for e in page(d, "window.rigConsole.events") if "protocol sphere10mm: " in e]
        wait_for(browser, ended, "the run did not end", WAIT_S)
        assert "interrupted" in ended(browser)[-1], ended(browser)
        wait_for(browser, lambda d: page(d, "window.rigConsole.protocol") is None, "still shown as running")
        source = browser.find_element("id", "axes-source").text
        assert "protocol sphere10mm's own simulated rig as it ended (interrupted)" in source, source
        z_shown = float(page(browser, "window.rigConsole.axes.z.position"))
        lifted = [e for e in page(browser, "window.rigConsole.events") if re.search(r"z (lifted|clear|at)", e)]
        from acquisition import schema as S
        from acquisition.run_reader import RunReader

        with RunReader.open(runs / protocol["run"]) as run:
            last_z = float(run.rows[S.POSE_MEASURED][run.n - 1][2])
            assert run.status == "interrupted"
        # the stop lifted z clear of where the last frame was pressed: the axes say that rig's lift
        assert z_shown > last_z, (z_shown, last_z, lifted)
        assert browser.find_element("id", "link-status").text == "live"
        assert not browser.find_element("id", "lock-msg").is_displayed()
        assert not any(b["disabled"] for b in _disabled_controls(browser))
        run_name = protocol["run"]
        wait_for(
            browser,
            lambda d: any(p["run"] == run_name and p.get("finished") for p in page(d, "window.rigConsole.progress")),
            "the progress panel still shows the run as running",
        )
        card = browser.find_element("css selector", f"[data-run='{run_name}'] .title").text
        assert card == f"{run_name}: ended", card
        _shots(browser, "console_stopped")

        # the run browser: the interrupted run, the slider moved
        Select(browser.find_element("id", "run-select")).select_by_value(protocol["run"])
        wait_for(
            browser, lambda d: (page(d, "window.rigConsole.run && window.rigConsole.run.frames") or 0) > 5, "no run"
        )
        for width in WIDTHS:
            browser.set_window_size(width, 1100)
            page(browser, "window.dispatchEvent(new Event('resize'))")
            n = page(browser, "window.rigConsole.run.frames")
            slider = browser.find_element("id", "run-slider")
            mid = str(n // 2)
            browser.execute_script(
                "const s = document.getElementById('run-slider'); s.value = arguments[0]; "
                "s.dispatchEvent(new Event('input'))",
                mid,
            )
            wait_for(
                browser,
                lambda d, mid=mid: d.find_element("id", "run-wrench").get_attribute("data-index") == mid,
                "slider",
            )
            assert slider.get_attribute("value") == mid
            for k, chart in enumerate(page(browser, "window.rigConsole.runCharts.map((u) => u.root.parentElement.id)")):
                box = page(browser, f"document.getElementById('{chart}').clientWidth")
                width_px = page(browser, f"window.rigConsole.runCharts[{k}].width")
                assert width_px <= box, (chart, width_px, box)
                x_max = page(browser, f"window.rigConsole.runCharts[{k}].scales.x.max")
                assert x_max >= page(browser, "window.rigConsole.run.t_s.at(-1)") - 1e-6, (chart, x_max)
                clipped = page(
                    browser,
                    f"Array.from(document.querySelectorAll('#{chart} .u-legend .u-series'))"
                    ".filter((e) => e.scrollWidth > e.clientWidth + 1 || e.getBoundingClientRect().right > "
                    "window.innerWidth).map((e) => e.textContent)",
                )
                assert clipped == [], (chart, clipped)
            run_info = browser.find_element("id", "run-info").text
            assert "interrupted (STOP from" in run_info and "interrupted (interrupted" not in run_info, run_info
            labels = page(browser, "window.rigConsole.runCharts[0].phaseLabels")
            assert labels, "no phase name drawn"
            for label in labels:  # each name inside its own band, above the traces
                assert label["band"][0] <= label["x0"] and label["x1"] <= label["band"][1], label
            browser.execute_script("document.getElementById('browser').scrollIntoView()")
            screenshot(browser, f"run_browser_slider_{width}.png")
