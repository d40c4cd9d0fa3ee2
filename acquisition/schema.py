"""The HDF5 run file schema: every path and attribute name, in one place.

Documented in docs/run-file.md. Units are in each dataset's ``units`` attribute.

Importing this module imports hdf5plugin, which registers the frames' compression
filter (Blosc) with HDF5: every reader and writer of run files names the schema's
paths, so this is the one place that makes compressed frames readable everywhere.
"""

from dataclasses import dataclass

import hdf5plugin
import numpy as np

FRAMES = "frames"  # (N, H, W, 3) uint8, BGR, one frame per chunk
WRENCH = "wrench"  # (N, 6) float64: Fx Fy Fz [N], Mx My Mz [N·mm]
POSE_COMMANDED = "pose_commanded"  # (N, 4) float64: x y z [mm], theta [deg], from the contact point
POSE_MEASURED = "pose_measured"  # (N, 4) float64, same frame, read from the stages
T_FRAME = "t_frame_s"  # (N,) float64: frame timestamp on the rig clock (the trigger)
T_CAPTURE = "t_capture_s"  # (N,) float64: scheduled capture time, protocol time
WRENCH_SKEW = "wrench_skew_s"  # (N,) float64: distance from the frame time to the nearest gauge sample
CAPTURE_INDEX = "capture_index"  # (N,) int64: k of the capture grid t = k / rate (no gap, no duplicate)
STEP_INDEX = "step_index"  # (N,) int32: protocol step running at the capture
PHASE_INDEX = "phase_index"  # (N,) int8: index into the file's own `phases` attribute
LEVEL = "level"  # (N,) int8: depth level, 1-based
RETAKE = "retake"  # (N,) int8: 0, or n: recorded again by the n-th resume, which re-did its level (superseded/)
SUPERSEDED = "superseded"  # group: per resume that re-did a level, the frames and rows it replaced
WRENCH_STREAM = "wrench_stream"  # (M, 7) float64: t_s on the rig clock, then the wrench, at the gauge's full rate
# Frame identity (acquisition/frame_identity.py): keyed by the run's own identity, bound to the index
FRAME_DIGEST = "frame_digest"  # (N, 16) uint8: BLAKE2b of the frame's index, its stored chunk and its row
STREAM_DIGEST = "wrench_stream_digest"  # (M,) uint64: BLAKE2b of each stream row's index and values

OBJECT_IMAGE = "object/image"  # (H, W, 3) uint8: the indenter's contact face
REFERENCE_FRAME = "reference_frame"  # (H, W, 3) uint8: no-contact frame taken at the start
STATUS = "run/status"  # scalar bytes: running | complete | aborted | interrupted
STATUS_REASON = "run/reason"  # scalar bytes: why it stopped, when it did
SIM_SOLVER_WARNINGS = "run/sim_solver_warnings"  # scalar int64: contact solves short of tolerance; -1: not simulated

# Root attributes (written at creation, before SWMR mode forbids attribute changes)
ATTR_SCHEMA = "schema_version"
ATTR_SOFTWARE = "software_version"
ATTR_CREATED = "created_utc"
ATTR_PROTOCOL_NAME = "protocol_name"
ATTR_PROTOCOL = "protocol_toml"  # the protocol file's text
ATTR_RIG_CONFIG = "rig_config"  # the rig config (TOML text, or a description of the simulated rig)
RIG_CONFIG_MARK = "# built-in simulated rig (rig run-protocol --sim)"  # first line of a simulated run's rig_config
ATTR_OBJECT = "object_name"
ATTR_OBJECT_GEOMETRY = "object_geometry"  # description of the indenter
ATTR_SENSOR_KIND = "sensor_kind"
ATTR_MM_PER_PX = "mm_per_px"  # calibration of the tactile frames
ATTR_CAPTURE_HZ = "capture_hz"
ATTR_FRAMES_PLANNED = "frames_planned"
ATTR_CONTACT_ORIGIN = "contact_origin"  # stage positions of the contact point (x, y, z, theta)
ATTR_PHASES = "phases"
ATTR_SENSOR_PROFILE = "sensor_profile"  # simulated runs: the sensor profile's name, sha256 and file (TOML text)
ATTR_OBJECT_FILE = "object_file_toml"  # a user object file's text (docs/protocols.md, "Your own objects")
ATTR_OBJECT_PHOTO_SHA256 = "object_photo_sha256"  # sha256 of that object's photo file: the condition's source
ATTR_ATTRS_SHA256 = "attrs_sha256"  # sha256 of every other root attribute (acquisition/attr_checksum.py)
ATTR_RUN_ID = "run_id"  # 32 hex digits, random at creation: the key of the frame and stream digests

