"""The force-response check of one evaluated part (model/sweeps/force_sweep.py does the sweeping and
measuring): the swept ranges from the training part's wrench percentiles, poses spread over the part,
each pose's frames generated from the same initial noise (in one batch for a deterministic sampler),
the physics render as reference where no real frame matches, and the real frames' own exponent
across the part. Kept apart from model/evaluation/evaluate.py, which calls ``force_sweep_part``
when a sweep is asked for.
"""

from __future__ import annotations

import numpy as np

from acquisition import schema as S
from acquisition.run_reader import RunReader
from dataset.torch_dataset import TactileDataset, uint8_tensor_to_image
from model.denoiser.samplers import DETERMINISTIC
from model.generation.inference import TrainedModel


def force_sweep_part(ev, model, split_dir, data, items, opts, seed, markers, profile, log, clock, run, blur) -> None:
    """The force-response check at ``opts.poses`` poses of the part (``opts``: evaluate.SweepOptions)."""
    from dataset.split import PERCENTILES
    from model.sweeps import force_sweep as F
    from model.sweeps import sweep_measures as M
    from model.sweeps.sweep_references import resize

    pct = data.manifest.get("wrench_percentiles") or _train_percentiles(split_dir, data, PERCENTILES)
    ranges, ev.sweep_skipped = F.swept_ranges(pct, opts.components)
    rows = np.array([[it["run"], it["frame"]] for it in items])
    real = [uint8_tensor_to_image(it["tactile"]) for it in items]
    backgrounds = [run(int(it["run"])).no_contact for it in items]
    threshold, peak = M.contact_threshold(real, backgrounds, blur)
    ev.frames_exponent = _frames_exponent(split_dir, sorted({int(r) for r in rows[:, 0]}), run, threshold, blur)
    if not ranges:
        ev.sweep_note = "no component has a range in the training data"
        return
    poses = F.choose_poses(rows, lambda r: run(r).wrench, lambda r: run(r).pose, opts.poses, data.std)
    if not poses:
        ev.sweep_note = "no frame of this part is in firm contact: no force sweep"
        return
    ev.sweep_poses = F.pose_runs(poses, {r: run(r).name for r, _ in poses})
    by_row = {(int(it["run"]), int(it["frame"])): it for it in items}

    last_notes: list[str] = []  # why each frame of the last sweep has its physics channels elsewhere ("")

    def generate(p: int, wrenches: np.ndarray) -> list[np.ndarray]:
        frames, notes = _sweep_frames(
            model, by_row[poses[p]], run(poses[p][0]).wrench[poses[p][1]], wrenches, opts, seed
        )
        last_notes[:] = notes
        return frames

    renderers: dict = {}
    unavailable: list[str] = []

    def physics(r: int, pose: np.ndarray, wrench: np.ndarray) -> np.ndarray | None:
        from model.conditioning.baseline import BaselineUnavailable, PhysicsRender
        from sensor_sim.profile import load_profile

        if r not in renderers:
            try:
                renderers[r] = PhysicsRender(data.runs[r], profile=load_profile(profile) if profile else None)
            except BaselineUnavailable as exc:  # an object the simulator does not know: no render reference
                renderers[r] = None
                unavailable.append(str(exc))
                log(f"{ev.part}: force sweep without the physics render: {exc}")
        if renderers[r] is None:
            return None
        return resize(renderers[r].render(pose, wrench), model.cfg.image_size)

    ev.sweeps = F.run_force_sweep(
        generate,
        {r: run(r) for r, _ in poses},
        poses,
        ranges,
        model.wrench_std,
        points=opts.points,
        beyond=opts.beyond,
        physics=physics,
        blur_px=blur,
        threshold=threshold,
        log=lambda line: log(f"{ev.part}: {line}"),
        clock=clock,
        notes=lambda: list(last_notes),
        skipped=ev.sweep_skipped,
    )
    ev.sweep_summary = [F.summarise(s) for s in ev.sweeps]
    ev.sweep_ranges = ranges
    ev.sweep_note = (
        f"generated with {opts.sampler}, {opts.steps} steps, seed {seed} (the same initial noise at every point); "
        f"{opts.points} values per component"
        + (f", and for Fz two more up to {opts.beyond:g} × its range past the training maximum" if opts.beyond else "")
        + f"; contact: change from the run's no-contact frame above {threshold:.1f} (0–255: a third of the part's "
        f"median peak change {peak:.1f}, at least {M.THRESHOLD:g}) after a Gaussian blur of σ {blur:g} px"
        + (
            "; the physics channels rendered under each swept wrench (for Fz at the depth where the simulator's "
            "contact gives it: a physics model sees force through the render as well as the wrench)"
            if model.cfg.uses_physics
            else ""
        )
        + "".join(f"; no physics render: {why}" for why in dict.fromkeys(unavailable))
    )


