"""What an evaluation holds: a metrics row per method, and one part's whole evaluation.

Kept apart from model/evaluation/evaluate.py (which computes them) so that the report writer
(model/evaluation/evaluation_report.py) reads them without importing the evaluation itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from model.sweeps.sweep_measures import FramesExponent

# docs/reference.md, "The model, as the paper states it": the paper's own table, on its real data at 256 px;
# reports print it in a table of its own, never among this run's rows
PAPER_ROWS = [
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
    # 95 % bootstrap interval over the frames of each metric's mean (model/evaluation/intervals.py):
    # metric → (low, high)
    ci: dict[str, tuple[float, float]] = field(default_factory=dict)
    per_frame: dict[str, list[float]] = field(default_factory=dict)  # each frame's value of each metric


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
    part: str = "test"
    objects: list[str] = field(default_factory=list)  # the objects whose frames the part holds
    test_runs: list[str] = field(default_factory=list)  # the split's runs named for the test part (--test-runs)
    unseen_objects: bool = False  # none of them is in the training part (a --by object split's test part)
    sweeps: list = field(default_factory=list)  # force_sweep.PoseSweep, one per (pose, component)
    sweep_summary: list[dict] = field(default_factory=list)  # force_sweep.summarise of each
    sweep_ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    sweep_note: str = ""  # how the sweep was made, or why there is none
    profiles: dict[str, str] = field(default_factory=dict)  # run file → the sensor profile its physics row used
    baselines: list[Row] = field(
        default_factory=list
    )  # model/evaluation/simple_baselines.py's rows (the physics render apart)
    sweep_skipped: dict[str, str] = field(default_factory=dict)  # component → why it was not swept
    sweep_poses: str = ""  # how many poses, from how many runs, in words
    frames_exponent: FramesExponent | None = None  # k of area ∝ Fz^k across the part's real frames
    # texture boards: {board: {row: {measure: (mean, low, high)} or why not scored}} (model/evaluation/texture_eval.py)
    texture: dict = field(default_factory=dict)
    texture_examples: dict = field(default_factory=dict)  # board → (frames by label, contact mask, band)
    # model/evaluation/contact_scores.py: each row's metrics near the contact (None: no frame's contact seen) ...
    near_rows: list[Row | None] = field(default_factory=list)  # this model's, one per setting
    near_baselines: list[Row | None] = field(default_factory=list)  # one per baseline
    near_physics: Row | None = None
    near_note: str = ""  # the region, its threshold and how many frames had one; or why none
    light_load: list[dict] = field(default_factory=list)  # contact_scores.light_load of every row
