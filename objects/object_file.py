"""A lab's own object: a TOML file naming a photo of its contact face and, optionally, a height map.

The photo is the model's condition (the paper's condition is a real photo of the object);
the height map lets the simulated rig press the object too. Without one the object still
runs on the real rig, which never needs its geometry. Format and conventions:
docs/protocols.md, "Your own objects"::

    [object]
    name = "star"                     # optional: the file's stem
    description = "printed star"      # optional
    [photo]                           # the contact face as a camera facing it sees it
    file = "star.png"                 # PNG or JPEG, relative to this file
    mm_per_px = 0.05
    centre_px = [120.0, 118.5]        # x (column), y (row) of the object's axis
    [height_map]                      # optional: without it the simulated rig refuses the object
    file = "star_height.png"          # 16-bit grey PNG (0: no material) or .npy of mm (NaN: none)
    mm_per_px = 0.05
    centre_px = [120.0, 118.5]
    mm_per_count = 0.001              # 16-bit PNG only: height of one grey level
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from common.errors import ConfigError, ToolError
from common.table import Table, toml_table
from objects.indenters import FAR_MM, Indenter

PHOTO_SUFFIXES = (".png", ".jpg", ".jpeg")
HEIGHT_SUFFIXES = (".png", ".npy")
# 0.1 µm to 1 mm per pixel: a microscope to a phone camera at arm's length
MM_PER_PX_LOW, MM_PER_PX_HIGH = 1e-4, 1.0
MAX_SIDE_PX = 16384  # a larger image is a mistake (or a 1 GB array), not a photo of a contact face
MAX_MM_PER_COUNT = 1.0  # one grey level of a 16-bit map at 1 mm spans 65 m: surely a unit slip
MAX_HEIGHT_MM = 1000.0  # a height beyond 1 m is a unit slip (µm or counts written as mm), not a contact face
# The relief that touches a gel: no gel a rig config accepts is thicker (rig/config, gel_thickness_mm
# <= 50 mm), and a face whose relief reaches the gel's thickness would press its tallest part through
# it; a rig that knows its gel refuses a relief at or beyond that too (rig/sim/rig_sim.py).
MAX_RELIEF_MM = 50.0


class NoHeightMap(ToolError):
    """The object file has no height map, so the simulated rig cannot press the object."""


def is_object_file(name: str) -> bool:
    """A protocol's ``object`` names an object file (not a library object) when it ends in .toml."""
    return name.lower().endswith(".toml")


def _image_file(table: Table, base: Path, suffixes: tuple[str, ...]) -> Path:
    raw = table.get("file", str)
    path = Path(raw) if Path(raw).is_absolute() else base / raw
    if path.suffix.lower() not in suffixes:
        raise table.error("file", f"must be a {' or '.join(suffixes)} file, got {raw!r}")
    if not path.is_file():
        raise table.error("file", f"{raw!r}: no such file ({path})")
    return path


def _centre(table: Table, shape: tuple[int, ...]) -> tuple[float, float]:
    cx, cy = table.vector("centre_px", 2)
    h, w = shape[:2]
    if not (0 <= cx <= w - 1 and 0 <= cy <= h - 1):
        raise table.error(
            "centre_px",
            f"[{cx:g}, {cy:g}] is outside the {w}x{h} px image (x in [0, {w - 1}], y in [0, {h - 1}])",
        )
    return cx, cy


def _check_size(table: Table, image: np.ndarray) -> None:
    if min(image.shape[:2]) < 2 or max(image.shape[:2]) > MAX_SIDE_PX:
        raise table.error("file", f"is {image.shape[1]}x{image.shape[0]} px; expected 2 to {MAX_SIDE_PX} px a side")


