"""The evaluation report: one Markdown file, a section per evaluated part, with its figures and JSON.

What was evaluated (image size, model, conditioning, split, machine) comes first, then for
each part (``test``: unseen frames of the training objects; ``test_object``: objects held
out of training) a one-line verdict, the metrics table — every row with its 95 % bootstrap
interval over the frames, this model's rows beside the baselines that need no model
(model/evaluation/simple_baselines.py) and the calibrated physics render — the error-against-run-time
plot, labelled example rows, the force-response check (model/sweeps/sweep_report.py) and, for marker
sensors, marker motion; the paper's own numbers last, in a table of their own labelled with
their resolution and data. The first part's figures keep the plain names (``samples.png``);
the others' carry the part (``samples-test_object.png``). No absolute path of the machine that
made the report appears in it (``strip_paths``): files are named by their names.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import asdict
from pathlib import Path

from model.evaluation.contact_report import near_section
from model.evaluation.eval_results import PAPER_ROWS, Evaluation, Row
from model.evaluation.verdicts import ci_cell, compare_metric, metrics_verdict

__all__ = ["compare_metric", "metrics_verdict", "write_report", "part_text", "strip_paths", "json_safe"]

PART_TEXT = {
    "test": "unseen frames of the training objects",
    "test_object": "objects held out of training, never seen by the model",
    "test_run": "runs held out of training (dataset split --hold-out-runs), never seen by the model",
    "test_force": "the frames of largest load held out of training (dataset split --hold-out-top)",
    "val": "the validation part",
}


def part_text(ev: Evaluation) -> str:
    """What the part holds, in words: a part none of whose objects was trained on says so."""
    if ev.unseen_objects:
        return PART_TEXT["test_object"]
    if ev.part == "test" and ev.test_runs:
        names = ", ".join(Path(r).name for r in ev.test_runs)
        return f"the runs named for the test part (dataset split --test-runs: {names}), never trained on"
    return PART_TEXT.get(ev.part, "a part of the split")


def _fmt_row(name: str, r: Row) -> str:
    if r.marker_px is None:
        mk = "—" if not r.marker_failures else f"— ({r.marker_failures} frames without markers)"
    else:
        mk = ci_cell(r.marker_px, r.ci.get("marker_px"), "{:.2f}") + (
            f" ({r.marker_failures} frames failed)" if r.marker_failures else ""
        )
    per_nfe = f"{r.seconds_per_image / r.network_evaluations:.5f}" if r.network_evaluations else "—"
    seconds = f"{r.seconds_per_image:.4f}" if r.seconds_per_image > 0 else "—"
    return (
        f"| {name} | {ci_cell(r.mse, r.ci.get('mse'), '{:.2f}')} | {ci_cell(r.mae, r.ci.get('mae'), '{:.2f}')} "
        f"| {ci_cell(r.ssim, r.ci.get('ssim'), '{:.3f}')} | {ci_cell(r.psnr, r.ci.get('psnr'), '{:.2f}')} | {mk} "
        f"| {seconds} | {per_nfe} |"
    )


_PATH = re.compile(r"(?<![\w.~:/-])/(?:[^\s/`'\"(),;|]+/)+([^\s/`'\"(),;|]+)")


def strip_paths(text: str) -> str:
    """Absolute paths of the machine that made a report replaced by their last component (a run file
    by its name): a report is read elsewhere, and a path there says nothing but where it was made."""
    return _PATH.sub(lambda m: m.group(1), text)


def json_safe(value):
    """JSON without NaN: nan and inf become null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
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
            "simulated": ev.simulated,
            "model": [asdict(r) for r in ev.rows],
            "baselines": [asdict(r) for r in ev.baselines],
            "physics_render": asdict(ev.baseline) if ev.baseline else None,
            "physics_render_note": ev.baseline_note,
            "physics_render_profiles": ev.profiles,
            "force_sweep": ev.sweep_summary,
            "force_sweep_ranges": ev.sweep_ranges,
            "force_sweep_skipped": ev.sweep_skipped,
            "force_sweep_poses": ev.sweep_poses,
            "force_sweep_note": ev.sweep_note,
            "real_frames_exponent": asdict(ev.frames_exponent) if ev.frames_exponent is not None else None,
            "texture": ev.texture,
            "near_contact": {
                "note": ev.near_note,
                "model": [asdict(r) if r else None for r in ev.near_rows],
                "baselines": [asdict(r) if r else None for r in ev.near_baselines],
                "physics_render": asdict(ev.near_physics) if ev.near_physics else None,
            },
            "light_load": ev.light_load,
        }
        payload["parts"][ev.part] = part_payload
        if k == 0:  # the first part also at the top, where single-part reports kept it
            payload.update({key: part_payload[key] for key in ("model", "physics_render", "physics_render_note")})
    lines += paper_section()
    (out / "report.md").write_text(strip_paths("\n".join(lines) + "\n"))
    (out / "metrics.json").write_text(strip_paths(json.dumps(json_safe(payload), indent=2) + "\n"))
    return out / "report.md"


