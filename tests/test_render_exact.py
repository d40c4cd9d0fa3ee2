"""The renderer's frames are bit for bit those of its plain formulation (with the colour
lookup's own gather), and within one grey level in a few pixels per million of it with
``cv2.remap`` doing the lookup (where this OpenCV interpolates exactly).

``sensor_sim/optics.py`` builds frames in (3, H, W) planes from per-renderer constants,
gathers the colour table's corners in one call, keeps the last press image and marker
shading, and adds the noise without ``np.roll``. Kept here, as the reference, is the
renderer as it was before that (commit 9c34a2e): the (H, W, 3) formulas, everything
recomputed per frame. For each sensor kind and a sequence of contact states (none, a
press, a sheared press, a twisted press, a deep press, states repeated, with and without
noise from a fixed seed, over the profile's background and over one bright and dark
enough to reach both knees of the soft bound) the two must give the same uint8 frames, for
the shipped profile of format 1 (one normal table, independent noise: what the reference knows).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.ndimage import map_coordinates

import sensor_sim.light as light_module
from common.sensors import SENSOR_KINDS
from objects.pose import Pose
from sensor_sim.light import CEIL, FLOOR, KNEE_HIGH, KNEE_LOW, remap_interpolates_exactly
from sensor_sim.optics import Renderer
from sensor_sim.profile import SHIPPED_PROFILES, load_profile
from sensor_sim.scene import Scene


def format1_profile():
    """The shipped profile as it was before the position-dependent light and the correlated noise
    (format 1): what the reference renderer below renders, and a profile of format 1 renders the same."""
    return load_profile(SHIPPED_PROFILES[1])


SEED = 11
STATES = (  # (x mm, y mm, z mm, twist deg): none, press, shear, twist, deep, repeats, none
    (0.0, 0.0, 0.5, 0.0),
    (0.0, 0.0, -0.6, 0.0),
    (0.0, 0.0, -0.6, 0.0),
    (0.6, -0.3, -0.6, 0.0),
    (0.6, -0.3, -0.6, 4.0),
    (0.0, 0.0, -1.4, 0.0),
    (0.6, -0.3, -0.6, 4.0),
    (0.0, 0.0, 0.5, 0.0),
)


# -- the reference: the renderer before the planar rewrite, copied ---------------------------
def _ref_soft_bound(img: np.ndarray) -> np.ndarray:
    out = img.copy()
    hi = img > KNEE_HIGH
    out[hi] = KNEE_HIGH + (CEIL - KNEE_HIGH) * np.tanh((img[hi] - KNEE_HIGH) / (CEIL - KNEE_HIGH))
    lo = img < KNEE_LOW
    out[lo] = KNEE_LOW - (KNEE_LOW - FLOOR) * np.tanh((KNEE_LOW - img[lo]) / (KNEE_LOW - FLOOR))
    return out


def _ref_corner_cells(gx: np.ndarray, gy: np.ndarray, bins: int):
    inv = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
    u = (1.0 - gx * inv) * (0.5 * (bins - 1))
    v = (1.0 - gy * inv) * (0.5 * (bins - 1))
    i0 = np.clip(np.floor(u).astype(np.int32), 0, bins - 2)
    j0 = np.clip(np.floor(v).astype(np.int32), 0, bins - 2)
    fu, fv = (u - i0).astype(np.float32), (v - j0).astype(np.float32)
    return j0 * bins + i0, [(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv]


def _ref_slopes(light, z_mm: np.ndarray, mm_per_px: float):
    z = z_mm.astype(np.float32)
    gy, gx = (np.asarray(g) for g in np.gradient(z, np.float32(mm_per_px)))
    blur_px = light.blur_mm / mm_per_px
    if blur_px > 0:
        gx = cv2.GaussianBlur(gx, (0, 0), blur_px)
        gy = cv2.GaussianBlur(gy, (0, 0), blur_px)
    return gx, gy


def _ref_change(light, gx: np.ndarray, gy: np.ndarray, background: np.ndarray) -> np.ndarray:
    bins = light.table_bgr.shape[1]
    k, w = _ref_corner_cells(gx, gy, bins)
    corners = [k, k + 1, k + bins, k + bins + 1]
    channels = []
    for table in light.table_bgr.reshape(3, -1):
        acc = np.take(table, corners[0])
        acc *= w[0]
        for index, weight in zip(corners[1:], w[1:]):
            corner = np.take(table, index)
            corner *= weight
            acc += corner
        channels.append(acc)
    delta = np.stack(channels, axis=-1)
    if light.shading == "multiplicative":
        delta *= background / np.asarray(light.reference_bgr, dtype=np.float32)
    return delta


class _ReferenceRenderer:
    """sensor_sim.optics.Renderer as of 9c34a2e (its light-model calls inlined above)."""

    def __init__(self, spec, geometry, background=None, seed=0, *, profile):
        self.spec, self.geometry, self.light = spec, geometry, profile.light
        h, w = spec.height_px, spec.width_px
        self.mm_per_px = geometry.width_mm / w
        if background is None and spec.kind != "white_markers":
            background = profile.background
        if background is not None:
            self.background = cv2.resize(background, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)
        else:
            yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
            r2 = ((xx - (w - 1) / 2) ** 2 + (yy - (h - 1) / 2) ** 2) / (0.5 * max(h, w)) ** 2
            grey = 200.0 * (1.0 - spec.vignetting * r2)
            self.background = np.repeat(grey[..., None], 3, axis=2)
        self.white_darkening = min(0.9, self.light.slope_gain() / 200.0)
        self._rng = np.random.default_rng(seed)
        self._noise = (
            self._rng.normal(0.0, spec.noise_std, (4, h, w, 3)).astype(np.float32) if spec.noise_std > 0 else None
        )
        pitch = spec.marker_pitch_mm
        n_x, n_y = int(geometry.width_mm / pitch), int(geometry.height_mm / pitch)
        mx = (np.arange(n_x) - (n_x - 1) / 2) * pitch
        my = (np.arange(n_y) - (n_y - 1) / 2) * pitch
        self.marker_rest_mm = np.stack(np.meshgrid(mx, my), axis=-1).reshape(-1, 2)

    def slope_change(self, uz_mm):
        up = cv2.resize(
            uz_mm.astype(np.float32), (self.spec.width_px, self.spec.height_px), interpolation=cv2.INTER_CUBIC
        )
        gx, gy = _ref_slopes(self.light, -up, self.mm_per_px)
        if self.spec.kind == "white_markers":
            tilt = np.sqrt(gx * gx + gy * gy) / np.sqrt(1.0 + gx * gx + gy * gy)
            return -self.white_darkening * tilt[..., None] * self.background
        return _ref_change(self.light, gx, gy, self.background)

    def marker_positions_px(self, ux_mm, uy_mm):
        h, w = self.spec.height_px, self.spec.width_px
        xy = self.marker_rest_mm.copy()
        if ux_mm is not None and (np.any(ux_mm) or np.any(uy_mm)):
            ny, nx = ux_mm.shape
            dx = self.geometry.dx_mm
            coords = np.stack([(ny - 1) / 2 - xy[:, 1] / dx, xy[:, 0] / dx + (nx - 1) / 2])
            xy[:, 0] += map_coordinates(ux_mm, coords, order=1, mode="nearest")
            xy[:, 1] += map_coordinates(uy_mm, coords, order=1, mode="nearest")
        return np.stack([xy[:, 0] / self.mm_per_px + (w - 1) / 2, (h - 1) / 2 - xy[:, 1] / self.mm_per_px], axis=-1)

    def marker_mask(self, centres_px):
        h, w = self.spec.height_px, self.spec.width_px
        shift = 4
        mask = np.zeros((h, w), np.float32)
        radius = int(round(self.spec.marker_radius_mm / self.mm_per_px * (1 << shift)))
        for c, r in centres_px:
            cv2.circle(
                mask, (int(round(c * (1 << shift))), int(round(r * (1 << shift)))), radius, 1.0, -1, cv2.LINE_AA, shift
            )
        return cv2.GaussianBlur(mask, (0, 0), 0.6)

    def render(self, fields):
        img = self.background.copy()
        uz = fields.get("uz")
        if uz is not None and np.any(uz):
            img += self.slope_change(uz)
        if self.spec.has_markers:
            centres = self.marker_positions_px(fields.get("ux"), fields.get("uy"))
            img *= 1.0 - self.spec.marker_darkness * self.marker_mask(centres)[..., None]
        if self._noise is not None:
            k = int(self._rng.integers(len(self._noise)))
            dy, dx = (int(v) for v in self._rng.integers(0, img.shape[:2]))
            img += np.roll(self._noise[k], (dy, dx), axis=(0, 1))
        return np.rint(_ref_soft_bound(img)).astype(np.uint8)


# -- the comparison ---------------------------------------------------------------------------
@pytest.fixture
def gather(monkeypatch):
    """The colour lookup through its own gather (bit for bit the reference)."""
    monkeypatch.setattr(light_module, "remap_interpolates_exactly", lambda: False)


@pytest.fixture(scope="module")
def fields_by_kind() -> dict[str, list[dict[str, np.ndarray]]]:
    """The mechanics fields of STATES, solved once per kind (the markers need uxy)."""
    out = {}
    for kind in SENSOR_KINDS:
        scene = Scene("sphere10mm", kind)
        needs = scene.renderer.needs()
        out[kind] = [dict(scene.contact.solve(Pose(*state), needs).fields) for state in STATES]
    return out


def _bright_and_dark(shape=(240, 320)) -> np.ndarray:
    """A background with a saturated-bright band and a near-black band (both knees)."""
    bg = np.full((*shape, 3), 120, np.uint8)
    bg[:, : shape[1] // 3] = (250, 245, 240)
    bg[:, -shape[1] // 3 :] = (12, 9, 6)
    return bg


@pytest.mark.parametrize("kind", SENSOR_KINDS)
@pytest.mark.parametrize("noise", [True, False], ids=["noise", "no-noise"])
@pytest.mark.parametrize("background", ["profile", "bright-dark"])
def test_frames_equal_the_reference_bit_for_bit(gather, fields_by_kind, kind, noise, background):
    profile = format1_profile()
    spec = profile.optics_spec(kind)
    geometry = Scene("sphere10mm", kind).geometry
    bg = _bright_and_dark() if background == "bright-dark" else None
    new = Renderer(spec, geometry, bg, SEED, profile=profile)
    ref = _ReferenceRenderer(spec, geometry, bg, SEED, profile=profile)
    if not noise:
        new._noise = ref._noise = None
    frames = []
    for state, fields in zip(STATES, fields_by_kind[kind]):
        got, want = new.render(fields), ref.render(fields)
        assert got.dtype == np.uint8 and got.shape == want.shape == (spec.height_px, spec.width_px, 3)
        assert got.flags.c_contiguous
        diff = np.abs(got.astype(int) - want.astype(int))
        assert np.array_equal(got, want), f"{kind} at {state}: {int((diff > 0).sum())} pixels differ, max {diff.max()}"
        frames.append(got)
    # The sequence is not trivial: contact changes the frame, the shear moves it again.
    assert not np.array_equal(frames[0], frames[1]) and not np.array_equal(frames[1], frames[3])
    if background == "bright-dark":  # both knees of the soft bound were reached
        assert frames[5].max() > KNEE_HIGH and frames[5].min() < KNEE_LOW


def test_renderer_state_follows_the_noise_switch(gather, fields_by_kind):
    """Tests and benches turn the noise off with ``renderer._noise = None``; turning it back
    on with a bank gives that bank's noise."""
    profile = format1_profile()
    spec = profile.optics_spec("rgb")
    geometry = Scene("sphere10mm", "rgb").geometry
    new = Renderer(spec, geometry, None, SEED, profile=profile)
    ref = _ReferenceRenderer(spec, geometry, None, SEED, profile=profile)
    bank = ref._noise
    assert bank is not None
    new._noise = ref._noise = None
    press = fields_by_kind["rgb"][1]
    assert np.array_equal(new.render(press), ref.render(press))
    new._noise = ref._noise = (2.0 * bank).astype(np.float32)
    assert np.array_equal(new.render(press), ref.render(press))


