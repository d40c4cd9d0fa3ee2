"""A sensor profile: what makes one tactile sensor, in one TOML file and a background PNG.

    profile = load_profile("my_sensor.toml")     # my_sensor.png beside it
    save_profile(profile, "copy.toml")           # sensor_sim/profile_save.py: copy.toml and copy.png
    default_profile()                            # the shipped GelSight Mini profile

It holds the frame size, the scale (mm per pixel), the gel (thickness, modulus), the
optics (``LightModel``: normal lookup tables, position and sink terms, blur, shading), the
marker layout for marker kinds and the camera's noise (``SensorNoise``). Every value is
checked on load: a missing key, a NaN or infinity, or a value out of range is a
``ProfileError`` naming the file and key.

Formats: ``[sensor] format = 5`` (written when the light has the sink table: ``[optics] sink_table_b``,
``_g``, ``_r``, per mm of sink at each normal); ``format = 4`` (written when the light has the quadratic
sink field: ``[optics] sink_bgr`` of SINK_FIELD_TERMS numbers per channel; without either, format 3);
``format = 3`` (written since the sink's terms are held at the deepest
calibration press: ``[optics] sink_max_mm``); ``format = 2`` (the position-dependent light:
position and sink terms, correlated noise in ``[noise]``; read with the sink never held); a
file without ``format`` is a profile of format 1 (one normal table, ``[sensor] noise_std`` of
independent noise at the frame's pixels), read as exactly what it says. Any other format is
refused in one line.

A run recorded with a profile stores ``profile.record()`` (name, content hash, file);
``profile_from_record`` finds the same profile again (by hash, never by name alone).
"""

from __future__ import annotations

import functools
import hashlib
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from sensor_sim.contact import SensorGeometry
from sensor_sim.elastomer import Elastomer
from sensor_sim.light import SHADINGS, SINK_FIELD_TERMS, LightModel, OpticsSpec
from sensor_sim.noise import SensorNoise

DEFAULT_PROFILE = Path(__file__).parent / "data" / "gelsight_mini.toml"
# Shipped profiles that runs may record besides the default: the default before the
# position-dependent light (format 1), so that runs simulated with it find it again.
SHIPPED_PROFILES = (DEFAULT_PROFILE, Path(__file__).parent / "data" / "gelsight_mini_format1.toml")
FORMATS = (1, 2, 3, 4, 5)


class ProfileError(ValueError):
    """A sensor profile file that cannot be used; the message names the file and key."""