REAL_EXPONENT_FRAMES = 400  # at most this many real frames (spread evenly) for the real frames' exponent


def _frames_exponent(split_dir, runs: list[int], run, threshold: float, blur: float):
    """k of area ∝ Fz^k across the real frames of the part's runs — every part of the split, training
    frames too (a property of the data, not of the model: more frames, more forces), at most
    REAL_EXPONENT_FRAMES spread evenly — measured as the sweep measures the model's frames."""
    from dataclasses import replace

    from dataset.split import load_split
    from dataset.torch_dataset import spread
    from model.sweeps import sweep_measures as M

    _, parts = load_split(split_dir)
    rows = np.concatenate([np.asarray(p).reshape(-1, 2) for p in parts.values()])
    rows = rows[np.isin(rows[:, 0], runs)]
    rows = rows[spread(len(rows), REAL_EXPONENT_FRAMES)] if len(rows) > REAL_EXPONENT_FRAMES else rows
    fz, areas = [], []
    for r, f in rows:
        data = run(int(r))
        m = M.measure_contact(
            data.frame(int(f)), data.no_contact, mm_per_px=data.mm_per_px, threshold=threshold, blur_px=blur
        )
        fz.append(float(data.wrench[int(f), 2]))
        areas.append(m.area_mm2)
    fe = M.frames_exponent(fz, areas)
    return replace(fe, source=f"{len(rows)} real frames of the split's runs (every part), each at its own pose")


def _sweep_frames(model: TrainedModel, base: dict, recorded: np.ndarray, wrenches: np.ndarray, opts, seed):
    """(frames, notes) of one pose's sweep, every point from the seed's initial noise (one batch for a
    deterministic sampler, else one at a time); a physics model's channels rendered under each swept
    wrench: for Fz at the depth where the simulator's contact gives it, as `generate` renders a pose
    given without z. A note per frame says why its channels are not at that Fz (past what the gel can
    give: rendered at its limit), ""."""
    import torch

    from dataset.condition import normalise_wrench

    items = []
    for w in wrenches:
        it = dict(base)
        norm = normalise_wrench(w, model.wrench_mean, model.wrench_std).astype(np.float32)
        it["wrench"] = torch.from_numpy(norm)
        if model.cfg.uses_physics:  # the physics channels under the swept load, not the frame's own
            it.pop("physics", None)
            it["wrench_raw"] = np.asarray(w, dtype=float)
            it["depth_from_fz"] = bool(w[2] != recorded[2])
        items.append(it)
    kw = {"steps": opts.steps, "sampler": opts.sampler, "seed": seed}
    if opts.sampler in DETERMINISTIC:  # all the pose's points in one batch, each from the seed's initial noise
        out = list(model.generate_items(items, same_noise=True, batch_size=max(1, len(items)), **kw))
    else:  # a sampler drawing noise at every step: one at a time, so every point draws the same
        out = [img for it in items for img in model.generate_items([it], **kw)]
    return out, [str(it.get("physics_note") or "") for it in items]


def _train_percentiles(split_dir, data: TactileDataset, qs) -> dict:
    """The training part's wrench percentiles, for a split written before split.json kept them."""
    from dataset.split import load_split

    _, parts = load_split(split_dir)
    train = parts["train"]
    wrench = []
    for r in np.unique(train[:, 0]):
        with RunReader.open(data.runs[int(r)]) as f:
            wrench.append(f.rows[S.WRENCH][train[train[:, 0] == r][:, 1]])
    values = np.percentile(np.concatenate(wrench), qs, axis=0)
    return {f"p{q}": row.tolist() for q, row in zip(qs, values)}
