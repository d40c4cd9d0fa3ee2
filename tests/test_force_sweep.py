"""The force-response measures recover known responses on synthetic frames (no network)."""

import math

import numpy as np
import pytest

from model.sweeps import force_sweep as F
from model.sweeps import sweep_measures as M
from model.sweeps import sweep_references as R
from model.sweeps.sweep_report import reference_table, response_table, verdict

SIZE = 64
MM_PER_PX = 0.1
GREY = 100
RADIUS_PX_PER_N3 = 6.0  # disk radius = 6 px × F^(1/3): Hertz's a ∝ F^(1/3)
SHIFT_PX_PER_N = 3.0  # the contact slides 3 px per N of Fx


def disk(radius_px: float, shift_px: float = 0.0, gain: float = 60.0) -> np.ndarray:
    img = np.full((SIZE, SIZE, 3), GREY, np.uint8)
    rows, cols = np.mgrid[:SIZE, :SIZE]  # pixel centres within the radius: area ≈ π r², sub-pixel exact
    inside = (cols - (SIZE - 1) / 2 - shift_px) ** 2 + (rows - (SIZE - 1) / 2) ** 2 <= radius_px**2
    img[inside] = GREY + gain
    return img


def hertz(wrench: np.ndarray) -> np.ndarray:
    fz = max(0.0, float(wrench[2]))
    return disk(RADIUS_PX_PER_N3 * fz ** (1 / 3), SHIFT_PX_PER_N * float(wrench[0]))


NO_CONTACT = np.full((SIZE, SIZE, 3), GREY, np.uint8)


def sweep(generator, component, values, references=None, base=(0.0, 0.0, 2.0, 0.0, 0.0, 0.0), blur_px=1.0, **more):
    refs = references if references is not None else [(None, "")] * len(values)
    return F.sweep_pose(
        lambda p, wrenches: [generator(w) for w in wrenches],
        0,
        component,
        np.asarray(values, dtype=float),
        np.asarray(base),
        no_contact=NO_CONTACT,
        mm_per_px=MM_PER_PX,
        references=refs,
        blur_px=blur_px,
        **more,
    )


def test_area_centroid_and_shading_of_a_disk():
    m = M.measure_contact(disk(10, shift_px=5), NO_CONTACT, mm_per_px=MM_PER_PX, blur_px=0)
    assert m.area_px == pytest.approx(math.pi * 10**2, rel=0.08)
    assert m.area_mm2 == pytest.approx(m.area_px * MM_PER_PX**2)
    assert m.centroid_x_mm == pytest.approx(0.5, abs=0.06) and m.centroid_y_mm == pytest.approx(0.0, abs=0.06)
    assert m.shading == pytest.approx(60.0, abs=0.5)
    none = M.measure_contact(NO_CONTACT, NO_CONTACT, mm_per_px=MM_PER_PX)
    assert none.area_px == 0 and math.isnan(none.centroid_x_mm) and none.shading == 0
    with pytest.raises(ValueError, match="mm_per_px"):
        M.measure_contact(NO_CONTACT, NO_CONTACT, mm_per_px=float("nan"))
    with pytest.raises(ValueError, match="differ in shape"):
        M.measure_contact(NO_CONTACT[:10], NO_CONTACT, mm_per_px=MM_PER_PX)


def test_hertz_disks_give_a_monotonic_area_with_exponent_two_thirds():
    values = F.sweep_values(0.5, 16.0, 8)
    s = F.summarise(sweep(hertz, "Fz", values, blur_px=0))
    assert s["area_mm2"]["rho"] == pytest.approx(1.0)
    assert s["monotonic"] and s["area_sign_consistency"] == 1.0
    assert s["area_exponent"] == pytest.approx(2 / 3, abs=0.03)
    assert s["area_mm2"]["slope"] > 0
    # the blur (against noise) widens every edge by about a pixel: the ranking stays, the exponent drops a little
    blurred = F.summarise(sweep(hertz, "Fz", values, blur_px=1.0))
    assert blurred["area_mm2"]["rho"] == pytest.approx(1.0) and 0.5 < blurred["area_exponent"] < 2 / 3