@dataclass(frozen=True)
class SensorProfile:
    name: str
    source: str  # where the calibration frames came from, and their licence
    width_px: int
    height_px: int
    mm_per_px: float
    gel_thickness_mm: float
    gel_E_MPa: float
    noise: SensorNoise  # the camera's noise (format 1: independent, at the frame's pixels)
    light: LightModel
    background: np.ndarray  # BGR uint8 no-contact frame, the frame's aspect ratio, any resolution
    marker_pitch_mm: float = 0.7
    marker_radius_mm: float = 0.17
    marker_darkness: float = 0.8
    path: str = ""  # the TOML it was loaded from ("" when built in memory)
    format: int = 3  # the file format it was read from or will be written in

    @property
    def width_mm(self) -> float:
        return self.width_px * self.mm_per_px

    @property
    def height_mm(self) -> float:
        return self.height_px * self.mm_per_px

    def geometry(self, cells: int = 128) -> SensorGeometry:
        """The gel pad the camera sees; ``cells`` mechanics cells across its longer side."""
        return SensorGeometry(
            width_mm=self.width_px * self.mm_per_px, height_mm=self.height_px * self.mm_per_px, cells=cells
        )

    def gel(self) -> Elastomer:
        """The profile's gel (thickness, modulus; Poisson ratio and friction the simulator's defaults)."""
        return Elastomer(E_MPa=self.gel_E_MPa, thickness_mm=self.gel_thickness_mm)

    def content_hash(self) -> str:
        """sha256 (hex) of everything that changes a rendered frame or a wrench: name, sizes,
        gel, noise, markers, optics and background pixels. Copies of a file share it; the
        ``source`` text and the file's name or place do not enter."""
        h = hashlib.sha256()
        numbers = (
            self.width_px,
            self.height_px,
            self.mm_per_px,
            self.gel_thickness_mm,
            self.gel_E_MPa,
            self.noise.std_bgr[0],
            self.marker_pitch_mm,
            self.marker_radius_mm,
            self.marker_darkness,
            self.light.blur_mm,
            *self.light.reference_bgr,
        )
        h.update(f"{self.name}|{self.light.shading}|{'|'.join(repr(float(v)) for v in numbers)}".encode())
        h.update(np.ascontiguousarray(self.light.table_bgr, dtype=np.float32).tobytes())
        bg = np.ascontiguousarray(self.background, dtype=np.uint8)
        h.update(repr(bg.shape).encode() + bg.tobytes())
        if self.format >= 2:  # format 1's hash is what runs recorded before format 2: unchanged
            n, light = self.noise, self.light
            extra = (
                *n.std_bgr,
                n.correlation_px,
                *n.channel_correlation,
                light.position_scale_mm,
                *_finite_range(light.position_range),
            )
            h.update(f"|format 2|{'|'.join(repr(float(v)) for v in extra)}".encode())
            for part in (light.position_bgr, light.sink_bgr):
                h.update(b"-" if part is None else np.ascontiguousarray(part, dtype=np.float32).tobytes())
        if self.format >= 3:  # formats 1 and 2 hash as runs recorded them
            h.update(f"|format 3|{_finite_range([light.sink_max_mm])[0]!r}".encode())
        if self.format >= 4:  # formats 1 to 3 hash as runs recorded them
            h.update(b"|format 4|")
        if self.format >= 5:  # formats 1 to 4 hash as runs recorded them
            table = light.sink_table_bgr
            h.update(b"|format 5|" + (b"-" if table is None else np.ascontiguousarray(table, np.float32).tobytes()))
        return h.hexdigest()

    def record(self) -> str:
        """What a run file stores about the profile it was simulated with (TOML text)."""
        return f'name = {_toml_str(self.name)}\nsha256 = "{self.content_hash()}"\nfile = {_toml_str(self.path)}\n'

    def optics_spec(self, kind: str = "rgb") -> OpticsSpec:
        return OpticsSpec(
            kind=kind,
            height_px=self.height_px,
            width_px=self.width_px,
            noise_std=self.noise.std_bgr[0],
            noise=None if self.noise.independent else self.noise,
            marker_pitch_mm=self.marker_pitch_mm,
            marker_radius_mm=self.marker_radius_mm,
            marker_darkness=self.marker_darkness,
        )


# (section, key, low, high): the ranges a profile's numbers must lie in (both formats).
NUMBERS = (
    ("sensor", "width_px", 16, 4096),
    ("sensor", "height_px", 16, 4096),
    ("sensor", "mm_per_px", 1e-4, 1.0),
    ("gel", "thickness_mm", 0.05, 50.0),
    ("gel", "E_MPa", 1e-3, 1e3),
    ("optics", "blur_mm", 0.0, 5.0),
    ("markers", "pitch_mm", 0.05, 10.0),
    ("markers", "radius_mm", 0.0, 5.0),
    ("markers", "darkness", 0.0, 1.0),
)


def _get(path: Path, data: dict, section: str, key: str):
    if section not in data or not isinstance(data[section], dict):
        raise ProfileError(f"{path}: missing section [{section}]")
    if key not in data[section]:
        raise ProfileError(f"{path}: missing key [{section}] {key}")
    return data[section][key]


def _number(path: Path, data: dict, section: str, key: str, low: float, high: float) -> float:
    value = _get(path, data, section, key)
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or not low <= value <= high
    ):
        raise ProfileError(f"{path}: [{section}] {key} must be a finite number in [{low:g}, {high:g}], got {value!r}")
    return value


def _array(path: Path, data: dict, section: str, name: str, shape: tuple[int, ...], limit: float, what: str):
    value = _get(path, data, section, name)
    size = "×".join(str(n) for n in shape)
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ProfileError(f"{path}: [{section}] {name} must be a {size} array of numbers") from None
    if array.shape != shape:
        raise ProfileError(f"{path}: [{section}] {name} must be {size}{what}, got shape {array.shape}")
    if not np.all(np.isfinite(array)) or np.abs(array).max() > limit:
        raise ProfileError(f"{path}: [{section}] {name} entries must be finite and within ±{limit:g}")
    return array


def _table(path: Path, data: dict, name: str, bins: int) -> np.ndarray:
    return _array(path, data, "optics", name, (bins, bins), 255, " (table_bins)")


