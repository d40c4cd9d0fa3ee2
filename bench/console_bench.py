"""`rig console` on the simulated rig in a real headless browser: frame latency and frame rate.

    .venv/bin/python bench/console_bench.py [--seconds 20]

The console serves `--sim` from a thread of this process; Debian's headless chromium
(chromedriver, selenium) opens the page. For each frame the page draws it posts back the
frame's capture time (the simulated camera stamps each frame when it is exposed, on the rig
clock = this host's monotonic clock); the server takes latency = arrival of that post-back −
capture time, so it covers encode, WebSocket, decode, draw and the (sub-millisecond) loopback
trip back. Frame rate = frames drawn per second over the window; the camera's own rate is the
frames the worker took from it in the same window. Two views: the plain frame, and the
difference from the reference (per-pixel work in the page).
"""

from __future__ import annotations

import argparse
import platform
import shutil
import threading
import time

from cli.console.launch import console_options
from cli.console.server import serving_in_thread
from common.machine import describe


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
    parser.add_argument("--seconds", type=float, default=20.0, help="measurement window per view (s)")
    args = parser.parse_args()
    options = console_options(config=None, sim=True, live=True, runs=[])
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
            for view, diff in (("frame", False), ("difference from reference", True)):
                driver.execute_script("document.getElementById('diff-view').checked = arguments[0];", diff)
                pause.wait(1.0)
                options.hub.reset_stats()
                sent0, t0 = worker.frames_sent, time.monotonic()
                pause.wait(args.seconds)
                stats, elapsed = options.hub.stats(), time.monotonic() - t0
                camera_fps = (worker.frames_sent - sent0) / elapsed
                drawn_fps = stats["frames_drawn"] / elapsed
                rows.append((view, camera_fps, drawn_fps, stats["latency_ms"]))
        finally:
            driver.quit()
    system = f"{platform.system()} {platform.release()}"
    print(f"machine: {describe()}, {system}; chromium {version} headless; {args.seconds:g} s per view\n")
    print("| view | camera frames/s | frames drawn/s | latency p50 (ms) | p95 (ms) | p99 (ms) |")
    print("|---|---|---|---|---|---|")
    for view, camera_fps, drawn_fps, lat in rows:
        p50, p95, p99 = (lat.get(k, float("nan")) for k in ("p50", "p95", "p99"))
        print(f"| {view} | {camera_fps:.1f} | {drawn_fps:.1f} | {p50:.1f} | {p95:.1f} | {p99:.1f} |")


if __name__ == "__main__":
    main()
