"""`rig console` on the simulated rig in a real headless browser: frame latency and frame rate.

    .venv/bin/python bench/console_bench.py [--seconds 10] [--rounds 3] [--sensor rgb_markers] [--at-rest]

The console serves `--sim` from a thread of this process; Debian's headless chromium
(chromedriver, selenium) opens the page. For each frame the page draws it posts back the
frame's capture time (the simulated camera stamps each frame when it is exposed, on the rig
clock = this host's monotonic clock); the server takes latency = arrival of that post-back −
capture time, so it covers encode, WebSocket, decode, draw and the (sub-millisecond) loopback
trip back. Frame rate = frames drawn per second over the window; the camera's own rate is the
frames the worker took from it in the same window. Three views on one console: the plain
frame, the difference from the reference (per-pixel work in the page), and the frame with
marker-flow arrows (marker sensors: markers found and matched in the console's flow thread at
most 5 times a second, arrows drawn on an overlay; flows drawn per second and the flow
thread's time per flow too). The views are interleaved over several rounds, their order
rotated each round, and each view's medians are reported with the ratio of its frames drawn
to the plain frame's, round by round: on a shared machine compare those, not absolute rates.
By default the indenter is first pressed 0.9 mm into the gel and sheared 0.3 mm (jogs through
the worker, as from the page), so that the markers move.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import threading
import time

import numpy as np

from cli.console.launch import console_options
from cli.console.server import serving_in_thread
from cli.console.worker import Command
from common.machine import describe
from common.sensors import SENSOR_KINDS


def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium") or "chromium"
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1400,1200"):
        options.add_argument(arg)
    return webdriver.Chrome(service=Service(shutil.which("chromedriver") or "chromedriver"), options=options)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="measurement window per view and round (s)")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of all views, interleaved")
    parser.add_argument("--sensor", default="rgb_markers", help="the simulated sensor kind (rgb has no marker flow)")
    parser.add_argument(
        "--at-rest", action="store_true", help="leave the indenter 5 mm above the gel (default: pressed and sheared)"
    )
    args = parser.parse_args()
    if not (args.seconds > 0 and args.seconds < 3600):
        parser.error(f"--seconds {args.seconds}: expected a number of seconds in (0, 3600)")
    if not 1 <= args.rounds <= 100:
        parser.error(f"--rounds {args.rounds}: expected 1..100")
    if args.sensor not in SENSOR_KINDS:
        parser.error(f"--sensor {args.sensor!r}: expected one of {', '.join(SENSOR_KINDS)}")
    options = console_options(config=None, sim=True, live=True, runs=[], sensor=args.sensor)
    pause = threading.Event()  # never set: a bounded wait for the measurement window
    rows = []
    with serving_in_thread(options) as url:
        worker = options.worker
        assert worker is not None and worker.ready.wait(60) and worker.error is None, worker and worker.error
        driver = browser()
        try:
            driver.get(url)
            version = driver.capabilities.get("browserVersion", "?")
            pause.wait(5.0)  # warm-up: the page loads, the first frames arrive
            if not args.at_rest:  # 0.9 mm into the gel, 0.3 mm of shear along x: markers move
                for axis, step in (("z", -5.0), ("z", -1.0), ("x", 0.3)):  # one at a time, as from the page
                    done = worker.commands_done + 1
                    worker.submit(Command("jog", axis=axis, step=step, who="bench"))
                    for _ in range(600):
                        if worker.commands_done >= done:
                            break
                        pause.wait(0.1)
                pause.wait(1.0)  # the wrench trace catches up
                fz_N = worker.history()[-1][3]
                if not fz_N > 1.0:
                    raise SystemExit(f"the indenter is not pressing (Fz {fz_N:.2f} N): see the console's events")
            views = [("frame", False, False), ("difference from reference", True, False)]
            if options.flow is not None:
                views.append(("frame + marker-flow arrows", False, True))
            for r in range(args.rounds):  # views interleaved, their order rotated: a load that drifts
                for view, diff, flow in views[r % len(views) :] + views[: r % len(views)]:  # hits all alike
                    rows.append((r, view, *measure(driver, options, args.seconds, diff, flow, pause)))
        finally:
            driver.quit()
    system = f"{platform.system()} {platform.release()}"
    print(
        f"machine: {describe()}, {system}; load average {os.getloadavg()[0]:.1f} at the end; chromium {version} "
        f"headless; sensor {args.sensor}, {'at rest' if args.at_rest else 'pressed 0.9 mm, sheared 0.3 mm'}; "
        f"{args.rounds} rounds of {args.seconds:g} s per view, medians over the rounds\n"
    )
    print("| view | camera frames/s | frames drawn/s | latency p50 (ms) | p95 (ms) | p99 (ms) | flows drawn/s |")
    print("|---|---|---|---|---|---|---|")
    names = list(dict.fromkeys(row[1] for row in rows))
    for view in names:
        mine = [row for row in rows if row[1] == view]
        med = lambda k, mine=mine: float(np.median([row[k] for row in mine]))
        lat = lambda p, mine=mine: float(np.median([row[4].get(p, float("nan")) for row in mine]))
        flows = f"{med(5):.1f}" if med(5) else "–"
        print(
            f"| {view} | {med(2):.1f} | {med(3):.1f} | {lat('p50'):.1f} | {lat('p95'):.1f} | {lat('p99'):.1f} "
            f"| {flows} |"
        )
    by_round = {(row[0], row[1]): row for row in rows}
    for view in names[1:]:
        ratios = [by_round[(r, view)][3] / by_round[(r, names[0])][3] for r in range(args.rounds)]
        print(f"\nframes drawn, {view} : {names[0]}, round by round: " + ", ".join(f"{x:.2f}" for x in ratios))
    flow_ms = [row[7] for row in rows if row[7] is not None]
    if flow_ms:
        computed = sum(row[6] for row in rows if row[7] is not None)
        print(f"marker flow: {computed} flows computed; median {np.median(flow_ms):.1f} ms each in the flow thread")


def measure(driver, options, seconds: float, diff: bool, flow: bool, pause: threading.Event) -> tuple:
    """One view for ``seconds``: camera frames/s, frames drawn/s, latency percentiles (ms),
    flows drawn/s, flows computed, the last flow's time in the flow thread (ms)."""
    worker = options.worker
    driver.execute_script(
        "document.getElementById('diff-view').checked = arguments[0];"
        " const f = document.getElementById('marker-flow');"
        " if (f.checked !== arguments[1]) {"
        " f.checked = arguments[1]; f.dispatchEvent(new Event('change')); }",
        diff,
        flow,
    )
    pause.wait(1.0)
    options.hub.reset_stats()
    sent0, t0 = worker.frames_sent, time.monotonic()
    flows0 = driver.execute_script("return window.rigConsole.flows;")
    computed0 = options.flow.computed if options.flow is not None else 0
    pause.wait(seconds)
    stats, elapsed = options.hub.stats(), time.monotonic() - t0
    flows = driver.execute_script("return window.rigConsole.flows;") - flows0
    flow_ms = driver.execute_script("return window.rigConsole.flowComputeMs;") if flow else None
    computed = (options.flow.computed - computed0) if options.flow is not None else 0
    return (
        (worker.frames_sent - sent0) / elapsed,
        stats["frames_drawn"] / elapsed,
        stats["latency_ms"],
        flows / elapsed,
        computed,
        flow_ms,
    )


if __name__ == "__main__":
    main()
