"""The HDF5 run file schema: every path and attribute name, in one place.

Documented in docs/run-file.md. Units are in each dataset's ``units`` attribute.
"""

from dataclasses import dataclass

FRAMES = "frames"  # (N, H, W, 3) uint8, BGR, one frame per chunk
WRENCH = "wrench"  # (N, 6) float64: Fx Fy Fz [N], Mx My Mz [N·mm]
POSE_COMMANDED = "pose_commanded"  # (N, 4) float64: x y z [mm], theta [deg], from the contact point
POSE_MEASURED = "pose_measured"  # (N, 4) float64, same frame, read from the stages
T_FRAME = "t_frame_s"  # (N,) float64: frame timestamp on the rig clock (the trigger)
T_CAPTURE = "t_capture_s"  # (N,) float64: scheduled capture time, protocol time
WRENCH_SKEW = "wrench_skew_s"  # (N,) float64: distance from the frame time to the nearest gauge sample
CAPTURE_INDEX = "capture_index"  # (N,) int64: k of the capture grid t = k / rate (no gap, no duplicate)
STEP_INDEX = "step_index"  # (N,) int32: protocol step running at the capture
PHASE_INDEX = "phase_index"  # (N,) int8: index into the PHASES attribute
LEVEL = "level"  # (N,) int8: depth level, 1-based

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


# Per-frame rows: (N, *shape). None in a shape means "any size" (frame height and width).
PER_FRAME_FIELDS = (
    Field(WRENCH, (6,), "f8", "N, N, N, N·mm, N·mm, N·mm", True),
    Field(POSE_COMMANDED, (4,), "f8", "mm, mm, mm, deg", True),
    Field(POSE_MEASURED, (4,), "f8", "mm, mm, mm, deg", True),
    Field(T_FRAME, (), "f8", "s (rig clock)", True),
    Field(T_CAPTURE, (), "f8", "s (protocol time)", True),
    Field(WRENCH_SKEW, (), "f8", "s", True),
    Field(CAPTURE_INDEX, (), "i8", "", True),
    Field(STEP_INDEX, (), "i4", "", True),
    Field(PHASE_INDEX, (), "i1", "", True),
    Field(LEVEL, (), "i1", "", True),
)
FRAMES_FIELD = Field(FRAMES, (None, None, 3), "u1", "BGR, 0-255", True)
FIXED_FIELDS = (
    Field(OBJECT_IMAGE, (None, None, 3), "u1", "", False),
    Field(REFERENCE_FRAME, (None, None, 3), "u1", "", False),
    Field(STATUS, (), f"S{STATUS_LEN}", "", False),
    Field(STATUS_REASON, (), f"S{REASON_LEN}", "", False),
    Field(SIM_SOLVER_WARNINGS, (), "i8", "count", False, required=False),
)
FIELDS = (FRAMES_FIELD, *PER_FRAME_FIELDS, *FIXED_FIELDS)

# Root attributes and the kind of value each holds: "str", "float", "int", "float[4]", "str[]".
ATTRS = (
    (ATTR_SCHEMA, "int"), (ATTR_SOFTWARE, "str"), (ATTR_CREATED, "str"), (ATTR_PROTOCOL_NAME, "str"),
    (ATTR_PROTOCOL, "str"), (ATTR_RIG_CONFIG, "str"), (ATTR_OBJECT, "str"), (ATTR_OBJECT_GEOMETRY, "str"),
    (ATTR_SENSOR_KIND, "str"), (ATTR_MM_PER_PX, "float"), (ATTR_CAPTURE_HZ, "float"),
    (ATTR_FRAMES_PLANNED, "int"), (ATTR_CONTACT_ORIGIN, "float[4]"), (ATTR_PHASES, "str[]"),
)
