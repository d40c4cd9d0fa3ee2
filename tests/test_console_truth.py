"""The console tells the truth while a protocol started from the page runs (issue 37): a "running
protocol" badge instead of "live", the run's own newest frame, every control the server would refuse
disabled with the reason (the keys too), the tare state beside the wrench, moment traces drawn as lines;
after STOP the axes of the rig that moved (the protocol's own simulated rig, z where the stop lifted it,
as the event line says), said so, until a command shows the console's own rig again; the run browser's
phase names in their own strip, each over its own band before and after the slider moves, and charts and
legends whole at 800 px. Screenshots at 1280 and 800 px, each asserted on.
"""

from __future__ import annotations

import re

import pytest
from test_console import (
    WAIT_S,
    browser_at,
    page,
    record_quick_run,
    screenshot,
    simulated_console,
    take_control,
    wait_for,
)

from acquisition import schema as S
from acquisition.run_reader import RunReader

pytestmark = pytest.mark.slow

SLOW = "motion.speed_mm_s=0.2"  # sphere10mm in about 600 frames: long enough to look at it running
WIDTHS = (1280, 800)
LIFT = re.compile(r"z lifted from (-?\d+\.\d+) to (-?\d+\.\d+) mm")
# the quick protocol (tests/test_console.py) at two depths, twisting slower: 26 frames, 10 phase bands
TWO_LEVELS = (("twist_speed_deg_s = 2.0", "twist_speed_deg_s = 0.5"), ("max_depth_mm = 0.4", "max_depth_mm = 0.8"))
UNTARED = "untared: raw gauge reading (zero gauge to tare)"

# Each chart as laid out: its width against its box and the window, where its newest time is drawn, and the
# legend entries cut off (wider than themselves or reaching out of the chart's box).
LAYOUT = """(charts) => charts.map((u) => {
  const box = u.root.parentElement, r = box.getBoundingClientRect(), dpr = devicePixelRatio;
  const xs = u.data[0].filter((v) => v != null), last = xs.length ? xs[xs.length - 1] : null;
  const legend = box.querySelector('.u-legend');
  return {
    id: box.id, width: u.width, box: box.clientWidth, right: r.right, window: document.documentElement.clientWidth,
    x_max: u.scales.x.max, t_last: last, x_last: last == null ? null : u.valToPos(last, 'x') + u.bbox.left / dpr,
    legend_cut: legend.scrollWidth > legend.clientWidth + 1,
    cut: Array.from(legend.querySelectorAll('.u-series')).filter((e) => { const s = e.getBoundingClientRect();
      return e.scrollWidth > e.clientWidth + 1 || s.right > r.right + 1 || s.left < r.left - 1; })
      .map((e) => e.textContent),
  };
})"""

# The dark pixels drawn in the strip above the plot of the run browser's first chart (the phase names), as
# runs of columns in CSS px from the canvas' left; and each frame's time at that scale.
STRIP = """((u) => {
  const dpr = devicePixelRatio, top = Math.floor(u.bbox.top), left = Math.ceil(u.bbox.left);
  const w = Math.floor(u.bbox.width), data = u.ctx.getImageData(left, 0, w, top).data, dark = [];
  for (let x = 0; x < w; x++) {
    let on = false;
    for (let y = 0; y < top && !on; y++) {
      const i = 4 * (y * w + x);
      on = data[i + 3] > 128 && data[i] < 150 && data[i + 1] < 150 && data[i + 2] < 150;
    }
    dark.push(on);
  }
  const runs = [];
  let s = -1;
  for (let x = 0; x <= w; x++) {
    if (x < w && dark[x]) { if (s < 0) s = x; continue; }
    if (s >= 0) { runs.push([(left + s) / dpr, (left + x) / dpr]); s = -1; }
  }
  const run = window.rigConsole.run;
  return { runs, plot_top: u.bbox.top / dpr, labels: u.phaseLabels, phases: run.phases, phase_index: run.phase_index,
    x: run.t_s.map((t) => u.valToPos(t, 'x') + u.bbox.left / dpr) };
})(window.rigConsole.runCharts[0])"""


