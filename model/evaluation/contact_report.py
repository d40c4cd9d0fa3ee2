"""The report's near-contact table, its verdict, and the light-load row (model/evaluation/contact_scores.py).

Beside the whole-frame table: the same metrics inside the stated radius around each real frame's
contact, with the same intervals and the same verdict rule (better or worse only where the 95 %
intervals do not overlap); then the contact's size under the lightest loads against the real
frames', each method a row.
"""

from __future__ import annotations

import math
from dataclasses import replace

from model.evaluation.eval_results import PHYSICS, Evaluation, Row
from model.evaluation.verdicts import ci_cell, metrics_verdict


def _near_line(name: str, r: Row) -> str:
    cells = [
        ci_cell(r.mse, r.ci.get("mse"), "{:.2f}"),
        ci_cell(r.mae, r.ci.get("mae"), "{:.2f}"),
        ci_cell(r.ssim, r.ci.get("ssim"), "{:.3f}"),
        ci_cell(r.psnr, r.ci.get("psnr"), "{:.2f}"),
    ]
    return f"| {name} | " + " | ".join(cells) + f" | {r.images} |"


def near_verdict(ev: Evaluation) -> str:
    """``metrics_verdict`` on the near-contact rows: the same model setting as the whole frame's verdict
    (its best on MSE there), against the best baseline near the contact on each metric."""
    if not ev.rows:
        return ""
    best = min(range(len(ev.rows)), key=lambda i: ev.rows[i].mse)
    model = ev.near_rows[best] if best < len(ev.near_rows) else None
    if model is None:
        return "**Verdict near the contact**: no frame shows a contact."
    near = replace(
        ev,
        rows=[model],
        baselines=[b for b in ev.near_baselines if b is not None],
        baseline=ev.near_physics,
    )
    return metrics_verdict(near).replace("**Verdict**", "**Verdict near the contact**", 1)


def near_section(ev: Evaluation) -> list[str]:
    """The near-contact table with its verdict (nothing when the part was not scored near its contact)."""
    if not ev.near_note:
        return []
    lines = ["", f"### Near the contact (`{ev.part}`)", "", near_verdict(ev), "", f"Each metric {ev.near_note}.", ""]
    lines += ["| method | MSE | MAE | SSIM | PSNR | frames |", "|---|---|---|---|---|---|"]
    for r in ev.near_rows:
        if r is not None:
            lines.append(_near_line(f"this model ({r.setting})", r))
    for r in ev.near_baselines:
        if r is not None:
            lines.append(_near_line(f"baseline: {r.setting}", r))
    if ev.near_physics is not None:
        lines.append(_near_line("baseline: physics render at the measured pose", ev.near_physics))
    lines += light_section(ev)
    return lines


def light_section(ev: Evaluation) -> list[str]:
    """The light-load row: each method's contact area over the lightest frames against the real frames'."""
    if not ev.light_load:
        return []
    first = ev.light_load[0]
    lines = [
        "",
        f"**Light load**: the {first['frames']} frame(s) of smallest Fz ({first['fz_low_N']:.3f}–"
        f"{first['fz_high_N']:.3f} N), their contact measured as the force sweep measures it (the same threshold "
        f"as above). The real frames' mean contact is {first['real_area_mm2']:.2f} mm²; the ratio is the method's "
        "mean area over the real frames' (1.00: the same size; 2.00: twice too large), with its 95 % bootstrap "
        "interval over those frames.",
        "",
        "| method | contact, mm² | real, mm² | ratio to the real frames |",
        "|---|---|---|---|",
    ]
    for row in ev.light_load:
        name = row["method"]
        label = f"this model ({name})" if row.get("model") else f"baseline: {name}"
        if name == PHYSICS and not row.get("model"):
            label = "baseline: physics render at the measured pose"
        ratio = ci_cell(row["ratio"], row["ratio_ci"], "{:.2f}")
        if not math.isfinite(row["ratio"]):
            ratio = "— (the real frames show no contact at these loads)"
        lines.append(f"| {label} | {row['area_mm2']:.2f} | {row['real_area_mm2']:.2f} | {ratio} |")
    return lines
