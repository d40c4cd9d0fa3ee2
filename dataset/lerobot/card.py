"""The dataset card (README.md): the metadata block the Hub reads (tags, task category, which files are
the data) and, for a person, what the runs are, what each feature holds, in which units, and how the
frames were encoded."""

from __future__ import annotations

import numpy as np

from acquisition import schema as S
from dataset.lerobot import layout as L

HEADER = """---
task_categories:
- robotics
tags:
- LeRobot
- tactile
- {sensor}
configs:
- config_name: default
  data_files: data/*/*.parquet
---
"""

UNITS = {
    "observation.state": "the measured pose of the indenter from the contact point: x, y, z in mm (z negative into "
    "the gel), θ in degrees counter-clockwise seen by the camera",
    "action": "the commanded pose, same axes and units",
    "observation.wrench": "the gauge at the frame: Fx, Fy, Fz in N, Mx, My, Mz in N·mm",
    L.WINDOW: "the gauge's full-rate samples of the capture period ending at the frame, oldest first (N, N·mm)",
    L.WINDOW_T: "each window sample's time from the frame, s",
    L.WINDOW_PAD: "true where the window is padding (fewer samples came)",
    S.T_FRAME: "the frame's time on the rig clock, s",
    S.T_CAPTURE: "the capture's scheduled time, s of protocol time",
    S.WRENCH_SKEW: "distance from the frame time to the nearest gauge sample, s",
    S.CAPTURE_INDEX: "k of the capture grid t = k / fps",
    S.STEP_INDEX: "the protocol step running at the capture",
    S.PHASE_INDEX: "the protocol phase (each run's names in meta/tactile/runs/*/run.json, `phases`; the first run's)",
    S.LEVEL: "the depth level, 1-based (0: approach or retract)",
    S.RETAKE: "0, or n: recorded again by the n-th resume",
    L.FRAME_IN_RUN: "the frame's index in its source run file",
}


def _count(n: int, noun: str) -> str:
    return f"{n:,} {noun}{'' if n == 1 else 's'}"


def card_text(runs, info: dict, chosen, summary) -> str:
    sensors = sorted({r.text(S.ATTR_SENSOR_KIND) for r in runs})
    lines = [HEADER.format(sensor="-".join(sensors) or "tactile"), "# Tactile sensor dataset\n"]
    lines.append(
        f"{_count(info['total_frames'], 'frame')} in {_count(info['total_episodes'], 'episode')} from "
        f"{_count(len(runs), 'run')} of a motorised rig pressing objects on a vision-based tactile sensor, at "
        f"{_count(info['fps'], 'frame')} per second, with the six-axis wrench and the pose at every frame. "
        "LeRobotDataset format v3.0, written by tactile-rig.\n"
    )
    lines += ["| run file | object | sensor | frames | status |", "|---|---|---|---|---|"]
    for r in runs:
        lines.append(f"| {r.path.name} | {r.text(S.ATTR_OBJECT)} | {r.text(S.ATTR_SENSOR_KIND)} | {r.n} | {r.status} |")
    codec_line = (
        "lossless (H.264 RGB at quantiser 0: every pixel equals the run file's, checked at export)"
        if chosen.lossless
        else f"{chosen.name}, lossy: mean squared error {np.mean(summary.mse):.2f} against the run's frames "
        f"(grey levels², measured at export over every frame)"
    )
    lines += ["", f"**Frames**: `{L.CAMERA}`, {codec_line}.", "", "| feature | holds |", "|---|---|"]
    phases = ", ".join(f"{i} {name}" for i, name in enumerate(runs[0].phases))
    for name in info["features"]:
        if name in UNITS:
            holds = UNITS[name] + (f": {phases}" if name == S.PHASE_INDEX else "")
            lines.append(f"| `{name}` | {holds} |")
    splits = ", ".join(f"{k} episodes {v}" for k, v in info["splits"].items())
    lines += [
        "",
        f"**Splits**: {splits}.",
        "",
        "**The contact condition** (what the tactile model is conditioned on) is in `meta/tactile/`: per episode "
        "the object's contact-face image at pose 0 and `condition.json` (object, sensor, mm per pixel, the pose "
        "convention); per run its full record, reference frame and full-rate wrench stream.",
        "",
        "Load it with `LeRobotDataset(repo_id, root=folder)` (the `lerobot` or `lerobot-dataset` package).",
        "",
    ]
    return "\n".join(lines)