def paper_section() -> list[str]:
    return [
        "",
        "## The paper's numbers (for orientation only)",
        "",
        "From the paper's own table (docs/reference.md): its real sensors' frames at 256×256 px, its data and "
        "split, with TACTO, Taxim and FOTS as its lighting-model baselines. Not comparable with the rows above, "
        "which are this split's frames at this model's size.",
        "",
        "| method (paper, real data, 256 px) | MSE | MAE | SSIM | PSNR |",
        "|---|---|---|---|---|",
    ] + [f"| {name} | {mse_} | {mae_} | {ssim_} | {psnr_} |" for name, mse_, mae_, ssim_, psnr_ in PAPER_ROWS]


def _part_section(ev: Evaluation, out: Path, suffix: str) -> list[str]:
    from model.evaluation.figures import error_vs_time_plot, force_sweep_figure, marker_flow_figure, samples_figure
    from model.sweeps.sweep_report import sweep_section

    n = ev.rows[0].images if ev.rows else 0
    lines = [
        "",
        f"## Part `{ev.part}`: {part_text(ev)} ({', '.join(ev.objects)})",
        "",
        metrics_verdict(ev),
        "",
        f"{n} frames. Metrics as docs/reference.md#metrics defines them (0–255 scale, all channels, "
        "whole image), each the mean over the frames with its 95 % bootstrap interval over them in brackets "
        "(2,000 resamples); marker error: mean distance per matched marker of the central 18×18, in px at the "
        "evaluated size. Baselines need no model: the run's no-contact frame; the mean training frame; that "
        "no-contact frame plus the training frames' mean contact moved to the frame's pose; the training frame "
        "whose condition (object, pose x, y, θ, wrench) is nearest; and the simulator's render through the "
        "calibrated sensor profile.",
        "",
        "| method | MSE | MAE | SSIM | PSNR | marker px/marker | s / image | s / network evaluation |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in ev.rows:
        lines.append(_fmt_row(f"this model ({r.setting})", r))
    for r in ev.baselines:
        lines.append(_fmt_row(f"baseline: {r.setting}", r))
    if ev.baseline is not None:
        words = (
            "baseline: physics render at the measured pose (the simulator's mechanics + calibrated lighting, "
            "on the run's no-contact frame)"
        )
        lines.append(_fmt_row(words, ev.baseline))
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
    conditioning = ev.context.get("conditioning", "")
    if ev.baseline is not None and "physics" in conditioning:
        where = "the depth where the simulator's contact gives the frame's Fz" if "Fz" in conditioning else "its pose"
        lines += [
            "",
            "This row is not the image the model is conditioned on: the model's physics channels are the "
            f"simulator's render at {where}, over the simulator's own background.",
        ]
    lines += near_section(ev)
    lines += [
        "",
        f"### Error against run time (`{ev.part}`)",
        "",
        f"![error against seconds per image](error_vs_time{suffix}.png)",
        "",
        "*Error against run time*: MSE (0–255², lower is better), SSIM (higher is better) and, for marker "
        "sensors, the marker error (px per marker) of each sampler setting against its warm seconds per image on "
        "this machine (log scale), points labelled with the sampler's steps; the star is the physics render.",
        "",
        f"### Examples (`{ev.part}`)",
        "",
        f"![examples](samples{suffix}.png)",
        "",
        "*Examples*: one row per test frame, each tile the frame at the model's "
        f"{_size(ev)} px (enlarged); columns left to right: "
        + ", ".join(ev.examples)
        + ". Under each row: the wrench it was generated for (Fz in N, Fx and Fy in N, Mz in N·mm) and the "
        "pose (x, y, z in mm from the contact point, θ in degrees).",
    ]
    error_vs_time_plot(ev, out / f"error_vs_time{suffix}.png")
    samples_figure(ev.examples, out / f"samples{suffix}.png", ev.example_labels)
    lines += sweep_section(ev, out, suffix, force_sweep_figure)
    lines += texture_section(ev, out, suffix)
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


def texture_section(ev: Evaluation, out: Path, suffix: str) -> list[str]:
    """Per texture board: the texture measure of every row with its interval, a verdict, the figure."""
    from model.evaluation.texture_eval import BLURRED
    from model.evaluation.texture_figure import texture_figure

    lines: list[str] = []
    for board, table in ev.texture.items():
        frames, mask, band = ev.texture_examples[board]
        lines += [
            "",
            f"### Texture: {board} (`{ev.part}`)",
            "",
            f"Inside the contact, in the band of the board's texture periods ({band.shortest_mm:g}–"
            f"{band.longest_mm:g} mm), at the run file's own resolution ({band.mm_per_px:.4f} mm/px; generated "
            "frames enlarged to it, bicubic): the power ratio (1 is right, below 1 texture missing), the "
            "correlation of the two log power spectra over the band's 2-D frequencies (orientation counts), "
            "SSIM of the high-pass parts, and their mean, the texture score (1 only when all three are). "
            f"Blurred contact: the real frame at the model's {_size(ev)} px and back, the most texture a "
            "perfect model of that size can show. Mean over the frames, 95 % bootstrap interval in brackets.",
            "",
            "| method | power ratio | spectrum corr | high-pass SSIM | texture score |",
            "|---|---|---|---|---|",
        ]
        for name, measures in table.items():
            if isinstance(measures, str):
                lines.append(f"| {name} | {measures} | | | |")
                continue
            cells = [
                f"{measures[k][0]:.2f} [{measures[k][1]:.2f}, {measures[k][2]:.2f}]"
                for k in ("power_ratio", "spectrum_corr", "hp_ssim", "texture_score")
            ]
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines += ["", _texture_verdict(table, BLURRED)]
        figure = f"texture-{board}{suffix}.png"
        texture_figure(frames, mask, band, out / figure, f"{board}: power inside the contact ({ev.part})")
        lines += [
            "",
            f"![texture spectra and crops]({figure})",
            "",
            "*Texture*: top, the radial power spectrum inside the contact of one frame (cycles per mm, log "
            "scales), the band shaded and the frame's Nyquist frequency dotted; below, 96-pixel crops at the "
            "contact's centre, each pixel drawn as a block: real, blurred contact, the physics render, the "
            "nearest training frame and this model's frame.",
        ]
    return lines


def _texture_verdict(table: dict, blurred: str) -> str:
    scored = {n: m["texture_score"] for n, m in table.items() if not isinstance(m, str)}
    model = {n: v for n, v in scored.items() if n.startswith("this model")}
    if not model:
        return "Verdict: not scored (" + next(iter(table.values())) + ")." if table else "Verdict: no frames."
    name, best = max(model.items(), key=lambda kv: kv[1][0])
    ceiling = scored.get(blurred)
    if ceiling is None:
        return f"Verdict: {name} texture score {best[0]:.2f}."
    if best[2] < ceiling[1]:
        relation = "below"
    elif best[1] > ceiling[2]:
        relation = "above"
    else:
        relation = "level with"
    return (
        f"Verdict: {name} scores {best[0]:.2f} [{best[1]:.2f}, {best[2]:.2f}] on texture, {relation} the blurred "
        f"contact's {ceiling[0]:.2f} [{ceiling[1]:.2f}, {ceiling[2]:.2f}] (the most its resolution can show)."
    )


def _size(ev: Evaluation) -> int:
    first = next(iter(ev.examples.values()), [])
    return int(first[0].shape[0]) if first else 0