def test_a_sliding_contact_gives_the_centroid_slope():
    values = F.sweep_values(-2.0, 2.0, 5)
    s = F.summarise(sweep(hertz, "Fx", values))
    # 3 px per N at 0.1 mm/px: 0.3 mm per N, rank correlation 1, and the area does not respond
    assert s["centroid_x_mm"]["slope"] == pytest.approx(SHIFT_PX_PER_N * MM_PER_PX, rel=0.1)
    assert s["centroid_x_mm"]["rho"] == pytest.approx(1.0)
    assert abs(s["centroid_y_mm"]["slope"]) < 0.01


def test_a_generator_that_ignores_the_force_is_flagged():
    values = F.sweep_values(0.5, 16.0, 8)
    flat = F.summarise(sweep(lambda w: disk(12), "Fz", values))
    assert math.isnan(flat["area_mm2"]["rho"]) and not flat["monotonic"] and flat["area_sign_consistency"] == 0.0
    shrinking = F.summarise(sweep(lambda w: disk(20 - float(w[2])), "Fz", values))
    assert shrinking["area_mm2"]["rho"] == pytest.approx(-1.0) and not shrinking["monotonic"]
    table = "\n".join(response_table([flat], {"Fz": (0.5, 16.0)}))
    assert "| Fz | +0.50 … +16.00 N | 1 | — (no response) | 0/1 (pressing harder never shrinks the contact) |" in table


def test_the_error_against_a_reference_is_the_known_difference():
    values = F.sweep_values(1.0, 8.0, 4)
    bigger = [(disk(RADIUS_PX_PER_N3 * v ** (1 / 3) + 2), "real frame") for v in values[:3]] + [(None, "")]
    s = F.summarise(sweep(hertz, "Fz", values, references=bigger))
    model = np.array(s["model_area_mm2"][:3])
    ref = np.array(s["real_area_mm2"][:3])
    assert s["references_real"] == 3 and s["references_render"] == 0 and math.isnan(s["real_area_mm2"][3])
    assert s["area_mm2"]["real_mae"] == pytest.approx(np.mean(np.abs(model - ref)))
    assert s["area_mm2"]["real_mae"] > 0.5  # a radius 2 px larger at 0.1 mm/px: well over half a mm²
    assert s["area_mm2"]["real_rho"] == pytest.approx(1.0) and s["monotonic"]
    # k compared over the points both have: a radius 2 px larger grows relatively slower, so its k is lower
    assert 0 < s["real_area_exponent"] < s["area_exponent_at_real"]


def test_spearman_slope_and_power_law():
    assert M.spearman([1, 2, 3, 4], [1, 3, 2, 4]) == pytest.approx(0.8)
    assert M.spearman([1, 2, 3, 4], [10, 10, 10, 10]) != M.spearman([1, 2, 3, 4], [10, 10, 10, 10])  # nan
    assert M.spearman([1, 2, 3, 4, 5], [1, 1, 2, 2, 3]) == pytest.approx(9 / math.sqrt(90))  # ties: mean ranks
    assert M.slope([0, 1, 2], [1, 3, 5]) == pytest.approx(2.0)
    f = np.array([1.0, 2.0, 4.0, 8.0])
    assert M.power_exponent(f, 3 * f**0.5) == pytest.approx(0.5)
    assert M.sign_consistency([1, 2, 2, 3], +1) == pytest.approx(2 / 3)


def test_real_frames_are_matched_at_the_pose_and_depth_follows_the_runs_force():
    # a run pressing at two places, four depths each; Fz = 10 N/mm^1.5 × depth^1.5
    depth = np.tile([0.2, 0.4, 0.6, 0.8], 2)
    pose = np.stack([np.repeat([0.0, 1.0], 4), np.zeros(8), -depth, np.zeros(8)], axis=1)
    wrench = np.zeros((8, 6))
    wrench[:, 2] = 10 * depth**1.5
    std = np.ones(6)
    values = np.array([0.5, 2.5, 5.0, 7.2, 20.0])
    found = R.match_real_frames(wrench, pose, 1, 2, values, std)
    # nearest at x = 0 only: 0.89 (frame 0) is within half a step of 0.5, 20 N is beyond the run
    assert found[:4] == [0, 1, 2, 3] and found[4] is None
    assert R.match_real_frames(wrench, pose, 5, 2, values, std)[:4] == [4, 5, 6, 7]
    assert R.depth_for_force(wrench[:, 2], pose[:, 2], 10 * 0.5**1.5) == pytest.approx(-0.5, abs=0.05)
    assert R.depth_for_force(wrench[:, 2], pose[:, 2], 50.0) is None