@dataclass(frozen=True)
class HeightMap:
    """Heights of the contact face toward the sensor (mm), NaN where there is no material."""

    height_mm: np.ndarray = field(repr=False)  # (H, W) float64
    mm_per_px: float
    centre_px: tuple[float, float]  # x (column), y (row) of the object's axis

    @property
    def relief_mm(self) -> float:
        return float(np.nanmax(self.height_mm) - np.nanmin(self.height_mm))

    @property
    def radius_mm(self) -> float:
        """Distance from the axis to the farthest material pixel (bounding radius of the face)."""
        rows, cols = np.nonzero(np.isfinite(self.height_mm))
        cx, cy = self.centre_px
        return float(np.hypot(cols - cx, rows - cy).max() + 1.0) * self.mm_per_px

    def separation(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Height above the face's lowest point (its highest height) at (u, v) mm; FAR_MM off the face."""
        from scipy.ndimage import map_coordinates

        raster = self._separation_raster()
        u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
        cx, cy = self.centre_px
        coords = np.stack([cy - v / self.mm_per_px, cx + u / self.mm_per_px])  # rows run down, v up
        out = map_coordinates(raster, coords.reshape(2, -1), order=1, mode="constant", cval=FAR_MM)
        return out.reshape(u.shape)

    def _separation_raster(self) -> np.ndarray:
        cached = self.__dict__.get("_raster")
        if cached is None:
            top = float(np.nanmax(self.height_mm))
            cached = np.where(np.isfinite(self.height_mm), top - self.height_mm, FAR_MM)
            object.__setattr__(self, "_raster", cached)
        return cached


@dataclass(frozen=True)
class ObjectFile:
    path: str
    text: str  # the file as written: stored in every run file of the object
    name: str
    description: str
    photo_bgr: np.ndarray = field(repr=False)  # (H, W, 3) uint8
    photo_mm_per_px: float
    photo_centre_px: tuple[float, float]  # x (column), y (row) of the object's axis
    photo_sha256: str  # of the photo file's bytes: which photo a run file's condition came from
    height_map: HeightMap | None = field(default=None, repr=False)

    @property
    def has_geometry(self) -> bool:
        return self.height_map is not None

    @property
    def border_bgr(self) -> tuple[float, float, float]:
        """The photo's own background: the median colour of its outermost pixels."""
        p = self.photo_bgr
        ring = np.concatenate([p[0], p[-1], p[:, 0], p[:, -1]]).reshape(-1, 3)
        b, g, r = np.median(ring, axis=0)
        return float(b), float(g), float(r)

    def object_image(self, size_px: int = 256, mm_per_px: float = 0.0625) -> np.ndarray:
        """BGR uint8 (size_px, size_px, 3): the photo at ``mm_per_px``, its centre in the middle
        (as library object images), beyond the photo its own border colour."""
        scale = self.photo_mm_per_px / mm_per_px  # output pixels per photo pixel
        photo = self.photo_bgr
        if scale < 1:  # shrinking: blur first so thin features do not alias away
            photo = cv2.GaussianBlur(photo, (0, 0), sigmaX=0.5 / scale)
        half = (size_px - 1) / 2
        cx, cy = self.photo_centre_px
        M = np.array([[scale, 0.0, half - scale * cx], [0.0, scale, half - scale * cy]])
        return cv2.warpAffine(
            photo,
            M,
            (size_px, size_px),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=self.border_bgr,
        )

    def indenter(self) -> "PhotoIndenter":
        """The object as the simulator presses it; NoHeightMap when the file has none."""
        if self.height_map is None:
            raise NoHeightMap(
                f"{self.path}: object {self.name!r} has no height map ([height_map] table): "
                "the simulated rig cannot press it; the real rig can"
            )
        hm = self.height_map
        return PhotoIndenter(self.name, self.description, hm.radius_mm, hm.separation, object_file=self)


@dataclass(frozen=True)
class PhotoIndenter(Indenter):
    """A library-like indenter whose object image is the object file's photo."""

    object_file: ObjectFile | None = field(default=None, repr=False, compare=False)

    def object_image(self, size_px: int = 256, mm_per_px: float = 0.0625) -> np.ndarray:
        assert self.object_file is not None  # built by ObjectFile.indenter()
        return self.object_file.object_image(size_px, mm_per_px)


def _read_photo(table: Table, base: Path) -> tuple[np.ndarray, str]:
    path = _image_file(table, base, PHOTO_SUFFIXES)
    data = path.read_bytes()
    photo = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if photo is None:
        raise table.error("file", f"{path.name}: not a readable PNG or JPEG image")
    _check_size(table, photo)
    return photo, hashlib.sha256(data).hexdigest()


def _read_height_map(table: Table, base: Path) -> HeightMap:
    path = _image_file(table, base, HEIGHT_SUFFIXES)
    if path.suffix.lower() == ".npy":
        try:
            raw = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise table.error("file", f"{path.name}: not a readable .npy array ({exc})") from None
        if raw.ndim != 2 or raw.dtype.kind not in "fiu":
            raise table.error(
                "file", f"{path.name}: expected a 2-D array of heights in mm, got {raw.dtype} {raw.shape}"
            )
        height = raw.astype(np.float64)
        if np.isinf(height).any():
            raise table.error("file", f"{path.name}: has infinite heights; use NaN where there is no material")
    else:
        raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if raw is None or raw.dtype != np.uint16 or raw.ndim != 2:
            got = "unreadable" if raw is None else f"{raw.dtype} with {1 if raw.ndim == 2 else raw.shape[2]} channel(s)"
            raise table.error("file", f"{path.name}: expected a 16-bit grey PNG, got {got}")
        mm_per_count = table.get("mm_per_count", float, positive=True, high=MAX_MM_PER_COUNT)
        height = np.where(raw > 0, raw * mm_per_count, np.nan)  # grey level 0: no material
    _check_size(table, height)
    if not np.isfinite(height).any():
        raise table.error("file", f"{path.name}: has no material (every value is 0 or NaN)")
    tallest = float(np.nanmax(np.abs(height)))
    if tallest > MAX_HEIGHT_MM:
        raise table.error(
            "file", f"{path.name}: a height of {tallest:.4g} mm; expected heights in mm within ±{MAX_HEIGHT_MM:g} mm"
        )
    relief = float(np.nanmax(height) - np.nanmin(height))
    if relief >= MAX_RELIEF_MM:
        raise table.error(
            "file",
            f"{path.name}: relief {relief:.4g} mm; a contact face's must be under {MAX_RELIEF_MM:g} mm (the thickest "
            "gel a rig takes): crop the map to the part that touches, or check its units",
        )
    mm_per_px = table.get("mm_per_px", float, low=MM_PER_PX_LOW, high=MM_PER_PX_HIGH)
    if path.suffix.lower() == ".npy" and "mm_per_count" in table.data:
        raise table.error("mm_per_count", "only for a 16-bit PNG; a .npy map holds heights in mm")
    return HeightMap(height, mm_per_px, _centre(table, height.shape))


def parse_object_file(text: str, path: str) -> ObjectFile:
    """An object file's text; images are found relative to ``path``. ConfigError names the
    file, the key and the value."""
    top, _ = toml_table(text, path)
    base = Path(path).parent
    meta = Table(path, "object", top.get("object", dict, {}))
    photo_t = Table(path, "photo", top.get("photo", dict))
    raw_height = top.get("height_map", dict, None)
    height_t = None if raw_height is None else Table(path, "height_map", raw_height)
    name = meta.get("name", str, Path(path).stem)
    if not name.strip() or is_object_file(name):
        raise meta.error("name", f"must be a name (not empty, not ending in .toml), got {name!r}")
    description = meta.get("description", str, f"user object {name}")
    photo, sha = _read_photo(photo_t, base)
    photo_mm_per_px = photo_t.get("mm_per_px", float, low=MM_PER_PX_LOW, high=MM_PER_PX_HIGH)
    centre = _centre(photo_t, photo.shape)
    height_map = None if height_t is None else _read_height_map(height_t, base)
    for table in (meta, photo_t, height_t):
        if table is not None:
            table.done()
    top.done()
    return ObjectFile(path, text, name, description, photo, photo_mm_per_px, centre, sha, height_map)


def load_object_file(path: str | Path) -> ObjectFile:
    """The object file at ``path``; ConfigError names the file, the key and the value."""
    path = Path(path)
    try:
        text = path.read_text()
    except (FileNotFoundError, IsADirectoryError):
        raise ConfigError(str(path), "-", "object file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(str(path), "-", f"cannot read the object file ({exc})") from None
    return parse_object_file(text, str(path))


def load_object(name_or_path: str) -> Indenter | ObjectFile:
    """A library object by name, or an object file's object: its indenter (presses, with the
    photo as object image) when it has a height map, else the ObjectFile (``has_geometry`` False)."""
    if not is_object_file(name_or_path):
        from objects.indenters import get_indenter

        return get_indenter(name_or_path)
    obj = load_object_file(name_or_path)
    return obj.indenter() if obj.has_geometry else obj


def object_file_of(obj: Indenter | ObjectFile) -> ObjectFile | None:
    """The object file behind ``obj`` (None for a library object)."""
    if isinstance(obj, ObjectFile):
        return obj
    return obj.object_file if isinstance(obj, PhotoIndenter) else None