def test_slope_change_and_marker_mask_equal_the_reference(gather, fields_by_kind):
    """The public pieces (the colour change, the marker coverage) are unchanged too."""
    profile = format1_profile()
    for kind in SENSOR_KINDS:
        spec = profile.optics_spec(kind)
        geometry = Scene("sphere10mm", kind).geometry
        new = Renderer(spec, geometry, None, SEED, profile=profile)
        ref = _ReferenceRenderer(spec, geometry, None, SEED, profile=profile)
        fields = fields_by_kind[kind][4]
        assert np.array_equal(new.slope_change(fields["uz"]), ref.slope_change(fields["uz"]))
        if spec.has_markers:
            centres = ref.marker_positions_px(fields["ux"], fields["uy"])
            assert np.array_equal(new.marker_positions_px(fields["ux"], fields["uy"]), centres)
            assert np.array_equal(new._marker_mask(centres), ref.marker_mask(centres))


@pytest.mark.parametrize("kind", ["rgb", "rgb_markers"])
def test_remap_lookup_frames_within_one_grey_level_of_the_reference(fields_by_kind, kind):
    """The default path (``cv2.remap`` where it interpolates exactly): every state's frame
    within 1 grey level of the reference, in at most 1 pixel value in 10,000."""
    if not remap_interpolates_exactly():
        pytest.skip("this OpenCV rounds remap's fraction: the renderer keeps the gather (tested above)")
    profile = format1_profile()
    spec = profile.optics_spec(kind)
    geometry = Scene("sphere10mm", kind).geometry
    bg = _bright_and_dark()
    new = Renderer(spec, geometry, bg, SEED, profile=profile)
    ref = _ReferenceRenderer(spec, geometry, bg, SEED, profile=profile)
    differing = total = 0
    for fields in fields_by_kind[kind]:
        got, want = new.render(fields), ref.render(fields)
        diff = np.abs(got.astype(int) - want.astype(int))
        assert diff.max() <= 1
        differing, total = differing + int((diff > 0).sum()), total + diff.size
    assert differing <= total // 10_000, f"{differing} of {total} values differ"