def test_poses_are_in_contact_low_shear_and_never_twins():
    n = 20
    wrench = {r: np.zeros((n, 6)) for r in (0, 1)}
    pose = {r: np.zeros((n, 4)) for r in (0, 1)}
    for r in (0, 1):
        wrench[r][:, 2] = np.linspace(0, 10, n)
        wrench[r][:, 0] = np.linspace(3, -3, n) ** 2  # least shear at the middle frames
        pose[r][:, 0] = np.linspace(0, 4, n)  # the two runs press at the same places
    rows = np.array([[r, f] for r in (0, 1) for f in range(n)])
    chosen = F.choose_poses(rows, wrench.__getitem__, pose.__getitem__, 3, np.ones(6))
    assert len(chosen) == 3
    fz = np.linspace(0, 10, n)
    shear = np.linspace(3, -3, n) ** 2
    assert all(1.0 <= fz[f] <= 9.5 and shear[f] <= np.median(shear[(fz >= 1.0) & (fz <= 9.5)]) for _, f in chosen)
    frames = [f for _, f in chosen]
    assert len(set(frames)) == 3  # the same frame of the other run is a twin: never chosen twice


def test_monotonic_follows_the_sign_of_the_references_rho_not_its_size():
    """Regression (issue 27): the model's ρ was multiplied by the reference's ρ, so a model ρ of +0.94
    against a reference whose own ρ was +0.5 counted as not monotonic ('monotonic poses 1/3')."""
    values = F.sweep_values(1.0, 8.0, 7)
    # references that grow only weakly and noisily (ρ = +0.5): the direction is 'growing' all the same
    radii = [5.0, 6.5, 5.5, 7.0, 6.0, 7.5, 6.8]
    refs = [R.Reference(disk(r), R.REAL, "real frame") for r in radii]
    s = F.summarise(sweep(hertz, "Fz", values, references=refs))
    assert 0.3 < s["area_mm2"]["real_rho"] < 0.8 and s["area_mm2"]["rho"] >= 0.8
    assert s["direction"] == 1.0 and s["direction_from"] == "real frames"
    assert s["monotonic"]
    # three such poses: all three monotonic, and the table says 3/3
    table = "\n".join(response_table([s, s, s], {"Fz": (1.0, 8.0)}))
    assert "| 3/3 (real frames) |" in table
    # a model against a shrinking reference direction is not monotonic, however large its ρ
    shrinking = [R.Reference(disk(9 - r), R.REAL, "real frame") for r in radii]
    assert not F.summarise(sweep(hertz, "Fz", values, references=shrinking))["monotonic"]


def test_components_without_range_are_skipped_and_said():
    pct = {"p2": [0.0, -0.3, 0.4, 0, 0, 0.0], "p98": [0.0, 0.3, 1.8, 0, 0, 0.0]}
    ranges, skipped = F.swept_ranges(pct, ("Fz", "Fx", "Fy", "Mz"))
    assert ranges == {"Fz": (0.4, 1.8), "Fy": (-0.3, 0.3)}
    assert set(skipped) == {"Fx", "Mz"}
    assert skipped["Fx"] == "Fx: no range in the training data (2nd to 98th percentile +0.00 … +0.00 N): not swept"
    assert "N·mm" in skipped["Mz"]


def test_real_frames_and_renders_are_reported_apart():
    values = F.sweep_values(1.0, 8.0, 4)
    refs = [
        R.Reference(disk(RADIUS_PX_PER_N3 * values[0] ** (1 / 3)), R.REAL, "real frame 3"),
        R.Reference(disk(RADIUS_PX_PER_N3 * values[1] ** (1 / 3)), R.REAL, "real frame 9"),
        R.Reference(disk(3 * RADIUS_PX_PER_N3 * values[2] ** (1 / 3)), R.RENDER, "physics render at z -1 mm"),
        R.Reference(disk(3 * RADIUS_PX_PER_N3 * values[3] ** (1 / 3)), R.RENDER, "physics render at z -2 mm"),
    ]
    s = F.summarise(sweep(hertz, "Fz", values, references=refs))
    assert (s["references_real"], s["references_render"]) == (2, 2)
    assert s["area_mm2"]["real_mae"] < 0.05  # the real frames are the model's own disks
    assert s["area_mm2"]["render_mae"] > 5  # renders three times as wide: their error is theirs alone
    table = "\n".join(reference_table([s], {"Fz": (1.0, 8.0)}))
    assert "| Fz | real frames | 2/4 |" in table and "| Fz | physics render | 2/4 |" in table


