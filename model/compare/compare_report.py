"""The comparison's report: per test part, each setting's mean ± spread over seeds beside the baselines.

A setting's metric is the mean over its seeds ± their standard deviation, [min, max] after it; the
baselines (which do not depend on the seed) carry their bootstrap interval over frames instead.
Each part opens with a verdict: which setting is best on MSE and whether its lead over each other
exceeds the spread (model/evaluation/intervals.py's ``differs``: the means apart by more than either
setting's standard deviation, and the seeds' ranges not overlapping). A default is to be chosen
only on such a difference.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from model.compare.compare import METRICS, as_spread
from model.evaluation.intervals import differs

FORMATS = {"mse": "{:.2f}", "mae": "{:.2f}", "ssim": "{:.3f}", "psnr": "{:.2f}"}


def _cell(d: dict, fmt: str) -> str:
    s = as_spread(d)
    if s.n == 0:
        return "—"
    if s.n == 1:
        return fmt.format(s.mean) + " (1 seed)"
    spread = fmt.replace("+", "")  # a standard deviation has no sign
    return f"{fmt.format(s.mean)} ± {spread.format(s.std)} [{fmt.format(s.low)}, {fmt.format(s.high)}]"


def _baseline_cell(row: dict, key: str) -> str:
    value, ci = row.get(key), (row.get("ci") or {}).get(key)
    if value is None:
        return "—"
    fmt = FORMATS[key]
    if ci and all(v is not None and math.isfinite(v) for v in ci):
        return f"{fmt.format(value)} ({fmt.format(ci[0])}–{fmt.format(ci[1])})"
    return fmt.format(value)


def verdict(candidates: dict) -> str:
    """Which setting has the lowest mean MSE, and against which others that lead exceeds the spread."""
    named = {name: as_spread(c["mse"]) for name, c in candidates.items() if c["mse"]["n"]}
    if len(named) < 2:
        return "**Verdict**: one setting only: nothing to compare."
    best = min(named, key=lambda n: named[n].mean)
    settled = [n for n in named if n != best and differs(named[best], named[n])]
    open_ = [n for n in named if n != best and n not in settled]
    text = f"**Verdict**: `{best}` has the lowest mean MSE ({named[best].mean:.2f})"
    if settled:
        text += "; ahead of " + ", ".join(f"`{n}` ({named[n].mean:.2f})" for n in settled) + " beyond the seed spread"
    if open_:
        text += "; not settled against " + ", ".join(f"`{n}` ({named[n].mean:.2f})" for n in open_)
        text += " (the difference is within the seeds' spread: not a ground for a default)"
    return text + "."


def force_verdict(entry: dict) -> str:
    """One line: each setting's Fz exponent against the one it is held to, as each run's own report
    holds it (model/sweeps/sweep_report.py, ``target_exponent``): the real frames' at the sweep's poses where
    the data has frames there at several forces, else the real frames' across their poses where that
    interval lies above zero, else the calibrated render's at the sweep's poses — within ±30 %?"""
    from model.sweeps.sweep_report import EXPONENT_TOLERANCE

    fe = entry.get("real_frames_exponent") or {}
    low, k_real = fe.get("low"), fe.get("k")
    at_poses = entry.get("real_exponent_at_poses")
    if (
        "reference_exponent" in entry
    ):  # the one reference each run's report names (model/compare/compare.py, _reference)
        if entry["reference_exponent"] is None:
            return f"**Force verdict**: no reference exponent to hold the settings to ({entry['reference_source']})."
        target, source = float(entry["reference_exponent"]), entry["reference_source"]
    elif at_poses is not None and math.isfinite(at_poses):
        target, source = float(at_poses), "the real frames at the sweep's poses"
    elif k_real is not None and low is not None and low > 0:
        target, source = float(k_real), "the real frames"
    elif entry.get("render_exponent") is not None:
        target, source = float(entry["render_exponent"]), "the calibrated physics render at the sweep's poses"
        if k_real is not None:
            source += f" (the real frames' k, {k_real:+.2f} [{fe['low']:+.2f}, {fe['high']:+.2f}], is not above zero)"
    else:
        return "**Force verdict**: no exponent to hold the settings to (no real frames' k above zero, no render)."
    parts = []
    for name, c in entry["candidates"].items():
        k = as_spread(c["k"])
        if not k.n:
            parts.append(f"`{name}` —")
            continue
        ok = target and abs(k.mean / target - 1) <= EXPONENT_TOLERANCE
        parts.append(f"`{name}` {k.text('{:+.2f}')} ({'within' if ok else 'outside'})")
    return (
        f"**Force verdict**: k of area ∝ Fz^k held to the reference exponent {target:+.2f} ± "
        f"{EXPONENT_TOLERANCE:.0%}, {source}: " + "; ".join(parts) + "."
    )


def near_table(entry: dict) -> list[str]:
    """Each setting's metrics near the contact over its seeds and its light-load contact ratio, beside the
    baselines' (nothing for a summary saved before reports had them)."""
    if not entry.get("near_note"):
        return []
    lines = [
        "",
        f"Near the contact: each metric {entry['near_note']}. Light load: the contact area over the lightest "
        "frames against the real frames' (1.00 the same size), per seed.",
        "",
        "| setting | MSE near | MAE near | SSIM near | PSNR near | light-load contact ratio |",
        "|---|---|---|---|---|---|",
    ]
    for name, c in entry["candidates"].items():
        if "near" not in c:
            continue
        cells = " | ".join(_cell(c["near"][m], FORMATS[m]) for m in METRICS)
        lines.append(f"| `{name}` | {cells} | {_cell(c['light_ratio'], '{:.2f}')} |")
    light = {row["method"]: row for row in entry.get("light_baselines", [])}
    for row in entry.get("near_baselines", []):
        ratio = light.get(row["setting"], {}).get("ratio")
        ratio_text = "—" if ratio is None or not math.isfinite(ratio) else f"{ratio:.2f}"
        cells = " | ".join(_baseline_cell(row, m) for m in METRICS)
        lines.append(f"| baseline: {row['setting']} | {cells} | {ratio_text} |")
    return lines


