"""Texture fidelity over a run's frames: where the contact is, which band to look in, and the
blurred-contact baseline (the real frame low-passed at a model's resolution: the most texture
a perfect model of that size could show).

Scores are taken at the real frame's own resolution: a generated frame is resized up to it
(bicubic), as a user would look at it beside the real one. ``texture_rows`` gives the mean and
the 95 % bootstrap interval over frames of each measure (model/evaluation/texture_measure.py).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from model.evaluation.texture_measure import MIN_CONTACT_PX, TextureBand, texture_score

CONTACT_LEVELS = 6.0  # grey levels of change from the background that mark the contact (noise is ~1)
CONTACT_SMOOTH_PX = 3.0


def board_band(object_name: str, mm_per_px: float) -> TextureBand | None:
    """The texture band of a library board (objects/indenters.py ``texture_mm``); None for a shape."""
    from objects.indenters import INDENTERS

    if object_name not in INDENTERS:
        return None
    periods = INDENTERS[object_name]().texture_mm
    return None if periods is None else TextureBand(periods[0], periods[1], mm_per_px)


def contact_mask(frame: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Where the frame differs from the sensor's unpressed background by more than CONTACT_LEVELS
    (grey, smoothed over CONTACT_SMOOTH_PX): the pressed part of the gel."""
    diff = np.abs(np.asarray(frame, np.float32).mean(axis=2) - np.asarray(background, np.float32).mean(axis=2))
    diff = cv2.GaussianBlur(diff, (0, 0), CONTACT_SMOOTH_PX)
    return diff > CONTACT_LEVELS


def to_size(frame: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``frame`` resized to (height, width): area-averaged down, bicubic up."""
    h, w = shape
    if frame.shape[:2] == (h, w):
        return frame
    shrinking = frame.shape[0] > h
    out = cv2.resize(frame, (w, h), interpolation=cv2.INTER_AREA if shrinking else cv2.INTER_CUBIC)
    return np.clip(out, 0, 255).astype(np.uint8) if frame.dtype == np.uint8 else out


def blurred_contact(frame: np.ndarray, size_px: int) -> np.ndarray:
    """The real frame through a model's resolution and back: what a perfect model of that size shows."""
    h, w = frame.shape[:2]
    small = to_size(frame, (size_px, round(size_px * w / h)))
    return to_size(small, (h, w))


def texture_rows(
    real: list[np.ndarray], made: list[np.ndarray], backgrounds: list[np.ndarray], band: TextureBand
) -> dict[str, tuple[float, float, float]] | str:
    """{measure: (mean, low, high)} over the frames with a contact, or a one-line reason why the
    frames cannot be scored (the band unresolved, no contact)."""
    from model.evaluation.intervals import bootstrap_interval

    if not band.resolved():
        return (
            f"not scored: the texture's shortest period {band.shortest_mm:g} mm is {band.shortest_px:.1f} px "
            "at this resolution, under the 2 px a frame needs to show it"
        )
    values: dict[str, list[float]] = {}
    for r, m, bg in zip(real, made, backgrounds):
        mask = contact_mask(r, bg)
        if int(mask.sum()) < MIN_CONTACT_PX:
            continue
        score = texture_score(r, to_size(m, r.shape[:2]), mask, band).as_dict()
        for k, value in score.items():
            if math.isfinite(value):
                values.setdefault(k, []).append(value)
    if not values:
        return "not scored: no frame has a contact"
    out = {}
    for k, per_frame in values.items():
        low, high = bootstrap_interval(per_frame)
        out[k] = (float(np.mean(per_frame)), float(low), float(high))
    return out


BLURRED = "blurred contact (the real frame at the model's resolution)"
FIGURE_ROWS = ("this model", "baseline: physics render", "baseline: nearest")  # the figure's rows besides the real


def texture_table(
    runs: list[str], rows: np.ndarray, objects: list[str], made: dict[str, list[np.ndarray]], size_px: int
) -> tuple[dict[str, dict[str, dict[str, tuple[float, float, float]] | str]], dict[str, tuple]]:
    """({board: {row name: measures or why not scored}}, {board: (example frames by label at the
    run's resolution, the contact mask, the band)}) for the frames of texture boards.

    ``runs``: the split's run files; ``rows``: (n, 2) run index and frame index of each frame;
    ``objects``: each frame's object; ``made``: {row name: the n frames at the model's size}
    (the model's settings and the baselines). Real frames are read at their own resolution
    through the verified read path; each row's frames are scored there, beside the
    blurred-contact row, the most a model of ``size_px`` can show."""
    from acquisition.run_reader import RunReader

    boards = sorted({o for o in objects if board_band(o, 1.0) is not None})
    out: dict[str, dict[str, dict[str, tuple[float, float, float]] | str]] = {}
    examples: dict[str, tuple] = {}
    for board in boards:
        picked = [i for i, o in enumerate(objects) if o == board]
        real, backgrounds, scale = [], [], None
        for run in sorted({int(rows[i, 0]) for i in picked}):
            with RunReader.open(runs[run]) as reader:
                background = reader.image("reference_frame")
                scale = reader.number("mm_per_px")
                for i in picked:
                    if int(rows[i, 0]) == run:
                        real.append((i, reader.frame(int(rows[i, 1]))))
                        backgrounds.append((i, background))
        real.sort(key=lambda t: t[0])
        backgrounds.sort(key=lambda t: t[0])
        order = [i for i, _ in real]
        full = [f for _, f in real]
        bgs = [b for _, b in backgrounds]
        assert scale is not None
        band = board_band(board, scale)
        assert band is not None
        model_band = board_band(board, full[0].shape[1] * scale / size_px)
        assert model_band is not None
        table: dict[str, dict[str, tuple[float, float, float]] | str] = {}
        if not model_band.resolved():
            why = texture_rows([], [], [], model_band)
            table = {name: why for name in [*made, BLURRED]}
        else:
            table[BLURRED] = texture_rows(full, [blurred_contact(f, size_px) for f in full], bgs, band)
            for name, frames in made.items():
                table[name] = texture_rows(full, [frames[i] for i in order], bgs, band)
        out[board] = table
        k = len(full) // 2  # a frame from the middle of the part (deeper presses come later in a run)
        shown = {"real": full[k], BLURRED: blurred_contact(full[k], size_px)}
        shown |= {
            name: to_size(frames[order[k]], full[k].shape[:2])
            for name, frames in made.items()
            if name.startswith(FIGURE_ROWS)
        }
        examples[board] = (shown, contact_mask(full[k], bgs[k]), band)
    return out, examples