def test_beyond_the_training_range_is_measured_apart_and_in_the_verdict():
    values = np.concatenate([F.sweep_values(1.0, 8.0, 5), F.beyond_values(1.0, 8.0, 1.0)])
    inside = [True] * 5 + [False] * 2

    def striped(w):  # a model that draws stripes past 8 N
        img = hertz(w)
        if w[2] > 8.0:
            img[:, ::4] = GREY + 40
        return img

    s = F.summarise(
        F.sweep_pose(
            lambda p, ws: [striped(w) for w in ws],
            0,
            "Fz",
            values,
            np.array([0, 0, 2.0, 0, 0, 0]),
            no_contact=NO_CONTACT,
            mm_per_px=MM_PER_PX,
            references=[R.NONE] * 7,
            inside=inside,
            blur_px=0.0,
        )
    )
    assert s["values"][-2:] == pytest.approx([11.5, 15.0]) and s["beyond_values"] == pytest.approx([11.5, 15.0])
    assert s["area_exponent"] == pytest.approx(2 / 3, abs=0.05)  # within the training range only
    assert s["outside_change_in_range"] < 1 < s["outside_change_beyond"]
    line = verdict([s], None, {})
    assert line.startswith("**Verdict**: the contact grows monotonically with Fz at 1/1 poses, k = 0.6")
    assert "past the training maximum" in line


def test_the_verdict_holds_the_model_to_the_real_frames_exponent():
    values = F.sweep_values(1.0, 8.0, 5)
    s = F.summarise(sweep(hertz, "Fz", values, blur_px=0))
    good = M.FramesExponent(0.6, 0.5, 0.7, 0.9, 20, 1.0, 8.0)
    assert "within ±30%" in verdict([s], good, {})
    assert "outside ±30%" in verdict([s], M.FramesExponent(0.3, 0.2, 0.4, 0.9, 20, 1.0, 8.0), {})
    vague = M.FramesExponent(-0.2, -0.8, 0.7, -0.1, 24, 1.2, 1.8)
    assert "not determined" in verdict([s], vague, {})
    assert "Fz was not swept (Fz: no range" in verdict([], None, {"Fz": "Fz: no range in the training data"})


def test_the_real_frames_exponent_has_a_bootstrap_interval():
    rng = np.random.default_rng(1)
    f = np.linspace(1, 9, 30)
    area = f ** (2 / 3) * np.exp(rng.normal(0, 0.05, 30))
    fe = M.frames_exponent(f, area)
    assert fe.low < 2 / 3 < fe.high and fe.high - fe.low < 0.2 and fe.frames == 30
    flat = M.frames_exponent(np.linspace(1.2, 1.8, 24), np.exp(rng.normal(0, 0.2, 24)))
    assert flat.low < 0 < flat.high  # no force range to speak of: the interval says so


def test_poses_say_when_they_share_a_run():
    assert F.pose_runs([(0, 1), (1, 5), (2, 9)], {}) == "3 poses, each from a different run"
    text = F.pose_runs([(0, 1), (1, 5), (0, 9)], {0: "a.h5", 1: "b.h5"})
    assert text == "3 poses from 2 run(s), so not all from different runs: poses 1, 3 from a.h5"


def test_the_contact_threshold_follows_the_parts_peak_change():
    frames = [disk(8, gain=90), disk(9, gain=96), NO_CONTACT]
    threshold, peak = M.contact_threshold(frames, [NO_CONTACT] * 3, blur_px=0)
    assert peak == pytest.approx(93) and threshold == pytest.approx(31)  # a third of the median, contacts only
    assert M.contact_threshold([NO_CONTACT], [NO_CONTACT], 0)[0] == M.THRESHOLD


def test_without_a_real_exponent_the_model_is_held_to_the_render_at_its_poses():
    """GelSight presses (issue 27): one press per place, so no real frames at one pose and several forces,
    and across the field the measured contact shrinks as the derived Fz grows: the verdict says so and
    holds the model to the calibrated render's exponent at the same poses."""
    values = F.sweep_values(1.0, 8.0, 5)
    renders = [R.Reference(disk(RADIUS_PX_PER_N3 * v ** (1 / 3)), R.RENDER, "physics render") for v in values]
    s = F.summarise(sweep(hertz, "Fz", values, references=renders, blur_px=0))
    assert s["render_area_exponent"] == pytest.approx(2 / 3, abs=0.1)
    falling = M.FramesExponent(-0.49, -1.05, -0.16, -0.42, 24, 1.18, 1.78, "24 real frames")
    line = verdict([s], falling, {})
    assert "reference exponent 0.67 (the physics render at the sweep's 1 pose(s) and Fz points" in line
    assert "within ±30%" in line
    assert "interval [-1.05, -0.16] that lies below zero" in line


