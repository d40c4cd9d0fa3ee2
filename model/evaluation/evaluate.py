"""Evaluate a trained run on a split's test part: the paper's metrics, per sampler setting.

For each (sampler, steps) setting: MSE, MAE, SSIM, PSNR (model/evaluation/metrics.py), the
marker displacement error for marker sensors, and the seconds per generated image;
beside them the simulator's physics render of the same frames (model/conditioning/baseline.py)
as the lighting-model baseline row; optionally the force-response check
(model/sweeps/force_sweep.py). ``evaluate_parts`` evaluates every test part a split has —
``test`` (unseen frames of the training objects) and ``test_object`` (objects held out
of training, ``dataset split --hold-out``) — and ``report`` writes one report with a
section per part: the table (Markdown + JSON), the error-against-run-time plot, example
frames, the force sweep and, for marker sensors, marker motion images (model/evaluation/figures.py).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader
from acquisition.schema import RIG_CONFIG_MARK
from common.eta import Eta
from common.wording import signed
from dataset.torch_dataset import TactileDataset, spread, uint8_tensor_to_image
from model.evaluation.eval_results import PAPER_ROWS, PHYSICS, Evaluation, Row
from model.evaluation.markers import marker_error
from model.evaluation.metrics import image_metrics
from model.generation.inference import TrainedModel
from model.sweeps.sweep_references import RunData

__all__ = ["PAPER_ROWS", "PHYSICS", "Evaluation", "Row", "evaluate", "evaluate_parts", "report"]


def _score(setting: str, real: list[np.ndarray], made: list[np.ndarray], seconds: float, markers: bool) -> Row:
    """The mean of each metric over the frames, its 95 % bootstrap interval over them and the
    per-frame values (kept for the seed comparison and metrics.json)."""
    from model.evaluation.intervals import bootstrap_interval

    metrics = [image_metrics(r, m) for r, m in zip(real, made)]
    per_frame = {k: [m[k] for m in metrics] for k in ("mse", "mae", "ssim", "psnr")}
    marker, failures = None, 0
    if markers:
        errors = []
        for r, m in zip(real, made):
            try:
                errors.append(marker_error(r, m).per_marker_px)
            except ValueError:
                failures += 1
        marker = float(np.mean(errors)) if errors else None
        if errors:
            per_frame["marker_px"] = errors
    mean = {k: float(np.mean(v)) for k, v in per_frame.items()}
    row = Row(setting, mean["mse"], mean["mae"], mean["ssim"], mean["psnr"], marker, seconds, len(real), failures)
    row.per_frame = per_frame
    row.ci = {k: bootstrap_interval(v) for k, v in per_frame.items()}
    return row


@dataclass
class SweepOptions:
    """The force-response check: ``poses`` test poses, ``points`` values per component, generated
    with ``sampler`` for ``steps`` steps (the same initial noise at every point)."""

    poses: int = 8  # spread over the field and the loads (force_sweep.choose_poses)
    points: int = 7
    sampler: str = "ddim"
    steps: int = 10
    components: tuple[str, ...] = ("Fz", "Fx", "Fy", "Mz")
    beyond: float = 1.0  # Fz also at two values up to this share of its range past the training maximum


def evaluate(
    run_dir: str | Path,
    split_dir: str | Path,
    *,
    part: str = "test",
    device: str = "cpu",
    precision: str = "auto",
    **kwargs,
) -> Evaluation:
    """One part of a split (``evaluate_part``'s options; ``precision``: TrainedModel.load's)."""
    return evaluate_part(TrainedModel.load(run_dir, device=device, precision=precision), split_dir, part=part, **kwargs)


def test_parts(split_dir: str | Path) -> list[str]:
    """The parts ``evaluate_parts`` reports on by default: test, test_object, test_run and test_force,
    those the split has."""
    from dataset.split import TEST_PARTS, load_split

    manifest, _ = load_split(split_dir)
    return [p for p in TEST_PARTS if p in manifest["parts"]] or [list(manifest["parts"])[-1]]


def evaluate_parts(
    run_dir: str | Path,
    split_dir: str | Path,
    *,
    parts: list[str] | None = None,
    device: str = "cpu",
    precision: str = "auto",
    log: Callable[[str], None] = lambda line: None,
    **kwargs,
) -> list[Evaluation]:
    """Every test part of the split (``parts``; default ``test_parts``), the model loaded once.
    With the physics row (the default), every run's profile is settled first: a run that records
    none, with no ``profile`` given, is refused before anything is generated (NoProfile)."""
    from dataset.split import check_unchanged, load_split

    manifest, _ = load_split(split_dir)
    check_unchanged(manifest, split_dir)  # a run file changed since the split: refused before anything loads
    if kwargs.get("baseline", True):
        _check_profiles(split_dir, kwargs.get("profile"))
    model = TrainedModel.load(run_dir, device=device, precision=precision)
    out = []
    for part in parts or test_parts(split_dir):
        log(f"part {part}:")
        out.append(evaluate_part(model, split_dir, part=part, log=log, **kwargs))
    return out


def evaluate_part(
    model: TrainedModel,
    split_dir: str | Path,
    *,
    part: str = "test",
    settings=(("ddim", 50),),
    limit: int | None = None,
    seed: int = 0,
    markers: bool | None = None,
    baseline: bool = True,
    batch_size: int = 64,
    n_examples: int = 6,
    log: Callable[[str], None] = lambda line: None,
    profile: str | Path | None = None,
    sweep: SweepOptions | None = None,
    clock: Callable[[], float] = time.perf_counter,
) -> Evaluation:
    """``limit`` frames spread evenly over the part (all by default); ``markers`` None: on
    when the split's sensor has markers. ``profile``: the sensor profile TOML of the physics
    render (default: each run's recorded profile, else the shipped one; model/conditioning/baseline.py).
    ``sweep``: run the force-response check too (model/sweeps/force_sweep.py)."""
    data = TactileDataset(split_dir, part, size=model.cfg.image_size)
    if len(data) == 0:
        raise ValueError(f"{split_dir}: the {part} part is empty")
    items = [data[int(i)] for i in spread(len(data), limit)]
    if markers is None:
        markers = any(str(r.get("sensor", "")).endswith("_markers") for r in data.manifest["runs"])
    real = [uint8_tensor_to_image(it["tactile"]) for it in items]
    ex = spread(len(items), n_examples)
    ev = Evaluation([], None, "", markers, part=part)
    ev.objects = sorted({str(data.manifest["runs"][int(r)].get("object", "?")) for r in np.unique(data.rows[:, 0])})
    trained_on = set(data.manifest.get("objects", {}).get("train", []))
    ev.unseen_objects = part != "train" and bool(trained_on) and not trained_on & set(ev.objects)
    ev.test_runs = [str(r) for r in data.manifest.get("test_runs") or []]
    ev.examples["object at pose"] = [uint8_tensor_to_image(items[i]["condition"]) for i in ex]
    ev.examples["real"] = [real[i] for i in ex]
    ev.references = _references(data, [items[i]["run"] for i in ex], model.cfg.image_size)
    ev.example_labels = [_label(data, items[i]) for i in ex]
    ev.context = _context(model, data, part, len(items))
    ev.simulated = all(_simulated(path) for path in data.runs)

    by_row: dict[str, list[np.ndarray]] = {}  # each row's frames, for the texture measure of board frames
    if baseline:
        from model.conditioning.baseline import BaselineUnavailable, render_frames
        from sensor_sim.profile import load_profile

        sensor = load_profile(profile) if profile is not None else None  # a bad file: ProfileError, one line
        runs = sorted({int(it["run"]) for it in items})
        sources = _profiles(data, runs, sensor)  # a run without a profile, none given: NoProfile, refused
        ev.profiles = {data.runs[r]: sources[r] for r in runs}
        try:
            rows = np.array([[it["run"], it["frame"]] for it in items])
            poses = np.stack([it["pose"].numpy() for it in items])
            for r in runs:
                log(f"baseline physics render of {data.runs[r]}: sensor profile {sources[r]}")
            rendered, seconds = render_frames(data.runs, rows, poses, model.cfg.image_size, sensor)
            ev.baseline = _score(PHYSICS, real, rendered, seconds, markers)
            by_row[PHYSICS] = rendered
            ev.examples[PHYSICS] = [rendered[i] for i in ex]
        except BaselineUnavailable as exc:
            ev.baseline_note = str(exc)
    else:
        ev.baseline_note = "not asked for (--no-baseline)"
    from model.evaluation.simple_baselines import simple_baselines

    for name, frames in simple_baselines(split_dir, items, model.cfg.image_size, log=log).items():
        ev.baselines.append(_score(name, real, frames, 0.0, markers))
        by_row[f"baseline: {name}"] = frames

    if settings:  # warm-up: the first timed setting should not pay for first-call costs
        list(model.generate_items(items[:1], steps=2, sampler=settings[0][0], seed=seed))
    work = Eta(sum(steps for _, steps in settings) * len(items), clock)  # in network evaluations per image
    done = 0
    for sampler, steps in settings:
        made: list[np.ndarray] = []
        t0 = clock()
        for img in model.generate_items(items, steps=steps, sampler=sampler, seed=seed, batch_size=batch_size):
            made.append(img)
            if len(made) % batch_size == 0 or len(made) == len(items):
                line = work.line(done + steps * len(made))
                log(f"{part}: {sampler} {steps} steps: {len(made)}/{len(items)} frames, {line}")
        done += steps * len(items)
        seconds = (clock() - t0) / len(items)
        setting = f"{sampler}, {steps} steps"
        row = _score(setting, real, made, seconds, markers)
        row.network_evaluations = steps  # guidance runs both halves in one batched pass
        ev.rows.append(row)
        ev.examples[setting] = [made[i] for i in ex]
        by_row[f"this model ({setting})"] = made
    _texture(ev, data, items, by_row, model.cfg.image_size, log)
    loaded: dict[int, RunData] = {}

    def run(r: int) -> RunData:
        if r not in loaded:
            loaded[r] = RunData.load(data.runs[r], model.cfg.image_size)
        return loaded[r]

    blur = max(0.5, model.cfg.image_size / 64) * (2.5 if markers else 1.0)
    try:
        _contact_scores(ev, items, real, by_row, run, blur)
        if sweep is not None:
            from model.sweeps.evaluate_sweep import force_sweep_part

            force_sweep_part(ev, model, split_dir, data, items, sweep, seed, markers, profile, log, clock, run, blur)
        else:
            ev.sweep_note = "not asked for (--no-force-sweep)"
    finally:
        for opened in loaded.values():  # each run file was opened (and verified) once and kept open for its frames
            opened.close()
    return ev


def _texture(ev, data: TactileDataset, items: list, by_row: dict, size_px: int, log) -> None:
    """The texture measure of the part's texture-board frames (model/evaluation/texture_eval.py), scored at
    the run files' own resolution, beside the blurred-contact row; nothing for other objects."""
    from model.evaluation.texture_eval import board_band, texture_table

    objects = [str(data.manifest["runs"][int(it["run"])].get("object", "?")) for it in items]
    if not any(board_band(o, 1.0) is not None for o in objects):
        return
    log(f"{ev.part}: texture of the board frames at the run files' resolution")
    rows = np.array([[it["run"], it["frame"]] for it in items])
    physics = {PHYSICS: "baseline: physics render"}
    named = {physics.get(name, name): frames for name, frames in by_row.items()}
    ev.texture, ev.texture_examples = texture_table(data.runs, rows, objects, named, size_px)


def _check_profiles(split_dir: str | Path, profile: str | Path | None) -> None:
    """NoProfile for the first run of the split that records no sensor profile, unless ``profile``."""
    from dataset.split import load_split
    from model.conditioning.baseline import no_profile

    if profile is not None:
        return
    manifest, _ = load_split(split_dir)
    for run in manifest["runs"]:
        if not str(run["sensor_profile"]).strip():
            raise no_profile(run["path"], "the physics row", "--profile FILE, or --no-baseline")


def _profiles(data: TactileDataset, runs: list[int], sensor) -> dict[int, str]:
    """The profile that renders each run's physics row, in words; NoProfile (one line, the command
    fails before anything is generated) for a run that records none when no --profile is given.
    A recorded profile that cannot be found again is the row's note (BaselineUnavailable)."""
    from model.conditioning.baseline import BaselineUnavailable, NoProfile, no_profile, profile_source

    out = {}
    for r in runs:
        record = str(data.manifest["runs"][r]["sensor_profile"])
        try:
            out[r] = profile_source(data.runs[r], record, sensor)
        except NoProfile:
            raise no_profile(data.runs[r], "the physics row", "--profile FILE, or --no-baseline") from None
        except BaselineUnavailable as exc:
            out[r] = f"unavailable: {exc}"
    return out


def _contact_scores(ev: Evaluation, items: list, real: list, by_row: dict, run, blur: float) -> None:
    """Every row's metrics near the contact and its light-load contact size (model/evaluation/contact_scores.py)."""
    from model.evaluation import contact_scores as C

    contacts = C.find_contacts(
        real,
        [run(int(it["run"])).no_contact for it in items],
        [run(int(it["run"])).mm_per_px for it in items],
        [float(run(int(it["run"])).wrench[int(it["frame"]), 2]) for it in items],
        blur_px=blur,
    )
    ev.near_rows = [C.near_row(r.setting, real, by_row[f"this model ({r.setting})"], contacts) for r in ev.rows]
    ev.near_baselines = [C.near_row(r.setting, real, by_row[f"baseline: {r.setting}"], contacts) for r in ev.baselines]
    if ev.baseline is not None:
        ev.near_physics = C.near_row(PHYSICS, real, by_row[PHYSICS], contacts)
    ev.near_note = (
        f"within {contacts.radius_mm:g} mm of the contact the real frame shows (its change from the run's no-contact "
        f"frame above {contacts.threshold:.1f} of 0–255 after a Gaussian blur of σ {blur:g} px), the same pixels for "
        f"every method; {contacts.seen} of {len(real)} frames show a contact"
        + ("" if contacts.seen == len(real) else " (the others have no near-contact value)")
    )
    named = [(f"this model ({r.setting})", r.setting) for r in ev.rows]
    named += [(f"baseline: {r.setting}", r.setting) for r in ev.baselines]
    named += [(PHYSICS, PHYSICS)] if ev.baseline is not None else []
    for key, label in named:
        row = C.light_load(label, by_row[key], contacts)
        if row is not None:
            row["model"] = key.startswith("this model")
            ev.light_load.append(row)


def _label(data: TactileDataset, item: dict) -> str:
    """An example row's condition in numbers: the wrench (N, N·mm) and the pose (mm, deg)."""
    w = item["wrench"].numpy() * data.std + data.mean
    x, y, z, theta = (float(v) for v in item["pose"].numpy())
    return (
        f"Fz {signed(w[2], 2, sign='')} N  Fx {signed(w[0], 2)} N  Fy {signed(w[1], 2)} N  "
        f"Mz {signed(w[5], 1)} N·mm | x {signed(x, 2)}  y {signed(y, 2)}  z {signed(z, 2)} mm  "
        f"θ {signed(theta, 1)}°"
    )


def _context(model: TrainedModel, data: TactileDataset, part: str, frames: int) -> dict[str, str]:
    """What the report is about, stated at its top: sizes, model, split and machine."""
    import os

    import torch

    from common.machine import describe
    from model.denoiser.precision import arithmetic_words

    cfg, m = model.cfg, data.manifest
    objects = sorted({str(r.get("object", "?")) for r in m["runs"]})
    device = str(model.device)
    if model.device.type == "cuda":
        device += f" ({torch.cuda.get_device_name(model.device)})"
    return {
        "image size": f"{cfg.image_size}×{cfg.image_size} px (the model's own; frames resized to it)",
        "model": f"{cfg.network}, widths {list(cfg.block_out_channels)}, {cfg.layers_per_block} resnet block(s) "
        f"per level, predicts {cfg.prediction}; trained {model.trained or 'for an unrecorded number of steps'}",
        "conditioning": cfg.conditioning
        + (
            "; the physics channels rendered at the depth where the simulator's contact gives the frame's Fz"
            if cfg.force_depth
            else ("; the physics channels rendered at the frame's measured pose" if cfg.uses_physics else "")
        )
        + (
            "; denoises the frame's difference from its physics channels (target physics_residual)"
            if cfg.residual
            else ""
        ),
        "split": f"by {m.get('by', '?')}, ratios {m.get('ratios', '?')}, seed {m.get('seed', '?')}; objects in the "
        f"split: {', '.join(objects)}; "
        + (
            f"held out of training (part test_object): {', '.join(m['held_out_objects'])}"
            if m.get("held_out_objects")
            else (
                "objects split between the parts: the test part's objects are never seen in training"
                if m.get("by") == "object"
                else "no object held out of training"
            )
        )
        + f"; trained on: {', '.join(m.get('objects', {}).get('train', [])) or '?'}"
        + (
            f"; the {t['frames']} frame(s) of largest {t['component']} ({t['smallest_held_out']:g}–"
            f"{t['largest_held_out']:g} {t['unit']}) held out of training (part test_force)"
            if (t := m.get("held_out_top"))
            else ""
        ),
        "machine": f"{describe()}, device {device}, torch "
        f"{torch.__version__} with {torch.get_num_threads()} thread(s), sampling in "
        f"{arithmetic_words(model.autocast)}; load average at the start "
        f"{os.getloadavg()[0]:.1f} (timings are warm, after one untimed batch, and share the machine "
        "with whatever else ran)",
    }


def _simulated(run_path: str) -> bool:
    with RunReader.open(run_path) as f:
        return f.text(S.ATTR_RIG_CONFIG).startswith(RIG_CONFIG_MARK)


def _references(data: TactileDataset, runs: list[int], size: int) -> list[np.ndarray]:
    import cv2

    cache: dict[int, np.ndarray] = {}
    for run in set(runs):
        with RunReader.open(data.runs[run]) as f:
            ref = f.image(S.REFERENCE_FRAME)
        cache[run] = ref if ref.shape[0] == size else cv2.resize(ref, (size, size), interpolation=cv2.INTER_AREA)
    return [cache[r] for r in runs]


def report(ev: Evaluation | list[Evaluation], out: str | Path, *, title: str) -> Path:
    """One report for one or several evaluated parts (model/evaluation/evaluation_report.py)."""
    from model.evaluation.evaluation_report import write_report

    return write_report(ev if isinstance(ev, list) else [ev], out, title=title)
