"""The verdict of a part's metrics: the model against the best baseline on each metric, by the intervals.

Better or worse only where the two 95 % intervals do not overlap, tied otherwise; on simulated frames
the physics render is an oracle, said apart and never counted. Used by the whole-frame table
(model/evaluation/evaluation_report.py) and the near-contact one (model/evaluation/contact_report.py).
"""

from __future__ import annotations

import math

from model.evaluation.eval_results import Evaluation, Row

VERDICT_METRICS = (
    ("mse", "MSE", False, "{:.2f}"),
    ("mae", "MAE", False, "{:.2f}"),
    ("ssim", "SSIM", True, "{:.3f}"),
    ("psnr", "PSNR", True, "{:.2f}"),
)


def _with_ci(row: Row, key: str, fmt: str) -> str:
    lo, hi = row.ci.get(key, (float("nan"), float("nan")))
    value = fmt.format(getattr(row, key))
    return f"{value} [{fmt.format(lo)}–{fmt.format(hi)}]" if math.isfinite(lo) and math.isfinite(hi) else value


def compare_metric(model: Row, rival: Row, key: str, higher: bool) -> str:
    """'better', 'worse' or 'tied' for ``model`` against ``rival`` on one metric: better or worse only
    where their 95 % intervals do not overlap (an interval missing: tied)."""
    lo, hi = model.ci.get(key, (float("nan"), float("nan")))
    rlo, rhi = rival.ci.get(key, (float("nan"), float("nan")))
    if not all(math.isfinite(v) for v in (lo, hi, rlo, rhi)) or not (hi < rlo or rhi < lo):
        return "tied"
    model_above = lo > rhi
    return "better" if model_above == higher else "worse"


def metrics_verdict(ev: Evaluation) -> str:
    """The model (its setting best on MSE) against the best non-oracle baseline on each metric, metric by
    metric: 'better' or 'worse' only where the 95 % intervals do not overlap, 'tied' otherwise. On
    simulated frames the physics render is an oracle (it renders the very physics that made the frames):
    said apart, never counted."""
    if not ev.rows:
        return "**Verdict**: no model row."
    model = min(ev.rows, key=lambda r: r.mse)
    oracle = ev.baseline if ev.simulated else None
    fair = ev.baselines + ([ev.baseline] if ev.baseline is not None and oracle is None else [])
    if not fair:
        return f"**Verdict**: {model.setting}: MSE {_with_ci(model, 'mse', '{:.2f}')}; no baseline to compare with."
    said = []
    for key, name, higher, fmt in VERDICT_METRICS:
        rivals = [b for b in fair if math.isfinite(getattr(b, key))]
        if not math.isfinite(getattr(model, key)) or not rivals:
            continue
        rival = (max if higher else min)(rivals, key=lambda r: getattr(r, key))
        word = compare_metric(model, rival, key, higher)
        against = "with" if word == "tied" else "than"
        said.append(
            f"{name} **{word}** {against} {rival.setting} ({_with_ci(model, key, fmt)} against "
            f"{_with_ci(rival, key, fmt)})"
        )
    note = ""
    if oracle is not None:
        note = (
            f" The physics render is an oracle on simulated frames (MSE {_with_ci(oracle, 'mse', '{:.2f}')}): "
            "shown, not counted."
        )
    return (
        f"**Verdict**: {model.setting} ({model.images} frames) against the best baseline on each metric, better or "
        "worse only where the 95 % intervals do not overlap: " + "; ".join(said) + "." + note
    )


def ci_cell(value: float | None, ci: tuple[float, float] | None, fmt: str) -> str:
    """A metric's mean with its 95 % bootstrap interval over frames: ``4.17 (3.20–5.31)``."""
    if value is None or not math.isfinite(value):
        return "—"
    text = fmt.format(value)
    if ci and all(isinstance(v, float) and math.isfinite(v) for v in ci):
        text += f" ({fmt.format(ci[0])}–{fmt.format(ci[1])})"
    return text
