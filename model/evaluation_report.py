"""The evaluation report: one Markdown file, a section per evaluated part, with its figures and JSON.

What was evaluated (image size, model, conditioning, split, machine) comes first, then for
each part (``test``: unseen frames of the training objects; ``test_object``: objects held
out of training) the metrics table, the error-against-run-time plot, labelled example
rows, the force-response check and, for marker sensors, marker motion. The first part's
figures keep the plain names (``samples.png``); the others' carry the part
(``samples-test_object.png``).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

from model.eval_results import PAPER_ROWS, Evaluation, Row

PART_TEXT = {
    "test": "unseen frames of the training objects",
    "test_object": "objects held out of training, never seen by the model",
    "val": "the validation part",
}


def part_text(ev: Evaluation) -> str:
    """What the part holds, in words: a part none of whose objects was trained on says so."""
    if ev.unseen_objects:
        return PART_TEXT["test_object"]
    return PART_TEXT.get(ev.part, "a part of the split")


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


def _clean(value):
    """JSON without NaN: nan and inf become null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    return value


def write_report(evs: list[Evaluation], out: str | Path, *, title: str) -> Path:
    """report.md + metrics.json + per part error_vs_time, samples, force_sweep (+ marker_flow) PNGs."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    first = evs[0]
    lines = [f"# {title}", ""]
    lines += [f"- **{key}**: {value}" for key, value in first.context.items()]
    lines.append(
        "- **parts evaluated**: "
        + "; ".join(
            f"`{ev.part}` ({part_text(ev)}: {', '.join(ev.objects)}), {ev.rows[0].images if ev.rows else 0} frames"
            for ev in evs
        )
    )
    payload: dict = {"parts": {}}
    for k, ev in enumerate(evs):
        suffix = "" if k == 0 else f"-{ev.part}"
        lines += _part_section(ev, out, suffix)
        part_payload = {
            "objects": ev.objects,
            "model": [asdict(r) for r in ev.rows],
            "physics_render": asdict(ev.baseline) if ev.baseline else None,
            "physics_render_note": ev.baseline_note,
            "physics_render_profiles": ev.profiles,
            "force_sweep": ev.sweep_summary,
            "force_sweep_ranges": ev.sweep_ranges,
            "force_sweep_note": ev.sweep_note,
        }
        payload["parts"][ev.part] = part_payload
        if k == 0:  # the first part also at the top, where single-part reports kept it
            payload.update({key: part_payload[key] for key in ("model", "physics_render", "physics_render_note")})
    (out / "report.md").write_text("\n".join(lines) + "\n")
    (out / "metrics.json").write_text(json.dumps(_clean(payload), indent=2) + "\n")
    return out / "report.md"


def _part_section(ev: Evaluation, out: Path, suffix: str) -> list[str]:
    from model.figures import error_vs_time_plot, force_sweep_figure, marker_flow_figure, samples_figure

    n = ev.rows[0].images if ev.rows else 0
    lines = [
        "",
        f"## Part `{ev.part}`: {part_text(ev)} ({', '.join(ev.objects)})",
        "",
        f"{n} frames. Metrics as docs/reference.md#metrics defines them (0–255 scale, all channels, "
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
    if ev.profiles:
        lines += ["", "Sensor profile of the physics render, per run file:", ""]
        lines += [f"- `{Path(run).name}`: {text}" for run, text in ev.profiles.items()]
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
        f"### Error against run time (`{ev.part}`)",
        "",
        f"![error against seconds per image](error_vs_time{suffix}.png)",
        "",
        f"### Examples (`{ev.part}`)",
        "",
        "Columns: " + ", ".join(ev.examples) + ". Under each row: the wrench and pose it was generated for.",
        "",
        f"![examples](samples{suffix}.png)",
    ]
    error_vs_time_plot(ev, out / f"error_vs_time{suffix}.png")
    samples_figure(ev.examples, out / f"samples{suffix}.png", ev.example_labels)
    lines += _sweep_section(ev, out, suffix, force_sweep_figure)
    if ev.markers and marker_flow_figure(ev, out / f"marker_flow{suffix}.png"):
        lines += [
            "",
            f"### Marker motion (`{ev.part}`)",
            "",
            "Arrows from each central marker at rest (the run's no-contact frame) to where it is found, "
            "drawn ×4: real, physics render, this model.",
            "",
            f"![marker motion](marker_flow{suffix}.png)",
        ]
    return lines


def _sweep_section(ev: Evaluation, out: Path, suffix: str, figure) -> list[str]:
    from model.force_sweep import MONOTONIC_RHO, component_table

    lines = ["", f"### Force response (`{ev.part}`)", ""]
    if not ev.sweeps:
        return lines + [f"No force sweep: {ev.sweep_note}."]
    lines += [
        "Each component swept over its training range (the split's 2nd–98th percentile) at "
        f"{len({s.label for s in ev.sweeps})} poses of this part, the condition image(s) and the other "
        "components held at the pose frame's own; "
        f"{ev.sweep_note}. Measured on each generated frame and on its reference — the real frame of the same run "
        "at the same x, y, θ (within 0.25 mm, 1°) nearest in the swept component with the other swept "
        "components within half a training standard deviation, else the physics render (for Fz at the "
        "depth the run's own Fz↔z relation gives; for Fx, Fy, Mz with the gel carrying the swept load): the "
        "contact's area, centroid and shading (mean |change| inside it). ρ: Spearman's "
        "rank correlation of the area with the force (for Fx and Fy also of the centroid's x or y: "
        "image axes, whose signs against the gauge's depend on how the sensor is mounted); a pose is "
        f"monotonic when |ρ| ≥ {MONOTONIC_RHO}, in the reference's direction where it has one (Fz: growing). Sign "
        "consistency: the share of successive steps whose area moves the way the reference's does (for Fz "
        "without a reference: growing). Errors: mean |model − reference| over the points with a reference. "
        "k: the exponent of area ∝ Fz^k over the points that have a reference (Hertz: 2/3 for a sphere; "
        "the model's k over every point is in metrics.json).",
        "",
    ]
    lines += component_table(ev.sweep_summary, ev.sweep_ranges)
    lines += ["", "Poses:", ""]
    lines += [f"{i + 1}. {label}" for i, label in enumerate(dict.fromkeys(s.label for s in ev.sweeps))]
    for name in ev.sweep_ranges:
        sweeps = [s for s in ev.sweeps if s.component == name]
        if sweeps:
            png = f"force_sweep_{name}{suffix}.png"
            figure(sweeps, out / png)
            lines += ["", f"![{name} sweep: frames and measures against {name}]({png})"]
    return lines