def test_a_rounding_remap_is_not_used(monkeypatch, fields_by_kind):
    """An OpenCV whose remap rounds the fraction to 1/32 of a cell (as 4.x does) fails the
    check, and the lookup keeps the gather: the frames stay the reference's, bit for bit."""
    real_remap = cv2.remap

    def rounding_remap(src, map_x, map_y, interpolation, **kw):
        return real_remap(src, np.round(map_x * 32) / 32, np.round(map_y * 32) / 32, interpolation, **kw)

    monkeypatch.setattr(cv2, "remap", rounding_remap)
    remap_interpolates_exactly.cache_clear()
    try:
        assert not light_module.remap_interpolates_exactly()
        profile = format1_profile()
        spec = profile.optics_spec("rgb")
        geometry = Scene("sphere10mm", "rgb").geometry
        new = Renderer(spec, geometry, None, SEED, profile=profile)
        ref = _ReferenceRenderer(spec, geometry, None, SEED, profile=profile)
        for fields in fields_by_kind["rgb"]:
            assert np.array_equal(new.render(fields), ref.render(fields))
    finally:
        remap_interpolates_exactly.cache_clear()


def test_slopes_the_remap_cannot_take_use_the_gather():
    """cv2.remap takes 2-D maps under 32,767 px a side: other slopes get the gather's numbers."""
    light = format1_profile().light
    rng = np.random.default_rng(3)
    for shape in ((2, 3, 4), (7,), (40_000, 1)):
        gx, gy = (rng.normal(0, 0.4, shape).astype(np.float32) for _ in range(2))
        got = light.change_planar(gx, gy)
        assert got.shape == (3, *shape)
        assert np.array_equal(got, light.change_planar(gx, gy, exact=True))