# A scratch moments chart, 520 px wide, drawn by the live view's own code from a minute of a gauge at rest
# (Mz flipping between 1 and 2 N·mm every 20 ms, as the simulated gauge's quantisation does) with one 20 ms
# spike; then, once drawn, how many pixels of Mz's colour each column of its plot holds.
SCRATCH = """(() => {
  const div = document.createElement('div');
  div.className = 'chart'; div.style.width = '520px'; document.body.appendChild(div);
  const u = chart(div, ['Mx', 'My', 'Mz'], 'N·mm', COLORS.slice(3), {}, [-HISTORY_S, 0], 't (s) before now');
  const rows = [];
  for (let i = 0; i < 3000; i++) rows.push([1000 + 0.02 * i, 0, 0, 0, 4, -3, i === 1500 ? 12 : 1 + (i % 2)]);
  plotRows(u, rows, [4, 5, 6], MIN_SPAN['N·mm']);
  window.scratchChart = u; window.scratchBox = div;
  return true;
})()"""
SCRATCH_DRAWN = """(() => {
  const u = window.scratchChart, dpr = devicePixelRatio, b = u.bbox;
  const data = u.ctx.getImageData(b.left, b.top, b.width, b.height).data, thick = [];
  for (let x = 0; x < b.width; x++) {
    let n = 0;
    for (let y = 0; y < b.height; y++) {
      const i = 4 * (y * b.width + x);
      n += Math.abs(data[i] - 140) + Math.abs(data[i + 1] - 86) + Math.abs(data[i + 2] - 75) < 60 && data[i + 3] > 128;
    }
    thick.push(n / dpr);
  }
  const out = { points: u.data[0].length, plot_px: b.width / dpr, mz: u.data[3], thick,
    spike_x: u.valToPos(0.02 * (1500 - 2999), 'x') * dpr };
  u.destroy(); window.scratchBox.remove();
  return out;
})()"""


