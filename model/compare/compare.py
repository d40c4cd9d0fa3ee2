"""Compare training settings over seeds: k models per setting, each evaluated alike, mean ± spread.

A setting (``Candidate``) is a conditioning and what goes with it (where the physics is rendered,
the target); ``compare`` trains one model per (setting, seed) on the same split with the same
steps, batch and learning rate — the seed changes the initial weights, the data order and the
noise — evaluates each on the same frames of every test part with the same sampler and seed,
and gathers per part and setting the mean and spread over seeds of each metric and of the Fz
sweep's exponent (model/compare/compare_report.py writes the table). A run already trained to the
asked steps is evaluated without training again, so an interrupted comparison continues.

``Candidate.parse`` reads the command line's form: ``plane``, ``physics``, or
``physics,physics_depth=force,target=physics_residual`` (a conditioning, then ``key=value`` of
ModelConfig's fields).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from model.denoiser.config import ModelConfig
from model.evaluation.intervals import Spread, seed_spread

METRICS = ("mse", "mae", "ssim", "psnr")


@dataclass(frozen=True)
class Candidate:
    """A setting compared: its name as given and the ModelConfig fields it sets."""

    name: str
    fields: tuple[tuple[str, str], ...]
    steps: int | None = None  # training steps of this setting (compare --steps 400,1200); None: every run's

    def with_steps(self, steps: int) -> "Candidate":
        """This setting trained for ``steps`` steps, named so (its own row and folder)."""
        return Candidate(f"{self.name} @ {steps} steps", self.fields, steps)

    @classmethod
    def parse(cls, text: str) -> "Candidate":
        """``CONDITIONING[,key=value...]``; ValueError naming the part that is not understood."""
        parts = [p.strip() for p in text.split(",") if p.strip()]
        if not parts or "=" in parts[0]:
            raise ValueError(f"--candidate {text!r}: expected a conditioning first (e.g. physics), then key=value")
        known = {f.name for f in dataclasses.fields(ModelConfig)} - {"conditioning"}
        fields = [("conditioning", parts[0])]
        for p in parts[1:]:
            key, eq, value = p.partition("=")
            if not eq or key not in known:
                raise ValueError(
                    f"--candidate {text!r}: {p!r} is not key=value of a model field ({', '.join(sorted(known))})"
                )
            fields.append((key, value))
        return cls(text, tuple(fields))

    def config(self, base: ModelConfig) -> ModelConfig:
        """``base`` with this candidate's fields (ValueError for a value the config refuses)."""
        over: dict = {}
        for key, value in self.fields:
            current = getattr(base, key)
            over[key] = type(current)(float(value)) if isinstance(current, float) else value
            if isinstance(current, bool):
                over[key] = value.lower() in ("1", "true", "yes")
            elif isinstance(current, int):
                over[key] = int(value)
        try:
            return dataclasses.replace(base, **over)
        except ValueError as exc:
            raise ValueError(f"--candidate {self.name!r}: {exc}") from None

    @property
    def folder(self) -> str:
        return "".join(c if c.isalnum() or c in "-_" else "_" for c in self.name.replace("+", "-"))


@dataclass
class Result:
    """One (setting, seed): its evaluation per part, as metrics.json gives it."""

    candidate: str
    seed: int
    run_dir: str
    parts: dict = field(default_factory=dict)  # part → metrics.json's part entry
    train_s: float = 0.0


def train_one(
    candidate: Candidate,
    seed: int,
    base: ModelConfig,
    train_fields: dict,
    split_dir: Path,
    run_dir: Path,
    *,
    profile=None,
    log: Callable[[str], None] = lambda line: None,
) -> float:
    """Train (or find trained) one model; the seconds it took (0 when found)."""
    import time

    from model.denoiser import checkpoint as C
    from model.training.build import build
    from model.training.trainer import TrainConfig

    cfg = candidate.config(base)
    steps = {} if candidate.steps is None else {"steps": candidate.steps, "checkpoint_every": candidate.steps}
    train_cfg = TrainConfig(**{**train_fields, **steps, "seed": seed})
    state = C.folder(run_dir) / C.STATE
    if state.is_file():
        meta = json.loads(state.read_text())
        if meta.get("step") == train_cfg.steps and C.model_config(meta, state) == cfg:
            log(f"{candidate.name}, seed {seed}: trained already ({run_dir})")
            return 0.0
    t0 = time.perf_counter()
    trainer = build(cfg, train_cfg, split_dir, run_dir, log=lambda line: log(f"  {line}"), profile=profile)
    trainer.train()
    trainer.save()
    return time.perf_counter() - t0


