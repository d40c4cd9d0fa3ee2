"""The pose convention of run files, and the conversion of an imported folder's poses to it.

Every pose in a run file (``pose_measured``, ``pose_commanded``; frames.csv ``x_mm y_mm
z_mm theta_deg`` and ``cx_mm …``) is the indenter relative to the contact point, as the
tactile camera sees it:

- ``x_mm``: +x points right in the frame;
- ``y_mm``: +y points up in the frame (image rows run down: +y is towards row 0);
- ``z_mm``: negative into the gel (z = 0 at first contact, a press is z < 0);
- ``theta_deg``: counter-clockwise as seen by the camera;
- origin: the contact point (the pose (0, 0, 0, 0) is the object centred in the frame, touching).

An import folder states its own convention in run.json (``pose_convention``, an object with
these five keys); a key naming the other direction is converted by a sign flip, an origin
other than the contact point is refused (the contact point is not known to the import).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from common.errors import ConfigError

# the run file's convention, as run.json states it (export writes exactly this)
POSE_CONVENTION: dict[str, str] = {
    "x": "right",
    "y": "up",
    "z": "negative_into_gel",
    "theta": "counter_clockwise",
    "origin": "contact_point",
}
# key → (the run file's value, the value converted by a sign flip); the index is the pose column
FLIPS: dict[str, tuple[int, str, str]] = {
    "x": (0, "right", "left"),
    "y": (1, "up", "down"),
    "z": (2, "negative_into_gel", "positive_into_gel"),
    "theta": (3, "counter_clockwise", "clockwise"),
}
DESCRIPTION = (
    "+x right, +y up in the frame, z negative into the gel, theta counter-clockwise seen by the camera; "
    "mm and deg from the contact point"
)
EXAMPLE = '"pose_convention": {"x": "right", "y": "up", "z": "negative_into_gel", "theta": "counter_clockwise", ' + (
    '"origin": "contact_point"}'
)


def pose_signs(path: str, value: Any) -> np.ndarray:
    """(4,) signs that bring run.json's stated convention to the run file's: +1 or -1 per pose
    column (x, y, z, theta). ConfigError names run.json, the key and the accepted values."""
    if value is None:
        raise ConfigError(
            path,
            "pose_convention",
            "missing: say which way your poses point, e.g. "
            f"{EXAMPLE} (y 'down' is converted); see docs/dataset.md, 'Pose convention'",
        )
    if not isinstance(value, dict):
        raise ConfigError(path, "pose_convention", f"must be an object with keys {', '.join(POSE_CONVENTION)}")
    unknown = [k for k in value if k not in POSE_CONVENTION]
    missing = [k for k in POSE_CONVENTION if k not in value]
    if unknown or missing:
        raise ConfigError(
            path,
            "pose_convention",
            f"keys must be {', '.join(POSE_CONVENTION)}"
            + (f"; unknown {', '.join(unknown)}" if unknown else "")
            + (f"; missing {', '.join(missing)}" if missing else "")
            + (
                "; units are the columns' (x_mm ... theta_deg): convert to mm and deg first" if "units" in value else ""
            ),
        )
    if value["origin"] != POSE_CONVENTION["origin"]:
        raise ConfigError(
            path,
            "pose_convention.origin",
            f"must be 'contact_point' (poses relative to where the object first touches the gel), "
            f"got {value['origin']!r}; subtract the contact point's stage position from the poses first",
        )
    signs = np.ones(4)
    for key, (column, same, flipped) in FLIPS.items():
        if value[key] == flipped:
            signs[column] = -1.0
        elif value[key] != same:
            raise ConfigError(path, f"pose_convention.{key}", f"must be {same!r} or {flipped!r}, got {value[key]!r}")
    return signs


def flipped_axes(signs: np.ndarray) -> list[str]:
    """The pose keys a conversion flips, e.g. ['y'] for a y-down folder."""
    return [key for key, (column, _, _) in FLIPS.items() if signs[column] < 0]
