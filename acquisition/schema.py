"""The HDF5 run file schema: every path and attribute name, in one place.

Documented in docs/run-file.md. Units are in each dataset's ``units`` attribute.
"""

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

# Root attributes (written at creation, before SWMR mode forbids attribute changes)
ATTR_SCHEMA = "schema_version"
ATTR_SOFTWARE = "software_version"
ATTR_CREATED = "created_utc"
ATTR_PROTOCOL_NAME = "protocol_name"
ATTR_PROTOCOL = "protocol_toml"  # the protocol file's text
ATTR_RIG_CONFIG = "rig_config"  # the rig config (TOML text, or a description of the simulated rig)
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