def compare(
    candidates: list[Candidate],
    seeds: list[int],
    base: ModelConfig,
    train_fields: dict,
    split_dir: Path,
    out: Path,
    *,
    evaluate_kwargs: dict,
    profile=None,
    log: Callable[[str], None] = lambda line: None,
) -> list[Result]:
    """Every (candidate, seed) trained and evaluated into ``out/CANDIDATE/seed-S`` (its report in
    ``report/``); the results in order."""
    from model.evaluation.evaluate import evaluate_parts, report

    results = []
    for cand in candidates:
        cand.config(base)  # a bad candidate fails before anything trains
    for cand in candidates:
        for seed in seeds:
            run_dir = out / cand.folder / f"seed-{seed}"
            log(f"{cand.name}, seed {seed}: training")
            seconds = train_one(cand, seed, base, train_fields, split_dir, run_dir, profile=profile, log=log)
            log(f"{cand.name}, seed {seed}: evaluating")
            evs = evaluate_parts(run_dir, split_dir, log=lambda line: log(f"  {line}"), **evaluate_kwargs)
            title = f"{cand.name}, seed {seed}, on {split_dir.resolve().name}"
            report(evs, run_dir / "report", title=title)
            saved = json.loads((run_dir / "report" / "metrics.json").read_text())
            results.append(Result(cand.name, seed, str(run_dir), saved["parts"], seconds))
    return results


def saved_results(candidates: list[Candidate], seeds: list[int], out: Path) -> list[Result]:
    """Every (candidate, seed)'s saved evaluation (``out/CANDIDATE/seed-S/report/metrics.json``);
    ValueError naming the first that is missing or unreadable."""
    results = []
    for cand in candidates:
        for seed in seeds:
            run_dir = out / cand.folder / f"seed-{seed}"
            path = run_dir / "report" / "metrics.json"
            try:
                saved = json.loads(path.read_text())
                results.append(Result(cand.name, seed, str(run_dir), saved["parts"]))
            except (OSError, json.JSONDecodeError, KeyError, TypeError) as exc:
                raise ValueError(f"{path}: no saved evaluation of {cand.name!r}, seed {seed} ({exc})") from None
    return results


