"""`dataset import` cannot silently mislead (issue 15): each mistake seen importing real presses
from another sensor is refused, converted, or made visible by `dataset preview --condition`.

The folders hold simulated presses of a 4 mm ball (sensor_sim), written as another rig would.
"""

from __future__ import annotations

import csv
import functools
import json
import re
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from acquisition import schema as S
from cli.dataset_app import app
from common.sensors import SENSOR_KINDS
from dataset.condition import place_object
from dataset.interchange import import_run
from dataset.pose_convention import POSE_CONVENTION
from dataset.preview import contact_sheet
from objects.indenters import get_indenter
from objects.pose import Pose

runner = CliRunner()
# presses across the field of view: x, y [mm] (z, theta fixed); +y up, as run files hold them
PRESSES_MM = ((-2.0, 1.5), (1.5, 2.0), (2.0, -1.5), (-1.5, -2.0), (0.5, 1.0), (-1.0, -0.5), (0.0, 2.2), (2.2, 0.0))
Z_MM, THETA_DEG = -0.6, 0.0
ONE_LINE = 10_000  # wide enough that rich never wraps an error line in the CLI output


@functools.cache
def _sim() -> tuple[np.ndarray, tuple[np.ndarray, ...], float]:
    """(reference, frames, mm per pixel): real simulator frames, rendered once per session."""
    from sensor_sim.light import OpticsSpec
    from sensor_sim.scene import Scene

    scene = Scene("sphere4mm", "rgb", optics=OpticsSpec(kind="rgb", noise_std=1.0))
    reference = scene.frame(Pose(0.0, 0.0, 1.0, 0.0)).image
    frames = tuple(scene.frame(Pose(x, y, Z_MM, THETA_DEG)).image for x, y in PRESSES_MM)
    return reference, frames, scene.geometry.width_mm / reference.shape[1]


