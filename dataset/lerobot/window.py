"""The gauge between frames: a fixed-size window of its full-rate samples per frame.

The gauge runs faster than the camera (the simulated rig's at 25 Hz, frames at 1 Hz). Each frame gets the
samples of the capture period that ends at it, t in (t_frame − 1/fps, t_frame], oldest first, as an
array of W rows of the six components (W: the most samples any exported frame's period holds). A
period with fewer samples is padded at its start with its oldest sample (``…_is_pad`` True there); one
with none holds zeros, all padding. ``…_t_s`` is each sample's time from the frame, in s (≤ 0).
The whole stream, samples outside every window included, is in meta/tactile (layout.py).
"""

from __future__ import annotations

import numpy as np

from acquisition import schema as S
from dataset.lerobot import layout as L


class WrenchWindows:
    def __init__(self, runs, fps: int, episodes) -> None:
        self.period_s = 1.0 / fps
        self._streams = [
            np.asarray(r.stream, dtype=np.float64) if r.stream is not None else np.zeros((0, 7)) for r in runs
        ]
        self._t = [np.asarray(r.rows[S.T_FRAME], dtype=np.float64) for r in runs]
        width = 0
        for e in episodes:
            lo, hi = self._bounds(e.run, e.frames)
            if len(lo):
                width = max(width, int((hi - lo).max()))
        self.width = width

    def _bounds(self, run: int, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t_stream = self._streams[run][:, 0]
        t = self._t[run][frames]
        return (np.searchsorted(t_stream, t - self.period_s, side="right"), np.searchsorted(t_stream, t, side="right"))

    def columns(self, episode) -> dict[str, np.ndarray]:
        if not self.width:
            return {}
        n, w = len(episode.frames), self.width
        stream = self._streams[episode.run]
        window = np.zeros((n, w, 6))
        dt = np.zeros((n, w))
        pad = np.ones((n, w), dtype=bool)
        lo, hi = self._bounds(episode.run, episode.frames)
        t = self._t[episode.run][episode.frames]
        for k in range(n):
            rows = stream[lo[k] : hi[k]]
            if not len(rows):
                continue
            m = len(rows)
            window[k, w - m :] = rows[:, 1:]
            dt[k, w - m :] = rows[:, 0] - t[k]
            window[k, : w - m] = rows[0, 1:]
            dt[k, : w - m] = rows[0, 0] - t[k]
            pad[k, w - m :] = False
        return {L.WINDOW: window, L.WINDOW_T: dt, L.WINDOW_PAD: pad}