def summary(results: list[Result]) -> dict:
    """Per part and candidate: the spread over seeds of each metric and of the Fz sweep (exponent k
    within the training range, monotonic poses), beside the baselines (the same for every run)."""
    from model.sweeps.force_sweep import grew_past_maximum

    out: dict = {}
    parts = sorted({p for r in results for p in r.parts})
    for part in parts:
        rows: dict = {}
        for name in dict.fromkeys(r.candidate for r in results):
            mine = [r.parts[part] for r in results if r.candidate == name and part in r.parts]
            best = [min(p["model"], key=lambda row: row["mse"]) for p in mine if p["model"]]
            entry: dict = {m: _spread([row[m] for row in best]) for m in METRICS}
            fz = [[s for s in p.get("force_sweep") or [] if s["component"] == "Fz"] for p in mine]
            entry["k"] = _spread([_mean([s.get("area_exponent") for s in sweeps]) for sweeps in fz])
            entry["monotonic"] = [sum(s["monotonic"] for s in sweeps) for sweeps in fz]
            # past the training maximum: does the contact keep growing, and the change away from it (0–255)
            beyond = [[s for s in sweeps if s.get("beyond_values")] for sweeps in fz]
            entry["beyond_grew"] = [sum(grew_past_maximum(s) for s in b) for b in beyond]
            entry["outside_change_beyond"] = _spread(
                [_mean([s.get("outside_change_beyond") for s in b]) for b in beyond]
            )
            entry["outside_change_in_range"] = _spread(
                [_mean([s.get("outside_change_in_range") for s in b]) for b in beyond]
            )
            entry["poses"] = [len(sweeps) for sweeps in fz]
            entry["seeds"] = [r.seed for r in results if r.candidate == name and part in r.parts]
            entry["per_seed_mse"] = [row["mse"] for row in best]
            entry["setting"] = best[0]["setting"] if best else ""
            # near the contact (model/evaluation/contact_scores.py): the same setting's rows there, and its
            # light-load ratio
            near = [_near_of(p, row["setting"]) for p, row in zip(mine, best)]
            entry["near"] = {m: _spread([n[m] if n else None for n in near]) for m in METRICS}
            entry["light_ratio"] = _spread([_light_of(p, row["setting"]) for p, row in zip(mine, best)])
            rows[name] = entry
        first = next(r.parts[part] for r in results if part in r.parts)
        fz_first = [s for s in first.get("force_sweep") or [] if s["component"] == "Fz"]
        reference, reference_source = _reference(fz_first, first)
        near_first = first.get("near_contact") or {}
        out[part] = {
            # the one exponent every run's own report holds its model to (model/sweeps/sweep_report.py, target_exponent)
            "reference_exponent": reference,
            "reference_source": reference_source,
            "simulated": bool(first.get("simulated")),
            "near_note": near_first.get("note", ""),
            "near_baselines": [b for b in near_first.get("baselines") or [] if b]
            + ([near_first["physics_render"]] if near_first.get("physics_render") else []),
            "light_baselines": [row for row in first.get("light_load") or [] if not row.get("model")],
            # the calibrated render's k at the sweep's poses (the same poses and renders for every model)
            "render_exponent": _mean([s.get("render_area_exponent") for s in fz_first]),
            # the real frames' k at the same poses (references matched by pose and force), where the data has them:
            # what each run's own report holds its model to first (model/sweeps/sweep_report.py, real_exponent)
            "real_exponent_at_poses": _mean([s.get("real_area_exponent") for s in fz_first]),
            "candidates": rows,
            "baselines": {b["setting"]: b for b in first.get("baselines", [])},
            "physics_render": first.get("physics_render"),
            "real_frames_exponent": first.get("real_frames_exponent"),
            "frames": first["model"][0]["images"] if first.get("model") else 0,
        }
    return out


def _near_of(part: dict, setting: str) -> dict | None:
    """The near-contact row of this model's ``setting`` in a saved part (None: not scored there)."""
    for row in (part.get("near_contact") or {}).get("model") or []:
        if row and row.get("setting") == setting:
            return row
    return None


def _light_of(part: dict, setting: str) -> float | None:
    for row in part.get("light_load") or []:
        if row.get("model") and row.get("method") == setting:
            return row.get("ratio")
    return None


def _reference(fz: list[dict], part: dict) -> tuple[float | None, str]:
    """(the reference exponent, how it was measured) as each run's report names it; (None, why) without one."""
    from model.sweeps.sweep_measures import FramesExponent
    from model.sweeps.sweep_report import target_exponent

    fe = part.get("real_frames_exponent") or {}
    frames = None
    if fe:  # as saved (json: nan as null), any field missing from an older report read as unknown
        values: dict = {f.name: fe.get(f.name) for f in dataclasses.fields(FramesExponent)}
        for key, value in values.items():
            if value is None:
                values[key] = "" if key == "source" else 0 if key == "frames" else float("nan")
        frames = FramesExponent(**values)
    k, source, why_not = target_exponent(
        [{**s, **{key: float("nan") if s.get(key) is None else s[key] for key in _EXPONENT_KEYS}} for s in fz],
        frames,
        bool(part.get("simulated")),
    )
    if not math.isfinite(k):
        return None, why_not or "no reference exponent"
    return k, source + (f" (the real frames' exponent is {why_not})" if why_not else "")


_EXPONENT_KEYS = ("real_area_exponent", "render_area_exponent")


def _mean(values) -> float | None:
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.mean(v)) if v else None


def _spread(values) -> dict:
    s = seed_spread(values)
    return dataclasses.asdict(s)


def as_spread(d: dict) -> Spread:
    return Spread(**d)