def test_on_simulated_frames_the_one_reference_is_the_simulators_render():
    """Simulated frames (issue 37): the recorded frames at the poses (0.50 here) and across the part (0.55)
    are diagnostics; the one reference is the render at the sweep's poses, the simulator that made the
    frames. A model matching the simulator's 0.67 passes; on a real sensor the real frames come first."""
    values = F.sweep_values(1.0, 8.0, 5)
    renders = [R.Reference(disk(RADIUS_PX_PER_N3 * v ** (1 / 3)), R.RENDER, "physics render") for v in values]
    s = F.summarise(sweep(hertz, "Fz", values, references=renders, blur_px=0))
    s["real_area_exponent"] = 0.50
    across = M.FramesExponent(0.55, 0.50, 0.60, 0.9, 40, 0.1, 3.0, "40 frames")
    simulated = verdict([s], across, {}, simulated=True)
    assert "reference exponent 0.67" in simulated and "the simulator that made these frames" in simulated
    assert "within ±30%" in simulated and simulated.count("reference exponent") == 1
    real = verdict([s], across, {}, simulated=False)
    assert "reference exponent 0.50 (the real frames at the sweep's poses" in real and "outside ±30%" in real


def test_a_pose_is_swept_only_over_what_its_own_run_recorded_and_says_so(monkeypatch):
    recorded = np.linspace(0.0, 2.4, 50)  # this run pressed to 2.4 N; the split's training range reaches 7.2 N
    low, high, note = F.pose_range((1.2, 7.2), recorded, "Fz", "sphere4mm.h5")
    assert low == pytest.approx(1.2) and high == pytest.approx(2.4)
    assert "sphere4mm.h5" in note and "no value past the training maximum" in note
    assert F.pose_range((1.2, 7.2), np.linspace(0.0, 9.0, 50), "Fz", "sphere10mm.h5") == (1.2, 7.2, "")
    # the run holding the split's largest loads reaches the training maximum (its 2nd–98th percentile of 19
    # training frames lies inside the run's extremes, not inside the run's own percentiles)
    presses = np.linspace(1.18, 1.78, 24)
    assert F.pose_range((1.20, 1.76), presses, "Fz", "gelsight.h5") == (1.20, 1.76, "")
    low, high, note = F.pose_range((-1.0, 1.0), np.zeros(30), "Fx", "press.h5")  # a run without shear
    assert not high > low and "nothing left" in note

    def hertz_gen(p, ws):
        return [hertz(w) for w in ws]

    run = R.RunData(
        "sphere4mm.h5",
        np.c_[np.zeros((50, 2)), recorded, np.zeros((50, 3))],
        np.zeros((50, 4)),
        NO_CONTACT,
        MM_PER_PX,
        SIZE,
    )
    monkeypatch.setattr(F, "references_at", lambda *a, **k: [R.NONE] * len(a[5]))  # no run file to match in
    lines, skipped = [], {}
    out = F.run_force_sweep(
        hertz_gen,
        {0: run},
        [(0, 49)],
        {"Fz": (1.2, 7.2), "Fx": (-1.0, 1.0)},
        np.ones(6),
        points=5,
        beyond=0.5,
        log=lines.append,
        skipped=skipped,
    )
    assert [s.component for s in out] == ["Fz"]  # Fx has nothing left at this pose: not swept, and said
    assert any("Fx at pose 1: not swept" in line for line in lines)
    assert "swept at no pose" in skipped["Fx"] and "nothing left" in skipped["Fx"]  # the report says why
    assert max(out[0].values) <= recorded.max() + 1e-9  # no "in range" value past the run, no beyond
    assert all(out[0].inside) and "sphere4mm.h5" in out[0].range_note