SCHEMA_VERSION = 1
STATUS_LEN = 16
REASON_LEN = 512

STATUSES = ("running", "complete", "aborted", "interrupted")


# -- the field table ---------------------------------------------------------------
# One row per dataset and attribute the schema promises. The writer creates datasets
# from it and `dataset validate` checks files against it, so a field added here is
# both written and checked.


@dataclass(frozen=True)
class Field:
    """A dataset of the run file: its path, shape per frame (or whole shape), dtype, units."""

    path: str
    shape: tuple  # per frame when per_frame, else the whole shape; None = any size
    dtype: str  # numpy dtype string, e.g. "f8"
    units: str
    per_frame: bool
    required: bool = True  # False: files written before the field existed lack it and stay valid
    columns: tuple[str, ...] = ()  # per-frame: its columns in export/import's frames.csv (default: columns_of)
    fill: float = 0.0  # per-frame: the value where a source lacks the field (an old file, a CSV without it)


def columns_of(field: Field) -> tuple[str, ...]:
    """The frames.csv columns of a per-frame field: its own names, else the path (scalar) or path_0.. path_k."""
    if field.columns:
        return field.columns
    if not field.shape:
        return (field.path,)
    return tuple(f"{field.path}_{i}" for i in range(field.shape[0]))


def blank_row() -> dict:
    """A row with every per-frame field at its fill value: the start of a synthetic row (benches, tests)."""
    return {
        f.path: (np.full(f.shape, f.fill, dtype=f.dtype) if f.shape else np.array(f.fill, dtype=f.dtype)[()])
        for f in PER_FRAME_FIELDS
    }


# Per-frame rows: (N, *shape). None in a shape means "any size" (frame height and width).
# Adding a per-frame field is one row here (with required=False, so older files stay
# valid) and the executor filling its value: the writer, validate, merge, export/import,
# the benches and the PyTorch Dataset (`fields=`) iterate this table.
PER_FRAME_FIELDS = (
    Field(
        WRENCH,
        (6,),
        "f8",
        "N, N, N, N·mm, N·mm, N·mm",
        True,
        columns=("Fx_N", "Fy_N", "Fz_N", "Mx_Nmm", "My_Nmm", "Mz_Nmm"),
    ),
    Field(POSE_COMMANDED, (4,), "f8", "mm, mm, mm, deg", True, columns=("cx_mm", "cy_mm", "cz_mm", "ctheta_deg")),
    Field(POSE_MEASURED, (4,), "f8", "mm, mm, mm, deg", True, columns=("x_mm", "y_mm", "z_mm", "theta_deg")),
    Field(T_FRAME, (), "f8", "s (rig clock)", True),
    Field(T_CAPTURE, (), "f8", "s (protocol time)", True),
    Field(WRENCH_SKEW, (), "f8", "s", True),
    Field(CAPTURE_INDEX, (), "i8", "", True),
    Field(STEP_INDEX, (), "i4", "", True),
    Field(PHASE_INDEX, (), "i1", "", True, columns=("phase",), fill=1),  # CSV: the phase's name; 1: press
    Field(LEVEL, (), "i1", "", True),
    Field(RETAKE, (), "i1", "", True, required=False),  # files before resume re-did levels lack it: 0
)
FRAMES_FIELD = Field(FRAMES, (None, None, 3), "u1", "BGR, 0-255", True)
# Per-run datasets that grow during the run, each row its own time stamp (first column).
STREAM_FIELDS = (
    Field(WRENCH_STREAM, (None, 7), "f8", "s (rig clock), N, N, N, N·mm, N·mm, N·mm", False, required=False),
)
# The digests that bind each frame and stream row to its index and run; files before them lack them.
DIGEST_FIELDS = (
    Field(FRAME_DIGEST, (16,), "u1", "", True, required=False),
    Field(STREAM_DIGEST, (None,), "u8", "", False, required=False),
)
FIXED_FIELDS = (
    Field(OBJECT_IMAGE, (None, None, 3), "u1", "", False),
    Field(REFERENCE_FRAME, (None, None, 3), "u1", "", False),
    Field(STATUS, (), f"S{STATUS_LEN}", "", False),
    Field(STATUS_REASON, (), f"S{REASON_LEN}", "", False),
    Field(SIM_SOLVER_WARNINGS, (), "i8", "count", False, required=False),
)
FIELDS = (FRAMES_FIELD, *PER_FRAME_FIELDS, *STREAM_FIELDS, *DIGEST_FIELDS, *FIXED_FIELDS)
FIELD = {f.path: f for f in FIELDS}  # a field by its dataset path

