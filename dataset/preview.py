"""A contact sheet of a run: evenly spaced frames labelled with their wrenches."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from acquisition import schema as S
from acquisition.run_file import RunFileError
from dataset.runs import open_run, read


def preview(path: str | Path, out: str | Path, *, tiles: int = 24, tile_px: int = 160) -> int:
    """A contact sheet of evenly spaced frames, each labelled with its frame index and wrench."""
    with open_run(path) as f:
        n = f[S.FRAMES].shape[0]
        if n == 0:
            raise RunFileError(f"{path}: no frames to preview")
        picks = np.unique(np.linspace(0, n - 1, min(tiles, n)).astype(int))
        images = []
        for i in picks:
            img = cv2.resize(read(f, S.FRAMES, int(i)), (tile_px, tile_px), interpolation=cv2.INTER_AREA)
            w = read(f, S.WRENCH, int(i))
            for line, text in enumerate(
                (f"#{i}", f"F {w[0]:+.2f} {w[1]:+.2f} {w[2]:+.2f} N", f"M {w[3]:+.0f} {w[4]:+.0f} {w[5]:+.1f} Nmm")
            ):
                cv2.putText(
                    img, text, (4, 14 + 14 * line), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (255, 255, 255), 1, cv2.LINE_AA
                )
            images.append(img)
    cols = 6
    while len(images) % cols:
        images.append(np.zeros_like(images[0]))
    sheet = np.vstack([np.hstack(images[r : r + cols]) for r in range(0, len(images), cols)])
    cv2.imwrite(str(out), sheet)
    return len(picks)