def test_values_the_render_could_not_reach_are_left_out_of_every_measure_and_said():
    values = F.sweep_values(1.0, 8.0, 5)

    def clamped(w):  # the model's channels stop at the gel's limit past 4.5 N: its picture stops growing
        return hertz(np.array([0, 0, min(float(w[2]), 4.5), 0, 0, 0]))

    limit = "past what the gel gives; rendered at 2.4 mm"
    notes = ["" if v <= 4.5 else limit for v in values]
    s = F.summarise(sweep(clamped, "Fz", values, [R.NONE] * 5, blur_px=0.0, notes=lambda: notes))
    assert s["render_limited_values"] == pytest.approx([6.25, 8.0]) and s["render_limited_note"] == limit
    assert s["area_exponent"] == pytest.approx(2 / 3, abs=0.08)  # from the three points the render reached
    assert "beyond_values" not in s  # the left-out values are not "past the training maximum" either
    from model.sweeps.sweep_report import pose_notes

    assert any("left out of every measure" in line and limit in line for line in pose_notes([s]))


def test_past_the_maximum_compares_with_the_last_value_the_model_was_conditioned_at():
    values = np.concatenate([F.sweep_values(1.0, 8.0, 5), F.beyond_values(1.0, 8.0, 1.0)])
    inside = [True] * 5 + [False] * 2
    notes = ["no depth for this value"] + [""] * 6  # the lowest value left out, the rest measured
    s = F.summarise(sweep(hertz, "Fz", values, [R.NONE] * 7, blur_px=0.0, inside=inside, notes=lambda: notes))
    assert s["last_inside_index"] == 4 and s["usable_points"] == 4
    assert "keeps growing at 1/1 poses" in verdict([s], None, {})
    everything = F.summarise(sweep(hertz, "Fz", values[:5], [R.NONE] * 5, blur_px=0.0, notes=lambda: ["limit"] * 5))
    assert everything["last_inside_index"] is None and math.isnan(everything["area_exponent"])


def test_default_sweep_poses_span_the_field_and_the_loads():
    """Issue 37: the three poses of before sat next to each other in Fz on one half of the field. The
    default eight span at least 60 % of the field's width (and height) and of the part's Fz range."""
    from model.sweeps.force_sweep import choose_poses

    rng = np.random.default_rng(0)
    runs = {}
    for r in range(3):  # presses over the field, each a ramp of load, some shear
        n = 120
        pose = np.zeros((n, 4))
        pose[:, 0] = np.repeat(rng.uniform(-3, 3, 6), 20)
        pose[:, 1] = np.repeat(rng.uniform(-2, 2, 6), 20)
        wrench = np.zeros((n, 6))
        wrench[:, 2] = np.tile(np.linspace(0.0, 6.0, 20), 6)
        wrench[:, :2] = rng.normal(0, 0.2, (n, 2))
        runs[r] = (pose, wrench)
    rows = np.array([(r, f) for r in runs for f in range(120)], dtype=np.int32)
    chosen = choose_poses(rows, lambda r: runs[r][1], lambda r: runs[r][0], 8, np.array([0.2, 0.2, 1, 1, 1, 1]))
    assert len(chosen) == 8 and len(set(chosen)) == 8
    xs = np.array([runs[r][0][f, 0] for r, f in chosen])
    ys = np.array([runs[r][0][f, 1] for r, f in chosen])
    fz = np.array([runs[r][1][f, 2] for r, f in chosen])
    all_x = np.concatenate([p[:, 0] for p, _ in runs.values()])
    all_y = np.concatenate([p[:, 1] for p, _ in runs.values()])
    all_fz = np.concatenate([w[:, 2] for _, w in runs.values()])
    assert np.ptp(xs) >= 0.6 * np.ptp(all_x) and np.ptp(ys) >= 0.6 * np.ptp(all_y)
    assert np.ptp(fz) >= 0.6 * np.ptp(all_fz)


def test_the_centroid_is_measured_with_y_up_like_every_other_figure():
    """Issue 37: a contact above the image centre (smaller row) had a negative centroid y."""
    image = NO_CONTACT.copy()
    h, w = image.shape[:2]
    rows, cols = np.mgrid[:h, :w]
    image[(rows - (h // 2 - 10)) ** 2 + (cols - w // 2) ** 2 < 36] = 200  # 10 px above the centre
    m = M.measure_contact(image, NO_CONTACT, mm_per_px=MM_PER_PX, blur_px=0)
    assert m.centroid_y_mm == pytest.approx(10 * MM_PER_PX, abs=0.6 * MM_PER_PX)
