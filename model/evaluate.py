"""Evaluate a trained run on a split's test part: the paper's metrics, per sampler setting.

For each (sampler, steps) setting: MSE, MAE, SSIM, PSNR (model/metrics.py), the
marker displacement error for marker sensors, and the seconds per generated image;
beside them the simulator's physics render of the same frames (model/baseline.py)
as the lighting-model baseline row. ``report`` writes the table (Markdown + JSON),
the error-against-run-time plot, example frames and, for marker sensors, marker
motion images (model/figures.py).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import h5py
import numpy as np

from acquisition import schema as S
from acquisition.schema import RIG_CONFIG_MARK
from dataset.torch_dataset import TactileDataset, spread, uint8_tensor_to_image
from model.inference import TrainedModel
from model.markers import marker_error
from model.metrics import image_metrics

PAPER_ROWS = [  # docs/reference.md, "The model, as the paper states it": real data, 0–255 scale
    ("TACTO (RGB light)", 201.87, 10.31, 0.80, 25.43),
    ("Taxim (RGB light)", 56.715, 5.14, 0.88, 31.12),
    ("FOTS (RGB light)", 53.267, 4.91, 0.89, 32.30),
    ("paper, RGB light", 21.00, 3.39, 0.97, 36.62),
    ("paper, RGB light + markers", 28.02, 3.24, 0.95, 34.28),
    ("paper, white light + markers", 67.09, 5.27, 0.81, 30.91),
]
PHYSICS = "physics render"


@dataclass
class Row:
    setting: str
    mse: float
    mae: float
    ssim: float
    psnr: float
    marker_px: float | None  # mean per marker over frames whose markers were found
    seconds_per_image: float
    images: int
    marker_failures: int = 0  # frames where 18×18 markers could not be found/matched
    network_evaluations: int = 0  # forward passes of the network per image (sampler steps); 0: not the model


@dataclass
class Evaluation:
    rows: list[Row]  # this model, one per sampler setting
    baseline: Row | None  # the physics render
    baseline_note: str  # why there is no baseline row, when there is none
    markers: bool
    simulated: bool = False  # every frame came from the simulated rig
    examples: dict[str, list[np.ndarray]] = field(default_factory=dict)  # column → BGR images of the example frames
    example_labels: list[str] = field(default_factory=list)  # each example row's wrench and pose
    context: dict[str, str] = field(default_factory=dict)  # what was evaluated, how, and on which machine
    references: list[np.ndarray] = field(default_factory=list)  # each example's no-contact frame


def _score(setting: str, real: list[np.ndarray], made: list[np.ndarray], seconds: float, markers: bool) -> Row:
    metrics = [image_metrics(r, m) for r, m in zip(real, made)]
    marker, failures = None, 0
    if markers:
        errors = []
        for r, m in zip(real, made):
            try:
                errors.append(marker_error(r, m).per_marker_px)
            except ValueError:
                failures += 1
        marker = float(np.mean(errors)) if errors else None
    mean = {k: float(np.mean([m[k] for m in metrics])) for k in ("mse", "mae", "ssim", "psnr")}
    return Row(setting, mean["mse"], mean["mae"], mean["ssim"], mean["psnr"], marker, seconds, len(real), failures)


def evaluate(
    run_dir: str | Path,
    split_dir: str | Path,
    *,
    part: str = "test",
    settings=(("ddim", 50),),
    limit: int | None = None,
    seed: int = 0,
    markers: bool | None = None,
    baseline: bool = True,
    device: str = "cpu",
    batch_size: int = 64,
    n_examples: int = 6,
    log: Callable[[str], None] = lambda line: None,
    profile: str | Path | None = None,
) -> Evaluation:
    """``limit`` frames spread evenly over the part (all by default); ``markers`` None: on
    when the split's sensor has markers. ``profile``: the sensor profile TOML of the physics
    render (default: each run's recorded profile, else the shipped one; model/baseline.py)."""
    model = TrainedModel.load(run_dir, device=device)
    data = TactileDataset(split_dir, part, size=model.cfg.image_size)
    if len(data) == 0:
        raise ValueError(f"{split_dir}: the {part} part is empty")
    items = [data[int(i)] for i in spread(len(data), limit)]
    if markers is None:
        markers = any(str(r.get("sensor", "")).endswith("_markers") for r in data.manifest["runs"])
    real = [uint8_tensor_to_image(it["tactile"]) for it in items]
    ex = spread(len(items), n_examples)
    ev = Evaluation([], None, "", markers)
    ev.examples["object at pose"] = [uint8_tensor_to_image(items[i]["condition"]) for i in ex]
    ev.examples["real"] = [real[i] for i in ex]
    ev.references = _references(data, [items[i]["run"] for i in ex], model.cfg.image_size)
    ev.example_labels = [_label(data, items[i]) for i in ex]
    ev.context = _context(model, data, part, len(items))
    ev.simulated = all(_simulated(path) for path in data.runs)

    if baseline:
        from model.baseline import BaselineUnavailable, render_frames
        from sensor_sim.profile import load_profile

        sensor = load_profile(profile) if profile is not None else None  # a bad file: ProfileError, one line
        try:
            rows = np.array([[it["run"], it["frame"]] for it in items])
            poses = np.stack([it["pose"].numpy() for it in items])
            which = f"sensor profile {sensor.name} ({sensor.path})" if sensor else "each run's sensor profile"
            log(f"physics render of {len(items)} frames with {which}")
            rendered, seconds = render_frames(data.runs, rows, poses, model.cfg.image_size, sensor)
            ev.baseline = _score(PHYSICS, real, rendered, seconds, markers)
            ev.examples[PHYSICS] = [rendered[i] for i in ex]
        except BaselineUnavailable as exc:
            ev.baseline_note = str(exc)
    else:
        ev.baseline_note = "not asked for (--no-baseline)"

    if settings:  # warm-up: the first timed setting should not pay for first-call costs
        list(model.generate_items(items[:1], steps=2, sampler=settings[0][0], seed=seed))
    for sampler, steps in settings:
        made: list[np.ndarray] = []
        t0 = time.perf_counter()
        for img in model.generate_items(items, steps=steps, sampler=sampler, seed=seed, batch_size=batch_size):
            made.append(img)
            if len(made) % batch_size == 0 or len(made) == len(items):
                log(f"{sampler} {steps} steps: {len(made)}/{len(items)} frames")
        seconds = (time.perf_counter() - t0) / len(items)
        setting = f"{sampler}, {steps} steps"
        row = _score(setting, real, made, seconds, markers)
        row.network_evaluations = steps  # guidance runs both halves in one batched pass
        ev.rows.append(row)
        ev.examples[setting] = [made[i] for i in ex]
    return ev


def _label(data: TactileDataset, item: dict) -> str:
    """An example row's condition in numbers: the wrench (N, N·mm) and the pose (mm, deg)."""
    w = item["wrench"].numpy() * data.std + data.mean
    x, y, z, theta = (float(v) for v in item["pose"].numpy())
    # ASCII only: OpenCV's figure text has no glyphs for · θ °
    return (
        f"Fz {w[2]:.2f} N  Fx {w[0]:+.2f}  Fy {w[1]:+.2f}  Mz {w[5]:+.1f} Nmm | "
        f"x {x:+.2f}  y {y:+.2f}  z {z:+.2f} mm  theta {theta:+.1f} deg"
    )


def _context(model: TrainedModel, data: TactileDataset, part: str, frames: int) -> dict[str, str]:
    """What the report is about, stated at its top: sizes, model, split and machine."""
    import os

    import torch

    from common.machine import describe

    cfg, m = model.cfg, data.manifest
    objects = sorted({str(r.get("object", "?")) for r in m["runs"]})
    device = str(model.device)
    if model.device.type == "cuda":
        device += f" ({torch.cuda.get_device_name(model.device)})"
    return {
        "image size": f"{cfg.image_size}×{cfg.image_size} px (the model's own; frames resized to it)",
        "model": f"{cfg.network}, widths {list(cfg.block_out_channels)}, {cfg.layers_per_block} resnet block(s) "
        f"per level, predicts {cfg.prediction}",
        "conditioning": cfg.conditioning,
        "split": f"by {m.get('by', '?')}, ratios {m.get('ratios', '?')}, seed {m.get('seed', '?')}; evaluated part "
        f"{part!r}, {frames} frames; objects in the split: {', '.join(objects)}",
        "machine": f"{describe()}, device {device}, torch "
        f"{torch.__version__} with {torch.get_num_threads()} thread(s); load average at the start "
        f"{os.getloadavg()[0]:.1f} (timings are warm, after one untimed batch, and share the machine "
        "with whatever else ran)",
    }


def _simulated(run_path: str) -> bool:
    with h5py.File(run_path, "r", swmr=True) as f:
        return str(f.attrs.get(S.ATTR_RIG_CONFIG, "")).startswith(RIG_CONFIG_MARK)


def _references(data: TactileDataset, runs: list[int], size: int) -> list[np.ndarray]:
    import cv2

    cache: dict[int, np.ndarray] = {}
    for run in set(runs):
        with h5py.File(data.runs[run], "r", swmr=True) as f:
            ref = f[S.REFERENCE_FRAME][()]
        cache[run] = ref if ref.shape[0] == size else cv2.resize(ref, (size, size), interpolation=cv2.INTER_AREA)
    return [cache[r] for r in runs]


def _fmt_row(name: str, r: Row) -> str:
    if r.marker_px is None:
        mk = "—" if not r.marker_failures else f"— ({r.marker_failures} frames without markers)"
    else:
        mk = f"{r.marker_px:.2f}" + (f" ({r.marker_failures} frames failed)" if r.marker_failures else "")
    per_nfe = f"{r.seconds_per_image / r.network_evaluations:.5f}" if r.network_evaluations else "—"
    return (
        f"| {name} | {r.mse:.2f} | {r.mae:.2f} | {r.ssim:.3f} | {r.psnr:.2f} | {mk} | {r.seconds_per_image:.4f} "
        f"| {per_nfe} |"
    )


def report(ev: Evaluation, out: str | Path, *, title: str) -> Path:
    """report.md + metrics.json + error_vs_time.png + samples.png (+ marker_flow.png) in ``out``."""
    from model.figures import error_vs_time_plot, marker_flow_figure, samples_figure

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    n = ev.rows[0].images if ev.rows else 0
    lines = [f"# {title}", ""]
    lines += [f"- **{key}**: {value}" for key, value in ev.context.items()]
    lines += [
        "",
        f"{n} held-out frames. Metrics as docs/reference.md#metrics defines them (0–255 scale, all channels, "
        "whole image); marker error: mean distance per matched marker of the central 18×18, in px at the "
        "evaluated size.",
        "",
        "| method | MSE | MAE | SSIM | PSNR | marker px/marker | s / image | s / network evaluation |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in ev.rows:
        lines.append(_fmt_row(f"this model ({r.setting})", r))
    if ev.baseline is not None:
        lines.append(_fmt_row("physics render: the simulator's mechanics + lighting at the measured pose", ev.baseline))
    for name, mse_, mae_, ssim_, psnr_ in PAPER_ROWS:
        lines.append(f"| {name} (paper's table, real data, 256 px) | {mse_} | {mae_} | {ssim_} | {psnr_} | — | — | — |")
    if ev.baseline is None:
        lines += ["", f"No physics-render row: {ev.baseline_note}"]
    elif ev.simulated:
        lines += [
            "",
            "These frames come from the simulated rig, so the physics render is the model that made them: "
            "it differs from them only by sensor noise and the friction history of earlier frames. Here it "
            "is an oracle, not a baseline; on frames from a real sensor it is the lighting-model baseline.",
        ]
    lines += [
        "",
        "## Error against run time",
        "",
        "![error against seconds per image](error_vs_time.png)",
        "",
        "## Examples",
        "",
        "Columns: " + ", ".join(ev.examples) + ".",
        "",
        "![examples](samples.png)",
    ]
    error_vs_time_plot(ev, out / "error_vs_time.png")
    samples_figure(ev.examples, out / "samples.png", ev.example_labels)
    if ev.markers:
        made = marker_flow_figure(ev, out / "marker_flow.png")
        if made:
            lines += [
                "",
                "## Marker motion",
                "",
                "Arrows from each central marker at rest (the run's no-contact frame) to where it is found, "
                "drawn ×4: real, physics render, this model.",
                "",
                "![marker motion](marker_flow.png)",
            ]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    payload = {
        "model": [asdict(r) for r in ev.rows],
        "physics_render": asdict(ev.baseline) if ev.baseline else None,
        "physics_render_note": ev.baseline_note,
    }
    (out / "metrics.json").write_text(json.dumps(payload, indent=2) + "\n")
    return out / "report.md"
