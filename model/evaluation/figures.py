"""The evaluation report's figures: error against run time, example frames, marker motion."""

from __future__ import annotations

import functools
from pathlib import Path

import cv2
import numpy as np

from model.evaluation.markers import marker_flow

TILE_PX = 160  # each example frame is drawn at least this large
FLOW_GAIN = 4.0  # marker arrows are drawn this many times their length


def error_vs_time_plot(ev, path: Path) -> None:
    """MSE, SSIM (and marker error) against seconds per image: one line per sampler
    through its step counts, the physics render as a star."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    panels = [("mse", "MSE, 0–255² (lower is better)"), ("ssim", "SSIM (higher is better)")]
    if ev.markers:
        panels.append(("marker_px", "marker error, px per marker"))
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.4), squeeze=False)
    samplers: dict[str, list] = {}
    for r in ev.rows:
        samplers.setdefault(r.setting.split(",")[0], []).append(r)
    for ax, (key, label) in zip(axes[0], panels):
        for name, rows in samplers.items():
            rows = sorted(rows, key=lambda r: r.seconds_per_image)
            pts = [(r.seconds_per_image, getattr(r, key)) for r in rows if getattr(r, key) is not None]
            if pts:
                ax.plot(*zip(*pts), "o-", label=f"model, {name}")
                for r, (x, y) in zip(rows, pts):
                    ax.annotate(
                        r.setting.split(", ")[1].split()[0],
                        (x, y),
                        textcoords="offset points",
                        xytext=(4, 4),
                        fontsize=7,
                    )
        b = ev.baseline
        if b is not None and getattr(b, key) is not None:
            ax.plot([b.seconds_per_image], [getattr(b, key)], "*", markersize=12, color="black", label="physics render")
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("seconds per image (this machine)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _tile(img: np.ndarray) -> np.ndarray:
    scale = max(1, -(-TILE_PX // img.shape[0]))
    return cv2.resize(img, (img.shape[1] * scale, img.shape[0] * scale), interpolation=cv2.INTER_NEAREST)


@functools.lru_cache(maxsize=1)
def _font():
    """matplotlib's own DejaVu Sans at 12 px (it has · θ °, which OpenCV's Hershey fonts lack)."""
    from matplotlib import font_manager
    from PIL import ImageFont

    return ImageFont.truetype(font_manager.findfont("DejaVu Sans"), 12)


def _header(text: str, width: int) -> np.ndarray:
    """A 22 px white strip with ``text`` in black, cut to the ``width // 8`` characters ``wrapped`` allows."""
    from PIL import Image, ImageDraw

    strip = Image.new("RGB", (width, 22), (255, 255, 255))
    ImageDraw.Draw(strip).text((4, 4), text[: max(4, width // 8)], fill=(0, 0, 0), font=_font())
    return np.asarray(strip)[:, :, ::-1].copy()


def samples_figure(columns: dict[str, list[np.ndarray]], path: Path, row_labels: list[str] | None = None) -> None:
    """A grid: one row per example frame, one column per source, each headed; under each row
    its label (the wrench and pose it was generated for) when given."""
    cols = []
    for name, images in columns.items():
        tiles = [_tile(im) for im in images]
        gap = np.full((4, tiles[0].shape[1], 3), 255, np.uint8)
        body = np.concatenate([x for t in tiles for x in (t, gap)][:-1], axis=0)
        cols.append(np.concatenate([_header(name, body.shape[1]), body], axis=0))
    sep = np.full((cols[0].shape[0], 4, 3), 255, np.uint8)
    grid = np.concatenate([x for c in cols for x in (c, sep)][:-1], axis=1)
    if row_labels:
        grid = _label_rows(grid, row_labels, tile_h=_tile(next(iter(columns.values()))[0]).shape[0])
    cv2.imwrite(str(path), grid)


def wrapped(text: str, width: int) -> list[str]:
    """``text`` in lines that fit a strip ``width`` px wide (``_header``'s width // 8 characters), broken
    after " | " or a space; nothing is cut off."""
    room = max(4, width // 8)
    lines: list[str] = []
    for part in text.split(" | "):
        line = ""
        for word in part.split(" "):
            candidate = f"{line} {word}" if line else word
            if len(candidate) > room and line:
                lines.append(line.strip())
                candidate = word
            line = candidate
        lines.append(line.strip())
    out: list[str] = []  # join the parts again where they fit on one line
    for line in lines:
        if out and len(out[-1]) + 3 + len(line) <= room:
            out[-1] = f"{out[-1]} | {line}"
        else:
            out.append(line)
    return out


def _label_rows(grid: np.ndarray, labels: list[str], tile_h: int) -> np.ndarray:
    """Each example row followed by strips with its label, wrapped to the grid's width (the header is
    22 px, rows are tile_h + 4 px apart)."""
    parts, top = [grid[:22]], 22
    for i, text in enumerate(labels):
        bottom = min(grid.shape[0], top + tile_h + (4 if i < len(labels) - 1 else 0))
        parts.append(grid[top:bottom])
        parts.extend(_header(line, grid.shape[1]) for line in wrapped(text, grid.shape[1]))
        top = bottom
    parts.append(grid[top:])
    return np.concatenate(parts, axis=0)


def _flow_panel(reference: np.ndarray, image: np.ndarray, colour) -> np.ndarray | None:
    try:
        start, end = marker_flow(reference, image)
    except ValueError:
        return None
    # a match half a marker pitch away or farther is the assignment filling in for a marker
    # not found (washed out under the contact), not motion: drawn, it would hide the flow
    nearest = np.sort(np.linalg.norm(start[:, None] - start[None], axis=2), axis=1)[:, 1]
    keep = np.linalg.norm(end - start, axis=1) < 0.5 * np.median(nearest)
    canvas = _tile(image)
    k = canvas.shape[0] / image.shape[0]
    for (c0, r0), (c1, r1) in zip(start[keep], end[keep]):
        a = (int(round(c0 * k)), int(round(r0 * k)))
        b = (int(round((c0 + FLOW_GAIN * (c1 - c0)) * k)), int(round((r0 + FLOW_GAIN * (r1 - r0)) * k)))
        cv2.arrowedLine(canvas, a, b, colour, 1, cv2.LINE_AA, tipLength=0.3)
    return canvas


def marker_flow_figure(ev, path: Path) -> bool:
    """Marker motion of each example: real (green), physics render (blue), model (red) for
    the last sampler setting; matches half a marker pitch away or farther are left out. False when no
    example's markers could be found."""
    sources = [("real", (0, 160, 0))]
    if "physics render" in ev.examples:
        sources.append(("physics render", (200, 60, 0)))
    if ev.rows:
        sources.append((ev.rows[-1].setting, (0, 0, 220)))
    rows: list[np.ndarray] = []
    for i, ref in enumerate(ev.references):
        panels = [_flow_panel(ref, ev.examples[name][i], colour) for name, colour in sources]
        found = [p for p in panels if p is not None]
        if len(found) == len(panels):
            rows.append(np.concatenate(found, axis=1))
    if not rows:
        return False
    header = np.concatenate([_header(name, rows[0].shape[1] // len(sources)) for name, _ in sources], axis=1)
    cv2.imwrite(str(path), np.concatenate([header, *rows], axis=0))
    return True


def _strip(images: list, size: int) -> np.ndarray:
    """Frames side by side with a 2 px white gap; a missing one (None) is a light-grey square."""
    tiles = [im if im is not None else np.full((size, size, 3), 225, np.uint8) for im in images]
    gap = np.full((size, 2, 3), 255, np.uint8)
    return np.concatenate([x for t in tiles for x in (t, gap)][:-1], axis=1)


def force_sweep_figure(sweeps: list, path: Path) -> None:
    """One component's sweep (force_sweep.PoseSweep per pose): for each pose the generated frames across
    the sweep over the reference frames (grey: none), then area, centroid and shading against the force,
    the model as solid lines, the reference as dashed (o: a real frame, x: the physics render); a dotted
    line marks the training maximum where the sweep goes past it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from model.sweeps.force_sweep import UNITS
    from model.sweeps.sweep_references import REAL, RENDER

    name = sweeps[0].component
    size = sweeps[0].images[0].shape[0]
    fig = plt.figure(figsize=(13, 2.0 * len(sweeps) + 3.2))
    grid = fig.add_gridspec(len(sweeps) + 1, 4, height_ratios=[1.6] * len(sweeps) + [2.2])
    for i, s in enumerate(sweeps):
        ax = fig.add_subplot(grid[i, :])
        strip = np.concatenate(
            [
                _strip(s.images, size),
                np.full((2, 1, 3), 255, np.uint8).repeat(_strip(s.images, size).shape[1], 1),
                _strip(s.reference_images, size),
            ],
            axis=0,
        )
        ax.imshow(strip[..., ::-1], interpolation="nearest")
        ax.set_xticks([(size + 2) * j + size / 2 for j in range(len(s.values))])
        ax.set_xticklabels([f"{v:.2f}" for v in s.values], fontsize=7)
        ax.set_yticks([size / 2, size * 1.5 + 2])
        ax.set_yticklabels(["model", "reference"], fontsize=7)
        ax.set_title(f"pose {i + 1}: {s.label}   (tiles: {name} in {UNITS[name]})", fontsize=7, loc="left")
    panels = [
        ("area_mm2", "contact area, mm²"),
        ("centroid_x_mm", "centroid x, mm"),
        ("centroid_y_mm", "centroid y, mm (+y up)"),
        ("shading", "shading, mean |change| (0–255)"),
    ]
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j, (key, label) in enumerate(panels):
        ax = fig.add_subplot(grid[len(sweeps), j])
        for i, s in enumerate(sweeps):
            c = colours[i % len(colours)]
            ax.plot(s.values, [getattr(m, key) for m in s.model], "-", color=c, label=f"model, pose {i + 1}")
            for marker, kind in (("o", REAL), ("x", RENDER)):
                pts = [
                    (v, getattr(m, key))
                    for v, m, k in zip(s.values, s.reference, s.kinds or [""] * len(s.values))
                    if m is not None and k == kind
                ]
                if pts:
                    ax.plot(
                        *zip(*pts),
                        "--" + marker,
                        color=c,
                        markersize=4,
                        label=f"reference ({kind}), pose {i + 1}",
                    )
            if s.inside and not all(s.inside):
                ax.axvline(max(v for v, ok in zip(s.values, s.inside) if ok), color="grey", linestyle=":", linewidth=1)
        ax.set_xlabel(f"{name}, {UNITS[name]} (swept)", fontsize=8)
        ax.set_ylabel(label, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
        if j == 0:
            ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