def _format(path: Path, data: dict) -> int:
    fmt = data.get("sensor", {}).get("format", 1) if isinstance(data.get("sensor"), dict) else 1
    if isinstance(fmt, bool) or fmt not in FORMATS:
        raise ProfileError(
            f"{path}: [sensor] format {fmt!r}: this version reads profile formats "
            f"{', '.join(str(f) for f in FORMATS)} (no format key: 1)"
        )
    return int(fmt)


def _noise(path: Path, data: dict, fmt: int) -> SensorNoise:
    if fmt == 1:
        std = _number(path, data, "sensor", "noise_std", 0.0, 50.0)
        return SensorNoise((float(std),) * 3, native=False)
    std = _array(path, data, "noise", "std_bgr", (3,), 50, " (grey levels, b g r)")
    if np.any(std < 0):
        raise ProfileError(f"{path}: [noise] std_bgr must be 3 numbers >= 0, got {std.tolist()}")
    corr_px = _number(path, data, "noise", "correlation_px", 0.0, 8.0)
    rho = _array(path, data, "noise", "channel_correlation", (3,), 0.99, " (b-g, b-r, g-r)")
    try:
        return SensorNoise(tuple(float(v) for v in std), float(corr_px), tuple(float(v) for v in rho))  # type: ignore[arg-type]
    except ValueError as exc:
        raise ProfileError(f"{path}: [noise] {exc}") from None


def _position_and_sink(path: Path, data: dict, fmt: int, bins: int) -> dict:
    """The light's position and sink terms (format 2, and the sink's hold from format 3; none in format 1)."""
    if fmt == 1:
        return {}
    order = _number(path, data, "optics", "position_order", 0, 1)
    if not float(order).is_integer():
        raise ProfileError(f"{path}: [optics] position_order must be 0 or 1, got {order!r}")
    scale = _number(path, data, "optics", "position_scale_mm", 1e-3, 1000.0)
    raw = data.get("optics", {}).get("sink_bgr") if isinstance(data.get("optics"), dict) else None
    wide = fmt >= 4 and isinstance(raw, list) and raw and isinstance(raw[0], list) and len(raw[0]) == SINK_FIELD_TERMS
    shape = (3, SINK_FIELD_TERMS) if wide else (3, 3)
    what = " (per channel b g r: the quadratic sink field)" if wide else " (per channel b g r: k, kx, ky)"
    sink = _array(path, data, "optics", "sink_bgr", shape, 1000, what)
    bounds = _array(path, data, "optics", "position_range", (4,), 1e6, " (x~ low, x~ high, y~ low, y~ high)")
    terms = {
        "sink_bgr": sink.astype(np.float32),
        "position_scale_mm": float(scale),
        "position_range": tuple(float(v) for v in bounds),
    }
    if fmt >= 3:
        terms["sink_max_mm"] = float(_number(path, data, "optics", "sink_max_mm", 1e-3, 1e6))
    if fmt >= 5:
        tables = [_array(path, data, "optics", f"sink_table_{c}", (bins, bins), 1000, " (table_bins)") for c in "bgr"]
        terms["sink_table_bgr"] = np.stack(tables).astype(np.float32)
    if order == 1:
        terms["position_bgr"] = np.stack(
            [np.stack([_table(path, data, f"position_{axis}_{c}", bins) for axis in "xy"]) for c in "bgr"]
        ).astype(np.float32)
    return terms