def write_compare_report(summary: dict, out: Path, *, title: str, context: dict[str, str]) -> Path:
    """compare.md and compare.json in ``out``."""
    lines = [f"# {title}", ""]
    lines += [f"- **{k}**: {v}" for k, v in context.items()]
    for part, entry in summary.items():
        lines += [
            "",
            f"## Part `{part}` ({entry['frames']} frames per evaluation)",
            "",
            verdict(entry["candidates"]),
            "",
        ]
        lines += [
            "Each setting: mean ± standard deviation over its seeds [min, max] of the per-seed mean over the frames "
            "(its best sampler setting by MSE); k: the exponent of area ∝ Fz^k of the force sweep within the "
            "training range, per seed the mean over its poses. Baselines: one evaluation, mean over the frames "
            "(95 % bootstrap interval over them).",
            "",
            "| setting | seeds | MSE | MAE | SSIM | PSNR | Fz sweep k | monotonic Fz poses per seed "
            "| past the training max: contact grows (poses per seed); change away from it, in range → past (0–255) |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for name, c in entry["candidates"].items():
            mono = ", ".join(f"{m}/{p}" for m, p in zip(c["monotonic"], c["poses"])) or "—"
            cells = " | ".join(_cell(c[m], FORMATS[m]) for m in METRICS)
            grew = ", ".join(f"{g}/{p}" for g, p in zip(c.get("beyond_grew", []), c["poses"])) or "—"
            change = (
                f"{_cell(c['outside_change_in_range'], '{:.1f}')} → {_cell(c['outside_change_beyond'], '{:.1f}')}"
                if c.get("outside_change_beyond")
                else "—"
            )
            lines.append(
                f"| `{name}` ({c['setting']}) | {', '.join(map(str, c['seeds']))} | {cells} "
                f"| {_cell(c['k'], '{:+.2f}')} | {mono} | {grew}; {change} |"
            )
        rows = list(entry["baselines"].values()) + ([entry["physics_render"]] if entry["physics_render"] else [])
        for row in rows:
            name = row["setting"]
            cells = " | ".join(_baseline_cell(row, m) for m in METRICS)
            lines.append(f"| baseline: {name} | — | {cells} | — | — | — |")
        lines += near_table(entry)
        lines += ["", force_verdict(entry)]
        fe = entry.get("real_frames_exponent")
        if fe and fe.get("k") is not None:
            lines += [
                "",
                f"Real frames: {fe.get('source') or 'this part’s, each at its own pose'} ({fe['frames']} in contact, "
                f"Fz {fe['fz_low']:.2f}–"
                f"{fe['fz_high']:.2f} N): k = {fe['k']:+.2f} [{fe['low']:+.2f}, {fe['high']:+.2f}] (95 % bootstrap "
                "interval over frames).",
            ]
    from model.evaluation.evaluation_report import json_safe, paper_section, strip_paths

    lines += paper_section()
    out.mkdir(parents=True, exist_ok=True)

    (out / "compare.md").write_text(strip_paths("\n".join(lines) + "\n"))
    (out / "compare.json").write_text(strip_paths(json.dumps(json_safe(summary), indent=1) + "\n"))
    return out / "compare.md"
