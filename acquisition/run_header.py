"""A run file's header: what a run records about itself before its first frame (``RunHeader``),
written as the file's root attributes and sealed with their checksum, and the empty datasets the
writer then fills (``write_header``). acquisition/run_writer.py creates and appends.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

import h5py
import numpy as np

from acquisition import schema as S
from acquisition.attr_checksum import seal
from acquisition.frame_identity import FRAME_DIGEST_BYTES, new_run_id
from acquisition.run_storage import ROW_BLOCK, STREAM_BLOCK, chunked
from rig import __version__


@dataclass(frozen=True)
class RunHeader:
    protocol_name: str
    protocol_toml: str
    rig_config: str
    object_name: str
    object_geometry: str
    sensor_kind: str
    mm_per_px: float
    capture_hz: float
    frames_planned: int
    contact_origin: tuple[float, float, float, float]
    phases: tuple[str, ...]
    sensor_profile: str = ""  # SensorProfile.record() of the sensor the frames came from; "": none known
    object_file_toml: str = ""  # a user object file's text; "" (a library object) writes no attribute
    object_photo_sha256: str = ""  # sha256 of that object's photo


def write_attributes(f: h5py.File, header: RunHeader) -> None:
    """The root attributes of ``header`` (before SWMR mode, which forbids adding any), sealed with
    their checksum (acquisition/attr_checksum.py)."""
    a = f.attrs
    a[S.ATTR_SCHEMA] = S.SCHEMA_VERSION
    a[S.ATTR_RUN_ID] = new_run_id()  # the key of its frame and stream digests (acquisition/frame_identity.py)
    a[S.ATTR_SOFTWARE] = __version__
    a[S.ATTR_CREATED] = dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")
    a[S.ATTR_PROTOCOL_NAME] = header.protocol_name
    a[S.ATTR_PROTOCOL] = header.protocol_toml
    a[S.ATTR_RIG_CONFIG] = header.rig_config
    a[S.ATTR_OBJECT] = header.object_name
    a[S.ATTR_OBJECT_GEOMETRY] = header.object_geometry
    a[S.ATTR_SENSOR_KIND] = header.sensor_kind
    a[S.ATTR_MM_PER_PX] = header.mm_per_px
    a[S.ATTR_CAPTURE_HZ] = header.capture_hz
    a[S.ATTR_FRAMES_PLANNED] = header.frames_planned
    a[S.ATTR_CONTACT_ORIGIN] = np.asarray(header.contact_origin, dtype=float)
    a[S.ATTR_PHASES] = list(header.phases)
    a[S.ATTR_SENSOR_PROFILE] = header.sensor_profile  # "" says the run has none: a reader never guesses one
    if header.object_file_toml:
        a[S.ATTR_OBJECT_FILE] = header.object_file_toml
        a[S.ATTR_OBJECT_PHOTO_SHA256] = header.object_photo_sha256
    seal(f)


def write_header(
    f: h5py.File, header: RunHeader, frame_shape, object_image, reference_frame, codec: str | None
) -> None:
    """The root attributes, then every dataset empty but for the two images, the status and its
    reason (a file in SWMR mode cannot gain any): what ``RunWriter.create`` writes under a temporary
    name before the run appears."""
    write_attributes(f, header)
    h, w, c = frame_shape
    frames = f.create_dataset(
        S.FRAMES,
        (0, h, w, c),
        maxshape=(None, h, w, c),
        dtype=S.FRAMES_FIELD.dtype,
        **chunked((1, h, w, c), codec=codec),
    )
    frames.attrs["units"] = S.FRAMES_FIELD.units
    for field in S.PER_FRAME_FIELDS:
        d = f.create_dataset(
            field.path,
            (0, *field.shape),
            maxshape=(None, *field.shape),
            dtype=field.dtype,
            **chunked((ROW_BLOCK, *field.shape)),
        )
        d.attrs["units"] = field.units
    for field in S.STREAM_FIELDS:
        width = field.shape[1:]
        d = f.create_dataset(
            field.path, (0, *width), maxshape=(None, *width), dtype=field.dtype, **chunked((STREAM_BLOCK, *width))
        )
        d.attrs["units"] = field.units
    f.create_dataset(
        S.FRAME_DIGEST,
        (0, FRAME_DIGEST_BYTES),
        maxshape=(None, FRAME_DIGEST_BYTES),
        dtype="u1",
        **chunked((ROW_BLOCK, FRAME_DIGEST_BYTES)),
    )
    f.create_dataset(S.STREAM_DIGEST, (0,), maxshape=(None,), dtype="u8", **chunked((STREAM_BLOCK,)))
    for name, image in ((S.OBJECT_IMAGE, object_image), (S.REFERENCE_FRAME, reference_frame)):
        image = np.ascontiguousarray(image, dtype=np.uint8)  # one checksummed chunk: a flipped byte fails its read
        f.create_dataset(name, data=image, chunks=image.shape, fletcher32=True)
    f.create_dataset(S.STATUS, data=np.bytes_("running"), dtype=f"S{S.STATUS_LEN}")
    f.create_dataset(S.STATUS_REASON, data=np.bytes_(""), dtype=f"S{S.REASON_LEN}")
    f.create_dataset(S.SIM_SOLVER_WARNINGS, data=np.int64(-1))  # datasets cannot be added once in SWMR mode