def write_folder(
    root: Path,
    *,
    y_sign: float = 1.0,
    meta: dict | None = None,
    rows: slice = slice(None),
    object_image: np.ndarray | None = None,
) -> Path:
    """An import folder of the presses; ``y_sign`` -1 writes the poses as a y-down rig records them,
    ``rows`` cuts the frames (e.g. to 4:3), ``meta`` replaces run.json's keys (None drops a key)."""
    reference, frames, mm_per_px = _sim()
    folder = root / "folder"
    (folder / "frames").mkdir(parents=True)
    with open(folder / "frames.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["file", "Fx_N", "Fy_N", "Fz_N", "Mx_Nmm", "My_Nmm", "Mz_Nmm", "x_mm", "y_mm", "z_mm", "theta_deg"])
        for i, ((x, y), frame) in enumerate(zip(PRESSES_MM, frames)):
            cv2.imwrite(str(folder / f"frames/{i:03d}.png"), frame[rows])
            w.writerow([f"frames/{i:03d}.png", 0, 0, -2.0, 0, 0, 0, x, y_sign * y, Z_MM, THETA_DEG])
    cv2.imwrite(str(folder / "reference.png"), reference[rows])
    obj = get_indenter("sphere4mm").object_image(reference.shape[1], mm_per_px)
    cv2.imwrite(str(folder / "object.png"), obj[rows] if object_image is None else object_image)
    run = {"mm_per_px": mm_per_px, "object": "sphere4mm", "sensor": "rgb", "pose_convention": POSE_CONVENTION}
    run |= meta or {}
    (folder / "run.json").write_text(json.dumps({k: v for k, v in run.items() if v is not None}))
    return folder


def invoke(*args: object):
    return runner.invoke(app, [str(a) for a in args], terminal_width=ONE_LINE)


def unboxed(output: str) -> str:
    """A usage error's text without the box rich draws around it (it wraps at 80 columns)."""
    return re.sub(r"[\s│╭╮╰╯─]+", " ", output)


def median_offset_px(run: Path, tmp_path: Path) -> float:
    sheet = contact_sheet(run, tmp_path / "sheet.png", condition=True)
    assert len(sheet.offsets_px) == len(PRESSES_MM)  # every press is seen, and its condition in view
    median = sheet.median_offset_px
    assert median is not None
    return median


# -- the pose convention ------------------------------------------------------------------


def test_a_folder_that_does_not_state_its_pose_convention_is_refused(tmp_path):
    folder = write_folder(tmp_path, meta={"pose_convention": None})
    result = invoke("import", folder, "--out", tmp_path / "x.h5")
    assert result.exit_code == 1
    assert f"{folder / 'run.json'}: [pose_convention] missing" in result.output and '"y": "up"' in result.output
    assert not (tmp_path / "x.h5").exists()


@pytest.mark.parametrize(
    "convention, key, words",
    [
        ({"y": "sideways"}, "pose_convention.y", "must be 'up' or 'down', got 'sideways'"),
        ({"origin": "stage_zero"}, "pose_convention.origin", "must be 'contact_point'"),
        ({"units": "inch"}, "pose_convention", "keys must be x, y, z, theta, origin; unknown units; units are"),
    ],
)
def test_a_convention_import_cannot_convert_is_refused_naming_the_key(tmp_path, convention, key, words):
    folder = write_folder(tmp_path, meta={"pose_convention": POSE_CONVENTION | convention})
    result = invoke("import", folder, "--out", tmp_path / "x.h5")
    assert result.exit_code == 1 and f"run.json: [{key}] {words}" in result.output, result.output


def test_a_y_down_folder_that_says_so_is_converted_and_lines_up(tmp_path):
    folder = write_folder(tmp_path, y_sign=-1.0, meta={"pose_convention": POSE_CONVENTION | {"y": "down"}})
    import_run(folder, tmp_path / "run.h5")
    with h5py.File(tmp_path / "run.h5", "r") as f:
        np.testing.assert_allclose(f[S.POSE_MEASURED][:, 1], [y for _, y in PRESSES_MM])  # stored +y up
        np.testing.assert_allclose(f[S.POSE_COMMANDED][:, 1], [y for _, y in PRESSES_MM])
    assert median_offset_px(tmp_path / "run.h5", tmp_path) < 3.0
    info = invoke("info", tmp_path / "run.h5")
    assert "pose: +x right, +y up in the frame" in info.output and "converted: y flipped" in info.output


def test_preview_shows_a_mirrored_import_far_from_the_contact(tmp_path):
    """The mistake of issue 15: y-down poses stated (or assumed) as y up. Import cannot know;
    the preview measures it: small for the correct folder, tens of pixels for the mirrored one."""
    good = write_folder(tmp_path / "good")
    mirrored = write_folder(tmp_path / "mirrored", y_sign=-1.0)  # says y up, holds y down
    import_run(good, tmp_path / "good.h5")
    import_run(mirrored, tmp_path / "mirrored.h5")
    assert median_offset_px(tmp_path / "good.h5", tmp_path) < 3.0
    assert median_offset_px(tmp_path / "mirrored.h5", tmp_path) > 40.0  # 2|y| / mm_per_px: ~55-80 px here
    result = invoke("preview", tmp_path / "mirrored.h5", "--out", tmp_path / "m.png", "--condition")
    assert result.exit_code == 0 and "warning: the condition lies" in result.output and "+y up" in result.output
    result = invoke("preview", tmp_path / "good.h5", "--out", tmp_path / "g.png", "--condition")
    assert result.exit_code == 0 and "warning" not in result.output
    sheet = cv2.imread(str(tmp_path / "g.png"))
    assert sheet.shape == (2 * 160 + 22, 6 * 160, 3)  # two rows of tiles and the legend
    # the condition is drawn on each tile where the pose puts it: the sheet without it differs there
    plain = invoke("preview", tmp_path / "good.h5", "--out", tmp_path / "p.png")
    assert plain.exit_code == 0
    drawn = np.abs(sheet[: 2 * 160].astype(int) - cv2.imread(str(tmp_path / "p.png")).astype(int)).sum(axis=2) > 30
    _, _, mm_per_px = _sim()
    for k, (x, y) in enumerate(PRESSES_MM):
        tile = drawn[160 * (k // 6) : 160 * (k // 6 + 1), 160 * (k % 6) : 160 * (k % 6 + 1)]
        tile[:45] = tile[-32:] = False  # the labels
        ys, xs = np.nonzero(tile)
        expected = ((127.5 + x / mm_per_px) * 160 / 256, (127.5 - y / mm_per_px) * 160 / 256)
        assert len(xs) > 300 and abs(np.median(xs) - expected[0]) < 6 and abs(np.median(ys) - expected[1]) < 8


# -- frame and object shapes ----------------------------------------------------------------

FOUR_THREE = slice(32, 224)  # 256x192 frames, centred (the contact point stays in the middle)


def test_non_square_frames_are_refused_naming_crop_and_pad(tmp_path):
    folder = write_folder(tmp_path, rows=FOUR_THREE)
    result = invoke("import", folder, "--out", tmp_path / "x.h5")
    assert result.exit_code == 1
    for words in ("000.png: the first frame is 256x192, not square", "squash", "--crop", "--pad", "--size"):
        assert words in result.output, (words, result.output)
    result = invoke("import", folder, "--out", tmp_path / "x.h5", "--size", "128")
    assert result.exit_code == 1 and "--size 128 alone would stretch it 1.33:1" in result.output
    assert not (tmp_path / "x.h5").exists()
    result = invoke("import", folder, "--out", tmp_path / "x.h5", "--crop", "--pad")
    assert result.exit_code == 2 and "give --crop or --pad, not both" in unboxed(result.output)


@pytest.mark.parametrize(
    "options, side_px, scale",
    [(("--crop",), 192, 1.0), (("--pad",), 256, 1.0), (("--crop", "--size", "96"), 96, 2.0)],
)
def test_crop_pad_and_size_keep_the_condition_on_the_contact(tmp_path, options, side_px, scale):
    folder = write_folder(tmp_path, rows=FOUR_THREE)
    result = invoke("import", folder, "--out", tmp_path / "run.h5", *options)
    assert result.exit_code == 0, result.output
    _, _, mm_per_px = _sim()
    with h5py.File(tmp_path / "run.h5", "r") as f:
        assert f[S.FRAMES].shape[1:] == (side_px, side_px, 3) and f[S.OBJECT_IMAGE].shape == (side_px, side_px, 3)
        assert f.attrs[S.ATTR_MM_PER_PX] == pytest.approx(mm_per_px * scale)
    assert median_offset_px(tmp_path / "run.h5", tmp_path) < 3.0 / scale + 0.5


def test_a_non_square_object_image_is_refused_not_stretched(tmp_path):
    reference, _, mm_per_px = _sim()
    obj = get_indenter("sphere4mm").object_image(reference.shape[1], mm_per_px)
    wide = cv2.copyMakeBorder(obj, 0, 0, 22, 22, cv2.BORDER_CONSTANT, value=(0, 0, 0))  # 300x256
    folder = write_folder(tmp_path, object_image=wide)
    result = invoke("import", folder, "--out", tmp_path / "x.h5")
    assert result.exit_code == 1 and "object.png: the object image is 300x256, not square" in result.output
    result = invoke("import", folder, "--out", tmp_path / "x.h5", "--crop")
    assert result.exit_code == 0, result.output
    with h5py.File(tmp_path / "x.h5", "r") as f:
        np.testing.assert_array_equal(f[S.OBJECT_IMAGE][()], obj)  # the centre, not a squashed copy


# -- the object's background -------------------------------------------------------------------


def test_a_translated_object_keeps_its_own_background():
    """A photo on a grey table, moved and turned: the uncovered area is grey, no black rectangle."""
    obj = np.full((101, 101, 3), (128, 132, 126), np.uint8)
    cv2.circle(obj, (50, 50), 12, (30, 200, 40), -1)
    for x_mm, y_mm, theta_deg in ((2.0, 0.0, 0.0), (-1.5, 2.5, 0.0), (1.0, -1.0, 30.0)):
        placed = place_object(obj, x_mm, y_mm, theta_deg, mm_per_px=0.1)
        centre = (50 + x_mm / 0.1, 50 - y_mm / 0.1)
        ys, xs = np.indices(placed.shape[:2])
        away = np.hypot(xs - centre[0], ys - centre[1]) > 14  # outside the disc (and its anti-aliased rim)
        assert np.abs(placed[away].astype(int) - (128, 132, 126)).max() <= 1, (x_mm, y_mm, theta_deg)
        assert placed[int(round(centre[1])), int(round(centre[0]))].tolist() == [30, 200, 40]


# -- sensor kind and profile ---------------------------------------------------------------------


def test_a_missing_sensor_kind_is_refused_at_import_with_the_choices(tmp_path):
    folder = write_folder(tmp_path, meta={"sensor": None})
    result = invoke("import", folder, "--out", tmp_path / "x.h5")
    assert result.exit_code == 1 and "[sensor] missing: pass --sensor rgb|rgb_markers|white_markers" in result.output
    meta = json.loads((folder / "run.json").read_text())
    (folder / "run.json").write_text(json.dumps(meta | {"sensor": "unknown"}))  # what import used to write
    result = invoke("import", folder, "--out", tmp_path / "x.h5")
    assert result.exit_code == 1 and f"must be one of {', '.join(SENSOR_KINDS)}, got 'unknown'" in result.output
    result = invoke("import", folder, "--out", tmp_path / "x.h5", "--sensor", "gelsight")
    assert result.exit_code == 2 and "must be one of rgb, rgb_markers, white_markers" in unboxed(result.output)
    result = invoke("import", folder, "--out", tmp_path / "x.h5", "--sensor", "rgb_markers")
    assert result.exit_code == 0, result.output
    with h5py.File(tmp_path / "x.h5", "r") as f:
        assert f.attrs[S.ATTR_SENSOR_KIND] == "rgb_markers"


def test_profile_is_recorded_as_a_collected_run_records_it(tmp_path):
    from sensor_sim.profile import DEFAULT_PROFILE, load_profile, parse_record

    folder = write_folder(tmp_path)
    result = invoke("import", folder, "--out", tmp_path / "run.h5", "--profile", DEFAULT_PROFILE)
    assert result.exit_code == 0, result.output
    with h5py.File(tmp_path / "run.h5", "r") as f:
        record = str(f.attrs[S.ATTR_SENSOR_PROFILE])
    assert parse_record(record)["sha256"] == load_profile(DEFAULT_PROFILE).content_hash()
    bad = tmp_path / "bad.toml"
    bad.write_text("[sensor]\nname = 'x'\n")
    result = invoke("import", folder, "--out", tmp_path / "other.h5", "--profile", bad)
    assert result.exit_code == 1 and "bad.toml" in result.output and not (tmp_path / "other.h5").exists()


# -- messages ------------------------------------------------------------------------------------


def test_importing_again_names_the_remedy_import_has(tmp_path):
    folder = write_folder(tmp_path)
    assert invoke("import", folder, "--out", tmp_path / "run.h5").exit_code == 0
    result = invoke("import", folder, "--out", tmp_path / "run.h5")
    assert result.exit_code == 1 and "run.h5: exists; dataset import writes a new run file" in result.output
    assert "--resume" not in result.output and "choose another --out, or delete run.h5" in result.output