# Root attributes and the kind of value each holds: "str", "float", "int", "float[4]", "str[]".
ATTRS = (
    (ATTR_SCHEMA, "int"),
    (ATTR_SOFTWARE, "str"),
    (ATTR_CREATED, "str"),
    (ATTR_PROTOCOL_NAME, "str"),
    (ATTR_PROTOCOL, "str"),
    (ATTR_RIG_CONFIG, "str"),
    (ATTR_OBJECT, "str"),
    (ATTR_OBJECT_GEOMETRY, "str"),
    (ATTR_SENSOR_KIND, "str"),
    (ATTR_MM_PER_PX, "float"),
    (ATTR_CAPTURE_HZ, "float"),
    (ATTR_FRAMES_PLANNED, "int"),
    (ATTR_CONTACT_ORIGIN, "float[4]"),
    (ATTR_PHASES, "str[]"),
)
# Root attributes a file may lack (written only by some runs, or added after older files);
# readers treat a missing one as "not recorded" (model/conditioning/baseline.py: the default profile).
# ATTR_ATTRS_SHA256: files written before it lack it (readable as before; validate notes it).
OPTIONAL_ATTRS = (
    (ATTR_SENSOR_PROFILE, "str"),
    (ATTR_OBJECT_FILE, "str"),
    (ATTR_OBJECT_PHOTO_SHA256, "str"),
    (ATTR_ATTRS_SHA256, "str"),
    (ATTR_RUN_ID, "str"),
)

# The frames' lossless codecs, chosen by bench/storage_bench.py (docs/benchmarks.md):
# - IMAGE_CODEC, HTJ2K (JPEG 2000's high-throughput coder, reversible): each pixel
#   predicted from its neighbours by the wavelet, so real GelSight frames take 0.24-0.28
#   of raw, written at ~590 frames/s at 256x256 and ~140 at 640x480. The default for
#   frames of 1 or 3 channels (what the filter accepts).
# - FAST_CODEC, Blosc with Zstandard level 1 on bit planes (neighbouring pixels share
#   their high bits): 0.48-0.55 of raw on real frames, 0.66-0.77 on simulated ones, at
#   ~1,400 frames/s. The simulated rig's runs use it (a run writes ~150 frames/s, and
#   HTJ2K's ~1 ms more a frame would be a sixth of it; on simulated frames HTJ2K gives
#   0.38 / 0.69 / 0.76 of raw for rgb / rgb_markers / white_markers), as do other
#   channel counts.
IMAGE_CODEC = "htj2k"
FAST_CODEC = "blosc-zstd-1+bitshuffle"
CODEC_FILTER_IDS = {IMAGE_CODEC: 32033, FAST_CODEC: 32001}  # HDF5's registered filter ids


def _codecs() -> dict[str, dict]:
    """The codecs this installation can write: HTJ2K needs hdf5plugin 7.1 or later with the
    filter built in (a stripped or older build falls back to Blosc for every frame)."""
    codecs = {FAST_CODEC: dict(hdf5plugin.Blosc(cname="zstd", clevel=1, shuffle=hdf5plugin.Blosc.BITSHUFFLE))}
    htj2k = getattr(hdf5plugin, "Htj2k", None)
    if htj2k is not None and IMAGE_CODEC in getattr(hdf5plugin.get_config(), "registered_filters", {}):
        codecs = {IMAGE_CODEC: dict(htj2k()), **codecs}
    return codecs


FRAME_CODECS = _codecs()


def frame_codec(frame_shape: tuple[int, ...], preferred: str | None = None) -> str:
    """The codec for frames of ``frame_shape`` (H, W, C): ``preferred`` (a FRAME_CODECS
    name) or the image codec, which takes 1 or 3 channels only (else the fast one)."""
    if preferred is not None and preferred not in CODEC_FILTER_IDS:
        raise ValueError(f"frame codec must be one of {', '.join(CODEC_FILTER_IDS)}, got {preferred!r}")
    codec = preferred or IMAGE_CODEC
    if codec not in FRAME_CODECS or (codec == IMAGE_CODEC and (len(frame_shape) != 3 or frame_shape[2] not in (1, 3))):
        return FAST_CODEC
    return codec
