"""A lab's own objects (docs/protocols.md, "Your own objects"): an object file naming a photo
and a height map, pressed on the simulated rig, refused there without a height map, checked
by ``rig object check``, and its mistakes refused in one line naming file, key and value."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from acquisition import schema as S
from acquisition.run_file import open_for_reading
from common.errors import ConfigError
from objects.indenters import FAR_MM
from objects.object_file import NoHeightMap, PhotoIndenter, load_object, load_object_file
from protocols.plan import Plan
from protocols.spec import load_protocol

runner = CliRunner()


def rig(*args: str):
    """``rig ARGS`` in-process, as a user types it."""
    from cli.rig_app import app

    return runner.invoke(app, list(args))


MM_PER_PX = 0.05
PHOTO_WH = (300, 260)  # not square: scale and axis are given
AXIS_PX = (140.0, 120.0)  # off the photo's middle on purpose
BACKGROUND_BGR = (180, 190, 200)
STAR_BGR = (40, 120, 230)
FIELD_MM_PER_PX = 14.0 / 256


def star_mask(shape_hw, axis_px, mm_per_px, outer_mm=4.0, inner_mm=1.8) -> np.ndarray:
    """A five-pointed star about ``axis_px``, one point straight up (+v, toward row 0)."""
    angles = np.pi / 2 + np.arange(10) * np.pi / 5
    radii = np.where(np.arange(10) % 2 == 0, outer_mm, inner_mm) / mm_per_px
    points = np.stack([axis_px[0] + radii * np.cos(angles), axis_px[1] - radii * np.sin(angles)], axis=1)
    mask = np.zeros(shape_hw, np.uint8)
    cv2.fillPoly(mask, [np.round(points * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
    return mask.astype(bool)


def write_object(folder: Path, *, height_map: bool = True, extra: str = "", photo_name: str = "star.jpg") -> Path:
    """A drawn star photographed at 0.05 mm/px and its height map (a 16-bit PNG, 1 µm per
    grey level: a flat face 1.0 mm high with a 0.1 mm dome); returns the object file."""
    w, h = PHOTO_WH
    photo = np.empty((h, w, 3), np.uint8)
    photo[:] = BACKGROUND_BGR
    star = star_mask((h, w), AXIS_PX, MM_PER_PX)
    photo[star] = STAR_BGR
    cv2.imwrite(str(folder / photo_name), photo, [cv2.IMWRITE_JPEG_QUALITY, 95])
    text = f'[object]\nname = "star"\ndescription = "printed star, 8 mm"\n\n[photo]\nfile = "{photo_name}"\n'
    text += f"mm_per_px = {MM_PER_PX}\ncentre_px = [{AXIS_PX[0]}, {AXIS_PX[1]}]\n"
    if height_map:
        rows, cols = np.mgrid[0:h, 0:w]
        r_mm = np.hypot(cols - AXIS_PX[0], rows - AXIS_PX[1]) * MM_PER_PX
        counts = np.where(star, 1000 + np.clip(100 * (1 - r_mm / 2), 0, None), 0).astype(np.uint16)
        cv2.imwrite(str(folder / "star_height.png"), counts)
        text += '\n[height_map]\nfile = "star_height.png"\n'
        text += f"mm_per_px = {MM_PER_PX}\ncentre_px = [{AXIS_PX[0]}, {AXIS_PX[1]}]\nmm_per_count = 0.001\n"
    path = folder / "star.toml"
    path.write_text(text + extra)
    return path


def short_protocol(folder: Path, object_ref: str) -> Path:
    text = (
        load_protocol("sphere10mm")
        .text.replace('name = "sphere10mm"', 'name = "star-quick"')
        .replace('object = "sphere10mm"', f'object = "{object_ref}"')
        .replace("max_depth_mm = 1.6", "max_depth_mm = 0.3")
        .replace("depth_step_mm = 0.4", "depth_step_mm = 0.3")
        .replace("shear_mm = 2.0", "shear_mm = 0.2")
        .replace("twist_deg = 5.0", "twist_deg = 0.0")
        .replace("speed_mm_s = 0.01", "speed_mm_s = 0.1")
    )
    path = folder / "star-quick.toml"
    path.write_text(text)
    return path


def test_star_object_image_is_the_photo_at_the_sensor_scale(tmp_path):
    obj = load_object_file(write_object(tmp_path))
    assert obj.name == "star" and obj.has_geometry
    assert obj.photo_sha256 == hashlib.sha256((tmp_path / "star.jpg").read_bytes()).hexdigest()
    image = obj.object_image(256, FIELD_MM_PER_PX)
    assert image.shape == (256, 256, 3) and image.dtype == np.uint8
    # the star is centred on the axis, at the sensor's scale: its top point 4 mm above the middle
    is_star = np.abs(image.astype(int) - STAR_BGR).sum(axis=2) < 60
    want = star_mask((256, 256), (127.5, 127.5), FIELD_MM_PER_PX)
    assert (is_star ^ want).sum() < 0.08 * want.sum()
    # beyond the photo (it spans 15 x 13 mm around an off-centre axis) its own border colour, not black
    assert np.abs(image[0, 0].astype(int) - BACKGROUND_BGR).max() <= 3
    assert np.abs(image[-1, -1].astype(int) - BACKGROUND_BGR).max() <= 3
    # the height map agrees with the photo: material exactly where the star is, the dome on top
    assert isinstance(load_object(str(tmp_path / "star.toml")), PhotoIndenter)
    indenter = obj.indenter()  # what load_object returns for a file with a height map
    assert indenter.name == "star"
    coords = (np.arange(256) - 127.5) * FIELD_MM_PER_PX
    U, V = np.meshgrid(coords, -coords)
    sep = indenter.separation(U, V)
    assert ((sep < FAR_MM / 2) ^ want).sum() < 0.08 * want.sum()
    assert indenter.separation(np.array(0.0), np.array(0.0)) == pytest.approx(0.0, abs=0.002)
    assert indenter.separation(np.array(0.0), np.array(3.0)) == pytest.approx(0.1, abs=0.01)  # off the dome
    assert 3.9 < indenter.radius_mm < 4.2
    np.testing.assert_array_equal(indenter.object_image(256, FIELD_MM_PER_PX), image)


def test_star_run_on_the_simulated_rig_stores_the_object_file(tmp_path):
    object_file = write_object(tmp_path)
    proto_path = short_protocol(tmp_path, "star.toml")  # relative to the protocol file
    protocol = load_protocol(proto_path)
    assert protocol.object == str(object_file.absolute())
    out = tmp_path / "star.h5"
    result = rig("run-protocol", str(proto_path), "--sim", "--out", str(out))
    assert result.exit_code == 0, result.output
    plan = Plan.of(protocol)
    obj = load_object_file(object_file)
    with open_for_reading(out) as f:
        assert f[S.STATUS][()] == b"complete" and f[S.FRAMES].shape[0] == plan.frame_count
        assert f.attrs[S.ATTR_OBJECT] == "star" and f.attrs[S.ATTR_OBJECT_GEOMETRY] == "printed star, 8 mm"
        assert f.attrs[S.ATTR_OBJECT_FILE] == object_file.read_text()
        assert f.attrs[S.ATTR_OBJECT_PHOTO_SHA256] == obj.photo_sha256
        mm_per_px = float(f.attrs[S.ATTR_MM_PER_PX])
        # the condition's source is the photo at the frame's scale
        np.testing.assert_array_equal(f[S.OBJECT_IMAGE][()], obj.object_image(f[S.FRAMES].shape[2], mm_per_px))
        wrench, pose = f[S.WRENCH][:], f[S.POSE_COMMANDED][:]
        deepest = int(np.argmin(pose[:, 2]))
        assert pose[deepest, 2] == pytest.approx(-0.3) and wrench[deepest, 2] > 0.5  # the star was pressed
        frames = f[S.FRAMES]
        moved = np.abs(frames[deepest].astype(int) - f[S.REFERENCE_FRAME][()].astype(int)).sum(axis=2) > 30
        # the gel moves where the star is (within 1 mm of it), the right way up: an upside-down
        # star (a mirrored height map) holds far fewer of the moved pixels
        star = star_mask(moved.shape, ((moved.shape[1] - 1) / 2, (moved.shape[0] - 1) / 2), mm_per_px)
        k = 2 * round(1.0 / mm_per_px) + 1
        near = cv2.dilate(star.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))) > 0
        assert moved[~near].mean() < 0.05 and moved[near].sum() > 0.9 * moved.sum()
        assert moved[np.flipud(near)].sum() < 0.8 * moved.sum()
    from dataset.condition import condition_image

    image = obj.object_image(256, mm_per_px)
    x_mm, y_mm = 0.0, 4 * mm_per_px  # the condition at a sheared pose: the photo moved up with the object
    placed = condition_image(image, x_mm, y_mm, 0.0, mm_per_px, 256, 256)
    shift_px = round(y_mm / mm_per_px)
    np.testing.assert_array_equal(placed[40 : 256 - 40, 40:-40], image[40 + shift_px : 256 - 40 + shift_px, 40:-40])


def test_without_a_height_map_the_simulated_rig_refuses_in_one_line(tmp_path):
    write_object(tmp_path, height_map=False)
    proto_path = short_protocol(tmp_path, "star.toml")
    assert not load_object(str(tmp_path / "star.toml")).has_geometry
    out = tmp_path / "never.h5"
    result = rig("run-protocol", str(proto_path), "--sim", "--out", str(out))
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "object 'star' has no height map" in lines[0]
    assert "the simulated rig cannot press it; the real rig can" in lines[0] and "star.toml" in lines[0]
    assert not out.exists() and not list(tmp_path.glob("never.h5*"))  # nothing opened, nothing written
    with pytest.raises(NoHeightMap):
        load_object_file(tmp_path / "star.toml").indenter()


def test_without_a_height_map_the_hardware_path_still_builds_its_object_image(tmp_path):
    """The real rig's run never needs the geometry: the executor's object comes from the photo."""
    obj = load_object(str(write_object(tmp_path, height_map=False)))
    image = obj.object_image(256, FIELD_MM_PER_PX)
    assert image.shape == (256, 256, 3) and obj.description == "printed star, 8 mm"


def test_check_command_writes_the_sheet_and_prints_sizes_in_mm(tmp_path):
    object_file = write_object(tmp_path)
    sheet = tmp_path / "sheet.png"
    result = rig("object", "check", str(object_file), "--out", str(sheet))
    assert result.exit_code == 0, result.output
    assert "photo: 300x260 px at 0.05 mm/px = 15.00 x 13.00 mm" in result.output
    assert "height map: 300x260 px at 0.05 mm/px = 15.00 x 13.00 mm" in result.output
    assert "relief 0.100 mm" in result.output and "14.00 mm (the sensor's field)" in result.output
    image = cv2.imread(str(sheet))
    assert image is not None and image.shape == (256 + 22, 3 * 256 + 8, 3)
    photo_panel, height_panel = image[22:, :256], image[22:, 260:516]
    want = star_mask((256, 256), (127.5, 127.5), FIELD_MM_PER_PX)
    lit = height_panel.max(axis=2) > 0
    lit[120:136, 120:136] = want[120:136, 120:136]  # the axis marker
    assert (lit ^ want).sum() < 0.08 * want.sum()  # the height map's star where the photo's is
    is_star = np.abs(photo_panel.astype(int) - STAR_BGR).sum(axis=2) < 60
    assert (is_star ^ want).sum() < 0.1 * want.sum()
    # without a height map: the sheet says so, the command still passes (the real rig runs it)
    write_object(tmp_path, height_map=False)
    result = rig("object", "check", str(object_file))
    assert result.exit_code == 0 and "height map: none" in result.output


@pytest.mark.parametrize(
    "edit, key, words",
    [
        (("mm_per_px = 0.05\ncentre", "mm_per_px = nan\ncentre"), "photo.mm_per_px", "finite"),
        (("mm_per_px = 0.05\ncentre", "mm_per_px = -0.05\ncentre"), "photo.mm_per_px", "-0.05"),
        (
            ("centre_px = [140.0, 120.0]\n\n", "centre_px = [140.0, 260.0]\n\n"),
            "photo.centre_px",
            "outside the 300x260",
        ),
        (('file = "star.jpg"', 'file = "missing.png"'), "photo.file", "'missing.png': no such file"),
        (('file = "star.jpg"', 'file = "star.gif"'), "photo.file", ".png or .jpg or .jpeg"),
        (('file = "star_height.png"', 'file = "star.jpg"'), "height_map.file", ".png or .npy"),
        (("mm_per_count = 0.001", "mm_per_count = 0"), "height_map.mm_per_count", "> 0"),
        (("mm_per_count = 0.001", "mm_per_count = 0.001\nscale = 2"), "height_map.scale", "unknown key"),
        (('name = "star"', 'name = ""'), "object.name", "must be a name"),
    ],
)
def test_mistakes_are_one_line_naming_file_key_and_value(tmp_path, edit, key, words):
    path = write_object(tmp_path)
    path.write_text(path.read_text().replace(edit[0], edit[1], 1))
    with pytest.raises(ConfigError) as caught:
        load_object_file(path)
    message = str(caught.value)
    assert caught.value.key == key and words in message and str(path) in message and "\n" not in message
    # the protocol naming it fails at load, with the same line
    proto = short_protocol(tmp_path, "star.toml")
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        load_protocol(proto)


def test_height_map_npy_and_its_own_checks(tmp_path):
    write_object(tmp_path)
    heights = np.full((40, 40), np.nan)
    heights[10:30, 10:30] = 0.5
    np.save(tmp_path / "block.npy", heights)
    text = (tmp_path / "star.toml").read_text()
    text = text.split("[height_map]")[0] + (
        '[height_map]\nfile = "block.npy"\nmm_per_px = 0.1\ncentre_px = [19.5, 19.5]\n'
    )
    (tmp_path / "star.toml").write_text(text)
    indenter = load_object_file(tmp_path / "star.toml").indenter()
    assert indenter.separation(np.array(0.0), np.array(0.0)) == 0.0
    assert indenter.separation(np.array(1.5), np.array(0.0)) == FAR_MM  # 1 mm half-side
    assert indenter.radius_mm == pytest.approx(math.hypot(10, 10) * 0.1 + 0.1, abs=0.1)
    (tmp_path / "star.toml").write_text(text + "mm_per_count = 0.001\n")
    with pytest.raises(ConfigError, match=r"height_map\.mm_per_count.*only for a 16-bit PNG"):
        load_object_file(tmp_path / "star.toml")
    np.save(tmp_path / "block.npy", np.full((40, 40), np.nan))
    (tmp_path / "star.toml").write_text(text)
    with pytest.raises(ConfigError, match="has no material"):
        load_object_file(tmp_path / "star.toml")


def test_protocol_object_file_missing_or_unknown_name(tmp_path):
    proto = short_protocol(tmp_path, "nowhere.toml")
    with pytest.raises(ConfigError, match=r"protocol\.object.*'nowhere\.toml' not found"):
        load_protocol(proto)
    proto.write_text(proto.read_text().replace('object = "nowhere.toml"', 'object = "teapot"'))
    with pytest.raises(ConfigError, match=r"protocol\.object.*or an object file \(\.toml\), got 'teapot'"):
        load_protocol(proto)
    # an absolute path works too, from anywhere
    elsewhere = tmp_path / "objects"
    elsewhere.mkdir()
    absolute = write_object(elsewhere).resolve()
    proto.write_text(proto.read_text().replace('object = "teapot"', f'object = "{absolute}"'))
    assert load_protocol(proto).object == str(absolute)


@pytest.mark.parametrize(
    "tallest, words",
    [(1e30, r"a height of 1e\+30 mm; expected heights in mm within ±1000 mm"), (60.0, r"relief 59.5 mm; a contact")],
)
def test_absurd_heights_are_refused_in_one_line(tmp_path, tallest, words):
    """A height map of 1e30 mm (a unit slip) or a relief taller than any gel is not a contact face."""
    write_object(tmp_path)
    heights = np.full((40, 40), np.nan)
    heights[10:30, 10:30] = 0.5
    heights[15, 15] = tallest
    np.save(tmp_path / "block.npy", heights)
    text = (tmp_path / "star.toml").read_text().split("[height_map]")[0]
    text += '[height_map]\nfile = "block.npy"\nmm_per_px = 0.1\ncentre_px = [19.5, 19.5]\n'
    (tmp_path / "star.toml").write_text(text)
    with pytest.raises(ConfigError, match=words):
        load_object_file(tmp_path / "star.toml")
    result = rig("object", "check", str(tmp_path / "star.toml"))
    assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1, result.output


def test_a_relief_as_tall_as_the_simulated_gel_is_refused_by_the_simulated_rig(tmp_path):
    from rig.sim.rig_sim import SimulatedRig

    write_object(tmp_path)
    heights = np.full((40, 40), np.nan)
    heights[10:30, 10:30] = 0.0
    heights[19, 19] = 3.5  # a 3.5 mm spike on a 3 mm gel
    np.save(tmp_path / "block.npy", heights)
    text = (tmp_path / "star.toml").read_text().split("[height_map]")[0]
    text += '[height_map]\nfile = "block.npy"\nmm_per_px = 0.1\ncentre_px = [19.5, 19.5]\n'
    (tmp_path / "star.toml").write_text(text)
    with pytest.raises(ConfigError, match="press through the gel"):
        SimulatedRig(indenter=str(tmp_path / "star.toml"))