def _moment_trace_is_a_line(browser) -> None:
    page(browser, SCRATCH)
    drawn = page(browser, SCRATCH_DRAWN)
    assert drawn["points"] <= drawn["plot_px"] + 10, drawn["points"]  # about a point per pixel, not 3000
    mz = drawn["mz"]
    at = mz.index(12)  # the spike's two pixels drawn at their least and greatest, the newest sample as it is
    quiet = mz[1 : at - 1] + mz[at + 2 : -1]
    assert min(quiet) >= 1.2 and max(quiet) <= 1.8, mz  # the noise elsewhere: its mean, pixel by pixel
    spike = int(drawn["spike_x"])
    columns = [n for x, n in enumerate(drawn["thick"]) if abs(x - spike) > 4 and n]
    columns.sort()
    assert len(columns) > 0.8 * drawn["plot_px"] and columns[len(columns) // 2] <= 3, columns  # a line
    assert max(drawn["thick"][spike - 4 : spike + 5]) >= 20, drawn["thick"][spike - 4 : spike + 5]  # the spike


def _fit(browser, width: int, section: str) -> None:
    """The window ``width`` px wide and tall enough for the page down to the end of #section (from the top
    for the live view, from the section's top otherwise), scrolled there: what the screenshot shows."""
    for _ in range(2):  # the second pass: with or without a scrollbar the page is laid out again
        chrome = page(browser, "window.outerHeight - window.innerHeight")
        top, bottom = page(
            browser,
            f"(() => {{ const r = document.getElementById('{section}').getBoundingClientRect(); "
            "return [r.top + window.scrollY, r.bottom + window.scrollY]; })()",
        )
        start = 0 if section == "live" else max(0, int(top) - 8)
        browser.set_window_size(width, int(bottom) - start + 16 + chrome)
        browser.execute_script("window.scrollTo(0, arguments[0])", start)


def _layout_whole(browser, charts: str) -> None:
    for c in page(browser, f"({LAYOUT})({charts})"):
        assert c["width"] <= c["box"] and c["right"] <= c["window"] + 1, c  # not cut at the window's right
        if c["t_last"] is not None:  # the time axis reaches the newest sample, drawn inside the chart
            assert c["x_max"] >= c["t_last"] - 1e-9 and c["x_last"] <= c["box"], c
        assert c["cut"] == [] and not c["legend_cut"], c


def _disabled_controls(browser) -> list[dict]:
    return page(
        browser,
        "Array.from(document.querySelectorAll('.needs-control')).map((b) => ({id: b.id, disabled: b.disabled, "
        "title: b.title}))",
    )


def _phase_names_in_their_bands(browser) -> list[str]:
    """Every dark pixel of the strip above the first chart lies over one phase's band (the bands computed
    here from the run's frames, not the page's own); each name drawn is its band's phase; returns them."""
    s = page(browser, STRIP)
    bands, start = [], 0
    for i in range(1, len(s["x"]) + 1):
        if i == len(s["x"]) or s["phase_index"][i] != s["phase_index"][start]:
            bands.append((s["x"][start], s["x"][min(i, len(s["x"]) - 1)], s["phases"][s["phase_index"][start]]))
            start = i
    assert s["runs"], "no phase name drawn above the plot"
    for a, b in s["runs"]:
        assert any(x0 - 0.5 <= a and b <= x1 + 0.5 for x0, x1, _ in bands), ((a, b), bands)
    for label in s["labels"]:
        mid = (label["x0"] + label["x1"]) / 2
        (phase,) = [p for x0, x1, p in bands if x0 <= mid <= x1]
        assert label["name"] == phase and label["bottom"] < s["plot_top"], (label, phase, s["plot_top"])
        assert label["text"] == phase or (label["text"].endswith("…") and phase.startswith(label["text"][:-1]))
    wide = [p for x0, x1, p in bands if x1 - x0 >= 60]  # room for any phase name: each of them is named
    assert {p for p in wide} <= {label["name"] for label in s["labels"]}, (wide, s["labels"])
    return [label["text"] for label in s["labels"]]


@pytest.mark.realtime  # a live run is watched as it runs, on real time
def test_a_page_started_protocol_is_shown_as_it_runs_and_as_it_ended(tmp_path):
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import Select

    runs = tmp_path / "runs"
    runs.mkdir()
    quick = record_quick_run(runs, "two-levels", TWO_LEVELS)  # complete, every phase twice: the run browser's
    with simulated_console(runs, "rgb") as (url, options), browser_at(url) as browser:
        browser.set_window_size(WIDTHS[0], 1100)
        take_control(browser)
        # laid out as the page grew (a scrollbar came, no resize event): every chart whole in its box
        wait_for(browser, lambda d: len(page(d, "window.rigConsole.liveFz()")) > 5, "no wrench trace")
        _layout_whole(browser, "Object.values(window.rigConsole.charts)")
        idle = [b for b in _disabled_controls(browser) if b["disabled"]]
        assert not idle, idle  # with control and nothing running, every control is usable
        console_z = float(page(browser, "window.rigConsole.axes.z.position"))
        _moment_trace_is_a_line(browser)
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
        # the keys are locked as the buttons are: said on the page, nothing sent for the server to refuse
        page(browser, "(document.activeElement.blur(), true)")
        browser.find_element("tag name", "body").send_keys(Keys.PAGE_DOWN)
        said = browser.find_element("id", "control-msg").text
        assert said == "PageDown not sent: protocol sphere10mm is running (STOP ends it)", said
        canvas = browser.find_element("id", "live-frame")
        shown = page(browser, "window.rigConsole.runFrame")
        assert canvas.get_attribute("data-run") == protocol["run"] == shown["run"]
        assert 0 <= shown["index"] <= page(browser, "window.rigConsole.protocol.frame")
        info = browser.find_element("id", "frame-info").text
        assert f"of {protocol['run']}" in info and "the protocol's newest frame" in info and "paused" in info, info
        # the tare state is the gauge's that the wrench shown comes from: the protocol's rig's
        bias = options.worker._run_rig.gauge.bias
        tare_pill = browser.find_element("id", "tare-state").text
        assert tare_pill == ("tared" if any(v != 0 for v in bias) else UNTARED), (tare_pill, bias)
        assert "simulated rig" in browser.find_element("id", "axes-source").text
        # moments drawn as lines: gauge noise of about 1 N·mm over at least 20 N·mm, a constant series too
        moments = page(
            browser,
            "(() => { const u = window.rigConsole.charts.moments, mz = u.data[3].filter((v) => v != null); "
            "const flat = u.scales.y.range(u, 0.42, 0.42); return {span: u.scales.y.max - u.scales.y.min, "
            "extent: Math.max(...mz) - Math.min(...mz), n: mz.length, flat, "
            "filled: u.series.slice(1).filter((s) => s.fill && s.fill(u, 1)).length}; })()",
        )
        assert moments["n"] >= 3 and moments["span"] >= 20 and moments["filled"] == 0, moments
        assert moments["extent"] > 2 or moments["extent"] / moments["span"] < 0.1, moments  # a line, not a bar
        flat = moments["flat"]
        assert flat[1] - flat[0] >= 20 and flat[0] < 0.42 < flat[1], flat
        for width in WIDTHS:
            _fit(browser, width, "live")
            assert lock.is_displayed() and browser.find_element("id", "tare-state").is_displayed()
            _layout_whole(browser, "Object.values(window.rigConsole.charts)")
            screenshot(browser, f"console_running_{width}.png")
        assert not [e for e in page(browser, "window.rigConsole.events") if "refused" in e]  # no key got through

        # STOP: the file ends interrupted; the axes shown are the protocol's rig's as it ended
        browser.find_element("id", "stop").click()
        ended = lambda d: [e for e in page(d, "window.rigConsole.events") if "protocol sphere10mm: " in e]
        wait_for(browser, ended, "the run did not end", WAIT_S)
        event = ended(browser)[-1]
        wait_for(browser, lambda d: page(d, "window.rigConsole.protocol") is None, "still shown as running")
        with RunReader.open(runs / protocol["run"]) as run:
            last_z = float(run.rows[S.POSE_MEASURED][run.n - 1][2])
            status, reason = run.status, run.reason
        assert status == "interrupted" and "interrupted" in event, (status, event)
        lift, said = LIFT.search(reason), LIFT.search(event)
        assert lift and said and lift.groups() == said.groups(), (reason, event)  # the file and the event agree
        lifted_z = float(lift.group(2))
        source = browser.find_element("id", "axes-source").text
        assert "protocol sphere10mm's own simulated rig as it ended (interrupted)" in source, source
        # the axes say that rig's lift: z where the event says the stop lifted it, above the last frame's
        z_shown = float(page(browser, "window.rigConsole.axes.z.position"))
        assert abs(z_shown - lifted_z) < 0.01 and z_shown > last_z, (z_shown, lifted_z, last_z, event)
        assert browser.find_element("css selector", "#axis-z .pos").text == f"{z_shown:.4f} mm"
        assert browser.find_element("id", "jog-z-pos").text == f"{z_shown:.3f}"
        assert browser.find_element("id", "link-status").text == "live"
        assert not browser.find_element("id", "lock-msg").is_displayed()
        assert not any(b["disabled"] for b in _disabled_controls(browser))
        assert "is running" not in browser.find_element("id", "live").text  # nothing says it still runs
        # the wrench is the console's own gauge again, never zeroed: said so
        wait_for(browser, lambda d: d.find_element("id", "tare-state").text == UNTARED, "the tare state not said")
        run_name = protocol["run"]
        wait_for(
            browser,
            lambda d: any(p["run"] == run_name and p.get("finished") for p in page(d, "window.rigConsole.progress")),
            "the progress panel still shows the run as running",
        )
        card = browser.find_element("css selector", f"[data-run='{run_name}'] .title").text
        assert card == f"{run_name}: ended", card
        for width in WIDTHS:
            _fit(browser, width, "live")
            assert f"{lifted_z:.4f} mm" in browser.find_element("id", "axes").text
            _layout_whole(browser, "Object.values(window.rigConsole.charts)")
            screenshot(browser, f"console_stopped_{width}.png")

        # a command (zero gauge) shows the console's own rig again, which did not move, and tares its gauge
        raw_fz = float(page(browser, "window.rigConsole.wrench[2]"))
        browser.find_element("id", "zero").click()
        wait_for(browser, lambda d: d.find_element("id", "tare-state").text == "tared", "not tared")
        wait_for(browser, lambda d: abs(page(d, "window.rigConsole.wrench[2]")) < 0.1, f"Fz {raw_fz} N not tared")
        assert "this console's rig" in browser.find_element("id", "axes-source").text
        assert abs(float(page(browser, "window.rigConsole.axes.z.position")) - console_z) < 0.01

        # the run browser: the interrupted run says how it ended; a complete run, every phase, the slider moved
        Select(browser.find_element("id", "run-select")).select_by_value(run_name)
        wait_for(browser, lambda d: (page(d, "window.rigConsole.run") or {}).get("name") == run_name, "no run")
        run_info = browser.find_element("id", "run-info").text
        assert "interrupted (STOP from" in run_info and "interrupted (interrupted" not in run_info, run_info
        Select(browser.find_element("id", "run-select")).select_by_value(quick.name)
        wait_for(browser, lambda d: (page(d, "window.rigConsole.run") or {}).get("name") == quick.name, "no run")
        n = page(browser, "window.rigConsole.run.frames")
        assert len(set(page(browser, "window.rigConsole.run.phase_index"))) >= 5  # press, shear, twist and back
        for width, i in zip(WIDTHS, (n // 2, n - 3), strict=True):
            _fit(browser, width, "browser")
            before = _phase_names_in_their_bands(browser)
            browser.execute_script(
                "const s = document.getElementById('run-slider'); s.value = arguments[0]; "
                "s.dispatchEvent(new Event('input'))",
                str(i),
            )
            shown = lambda d, i=i: d.find_element("id", "run-wrench").get_attribute("data-index") == str(i)
            wait_for(browser, shown, f"frame {i} not shown")
            assert browser.find_element("id", "run-slider").get_attribute("value") == str(i)
            assert _phase_names_in_their_bands(browser) == before  # the slider moved, the names stayed put
            _layout_whole(browser, "window.rigConsole.runCharts")
            screenshot(browser, f"run_browser_slider_{width}.png")