def load_profile(path: str | Path) -> SensorProfile:
    """Read and check a profile; raises ProfileError (one line: file, key, what was expected)."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except OSError as exc:
        raise ProfileError(f"{path}: cannot read the profile ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(f"{path}: not valid TOML ({exc})") from None
    fmt = _format(path, data)
    n = {f"{s}.{k}": _number(path, data, s, k, lo, hi) for s, k, lo, hi in NUMBERS}
    for s, k in (("sensor", "width_px"), ("sensor", "height_px")):
        if not float(n[f"{s}.{k}"]).is_integer():
            raise ProfileError(f"{path}: [{s}] {k} must be a whole number of pixels, got {n[f'{s}.{k}']!r}")
    shading = _get(path, data, "optics", "shading")
    if shading not in SHADINGS:
        raise ProfileError(f"{path}: [optics] shading must be one of {', '.join(SHADINGS)}, got {shading!r}")
    bins = _number(path, data, "optics", "table_bins", 3, 201)
    if not float(bins).is_integer() or bins % 2 == 0:
        raise ProfileError(
            f"{path}: [optics] table_bins must be an odd whole number (the flat normal in the middle), got {bins!r}"
        )
    table = np.stack([_table(path, data, f"table_{c}", int(bins)) for c in "bgr"])
    reference = _get(path, data, "optics", "reference_bgr")
    if (
        not isinstance(reference, list)
        or len(reference) != 3
        or not all(isinstance(v, (int, float)) and math.isfinite(v) and 0 < v <= 255 for v in reference)
    ):
        raise ProfileError(f"{path}: [optics] reference_bgr must be 3 finite numbers in (0, 255], got {reference!r}")
    bg_name = _get(path, data, "sensor", "background")
    bg_path = path.parent / str(bg_name)
    background = cv2.imread(str(bg_path), cv2.IMREAD_COLOR)
    if background is None:
        raise ProfileError(f"{path}: [sensor] background {bg_name!r}: no readable image at {bg_path}")
    aspect, bg_aspect = n["sensor.width_px"] / n["sensor.height_px"], background.shape[1] / background.shape[0]
    if abs(bg_aspect / aspect - 1) > 0.02:
        raise ProfileError(
            f"{path}: [sensor] background {bg_name!r} is {background.shape[1]}x{background.shape[0]}, "
            f"not the frame's aspect ratio {int(n['sensor.width_px'])}x{int(n['sensor.height_px'])}"
        )
    terms = _position_and_sink(path, data, fmt, int(bins))  # its ProfileError names the file once
    try:
        light = LightModel(
            table.astype(np.float32),
            float(n["optics.blur_mm"]),
            shading,
            (float(reference[0]), float(reference[1]), float(reference[2])),
            **terms,
        )
    except ValueError as exc:
        raise ProfileError(f"{path}: [optics] {exc}") from None
    noise = _noise(path, data, fmt)
    return SensorProfile(
        name=str(_get(path, data, "sensor", "name")),
        source=str(data["sensor"].get("source", "")),
        width_px=int(n["sensor.width_px"]),
        height_px=int(n["sensor.height_px"]),
        mm_per_px=float(n["sensor.mm_per_px"]),
        gel_thickness_mm=float(n["gel.thickness_mm"]),
        gel_E_MPa=float(n["gel.E_MPa"]),
        noise=noise,
        light=light,
        background=background,
        marker_pitch_mm=float(n["markers.pitch_mm"]),
        marker_radius_mm=float(n["markers.radius_mm"]),
        marker_darkness=float(n["markers.darkness"]),
        path=str(path.resolve()),
        format=fmt,
    )


@functools.lru_cache(maxsize=1)
def default_profile() -> SensorProfile:
    """The shipped GelSight Mini profile (fitted by bench/calibrate_optics.py)."""
    return load_profile(DEFAULT_PROFILE)


def resolve_profile(path: str | Path | None) -> SensorProfile:
    """The profile at ``path``, or the shipped default when None; ProfileError as load_profile."""
    return default_profile() if path is None else load_profile(path)


def parse_record(text: str, where: str = "run file") -> dict[str, str]:
    """{name, sha256, file} of a stored ``SensorProfile.record()``; ProfileError if malformed."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(f"{where}: the recorded sensor profile is not valid TOML ({exc})") from None
    missing = [k for k in ("name", "sha256", "file") if not isinstance(data.get(k), str)]
    if missing:
        raise ProfileError(f"{where}: the recorded sensor profile lacks {', '.join(missing)}")
    return {k: data[k] for k in ("name", "sha256", "file")}


def profile_from_record(text: str, where: str = "run file") -> SensorProfile:
    """The profile a run was recorded with: its recorded file, else the shipped default, whichever
    has the recorded content hash. ProfileError (naming name, hash and file) when neither has."""
    rec = parse_record(text, where)
    candidates = [rec["file"]] if rec["file"] else []
    candidates += [str(shipped) for shipped in SHIPPED_PROFILES]
    for candidate in candidates:
        if not Path(candidate).is_file():
            continue
        try:
            profile = default_profile() if Path(candidate) == DEFAULT_PROFILE else load_profile(candidate)
        except ProfileError:
            continue
        if profile.content_hash() == rec["sha256"]:
            return profile
    raise ProfileError(
        f"{where}: recorded with sensor profile {rec['name']!r} (sha256 {rec['sha256'][:12]}…, file "
        f"{rec['file'] or '?'}), which is not there or has changed since: pass --profile FILE"
    )


def _toml_str(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _finite_range(bounds) -> tuple[float, ...]:
    """TOML has no infinity a reader accepts here: an open range is written as ±1e6 (far beyond any frame)."""
    return tuple(max(-1e6, min(1e6, float(v))) for v in bounds)
