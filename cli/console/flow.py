"""Marker flow for the live view: how far each marker moved from the reference frame.

For marker sensors (``rgb_markers``, ``white_markers``) the rig worker hands every frame to
``MarkerFlow.offer`` (it keeps a reference to the newest, nothing more); this object's own
thread computes the flow of the newest frame at most every ``every_s`` and only while a page
wants it, so the live frame never waits for it. Markers are found and matched by
``sensor_sim.markers`` (OpenCV, SciPy; no torch). The reference is the first frame seen,
or the next one after ``set_reference``; it is shared by every page.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import numpy as np

log = logging.getLogger("rig.console")

FLOW_EVERY_S = 0.2  # at most 5 flows a second: a few ms of one core each for 400 markers
ARROW_SCALE = 5.0  # arrows drawn this many times their length: a 1 px motion is visible


class MarkerFlow:
    def __init__(
        self,
        on_flow: Callable[[dict], object],
        *,
        every_s: float = FLOW_EVERY_S,
        scale: float = ARROW_SCALE,
        now: Callable[[], float] = time.monotonic,
    ):
        self._on_flow = on_flow
        self.every_s, self.scale, self._now = every_s, scale, now
        self._lock = threading.Lock()
        self._new = threading.Event()
        self._closing = threading.Event()
        self._latest: tuple[int, float, np.ndarray] | None = None
        self._reference: np.ndarray | None = None  # the reference frame's markers (col, row), px
        self._reference_index = -1
        self._pitch_px = float("nan")  # the reference grid's pitch
        self._take_reference = True
        self._pending_reference: tuple[int, float, np.ndarray] | None = None
        self.wanted = 0  # pages that asked for flow
        self.computed = 0
        self.errors = 0
        self._thread = threading.Thread(target=self._run, name="rig-console-flow", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def close(self, timeout_s: float = 10.0) -> None:
        self._closing.set()
        self._new.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    def offer(self, index: int, t_s: float, image: np.ndarray) -> None:
        """A new camera frame (called by the worker for each; cheap)."""
        frame = (index, t_s, image.copy())  # a grabber may reuse its buffer
        with self._lock:
            self._latest = frame
            if self._take_reference:  # exactly this frame: its markers are found in the flow thread
                self._pending_reference, self._take_reference = frame, False
        self._new.set()

    @property
    def reference_index(self) -> int:
        return self._reference_index

    def set_reference(self) -> None:
        """The next frame offered becomes the reference (no contact, ideally)."""
        with self._lock:
            self._take_reference = True

    def _run(self) -> None:
        last = -np.inf
        while not self._closing.is_set():
            wait = self.every_s - (self._now() - last)
            if wait > 0:
                self._closing.wait(wait)  # bounded rate; wakes at once when closing
                continue
            if not self._new.wait(1.0):
                continue
            self._new.clear()
            with self._lock:
                latest, self._latest = self._latest, None
                pending, self._pending_reference = self._pending_reference, None
            try:
                if pending is not None:
                    self._set_reference(pending)
                if latest is not None and self.wanted > 0 and self._reference is not None:
                    last = self._now()
                    self._compute(latest)
            except Exception:
                self.errors += 1
                log.exception("marker flow failed")

    def _set_reference(self, latest: tuple[int, float, np.ndarray]) -> None:
        from sensor_sim.markers import find_markers, spacing_px

        self._reference = find_markers(latest[2])
        self._pitch_px = spacing_px(self._reference)
        self._reference_index = latest[0]

    def _compute(self, latest: tuple[int, float, np.ndarray]) -> None:
        from sensor_sim.markers import displacements

        index, t_s, image = latest
        assert self._reference is not None
        started = time.perf_counter()
        d = displacements(self._reference, image, pitch_px=self._pitch_px)
        self.computed += 1
        self._on_flow(
            {
                "type": "flow",
                "index": index,
                "t_s": t_s,
                "reference_index": self._reference_index,
                "markers": len(self._reference),
                "scale": self.scale,
                "vectors": np.round(d, 2).tolist(),  # x, y, dx, dy (px)
                "compute_ms": 1e3 * (time.perf_counter() - started),
            }
        )
