"""Writing a sensor profile: ``save_profile`` writes its TOML (in the profile's own format) and
its background PNG beside it, so that ``load_profile`` reads back the same profile (the same
content hash). The reading side, and the checks every value passes, are sensor_sim/profile.py.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from sensor_sim.profile import ProfileError, SensorProfile, _finite_range, _toml_str


def _toml_rows(table: np.ndarray) -> str:
    return "[\n" + "".join("  [" + ", ".join(f"{v:.3f}" for v in row) + "],\n" for row in table) + "]"


def _toml_numbers(values) -> str:
    return "[" + ", ".join(f"{float(v)!r}" for v in values) + "]"


def save_profile(profile: SensorProfile, path: str | Path) -> Path:
    """Write ``path`` (TOML, in the profile's format) and its background PNG beside it (same stem);
    returns the TOML path."""
    path = Path(path)
    bg_path = path.with_suffix(".png")
    if not cv2.imwrite(str(bg_path), np.asarray(profile.background, dtype=np.uint8)):
        raise ProfileError(f"{bg_path}: cannot write the background image")
    light, noise = profile.light, profile.noise
    if profile.format == 1 and (light.extended or not noise.independent):
        raise ProfileError(f"{path}: a profile of format 1 holds no position or sink terms and no correlated noise")
    if profile.format == 2 and math.isfinite(light.sink_max_mm):
        raise ProfileError(f"{path}: a profile of format 2 holds no sink_max_mm (format 3 does)")
    if profile.format < 4 and light.quadratic_sink:
        raise ProfileError(f"{path}: format {profile.format} holds no quadratic sink field (format 4 does)")
    if (profile.format < 5) != (light.sink_table_bgr is None):
        raise ProfileError(
            f"{path}: format {profile.format} with{'' if profile.format < 5 else 'out'} a sink table "
            "(format 5 holds one, formats 1 to 4 none)"
        )
    tables = "\n".join(f"table_{c} = {_toml_rows(light.table_bgr[i])}" for i, c in enumerate("bgr"))
    if profile.format == 1:
        noise_line, noise_section, terms = (
            f"noise_std = {noise.std_bgr[0]!r}  # grey levels per pixel and channel\n",
            "",
            "",
        )
    else:
        noise_line = ""
        noise_section = f"""
[noise]  # the camera's noise, at the background's pixels (the camera's own)
std_bgr = {_toml_numbers(noise.std_bgr)}  # grey levels per pixel
correlation_px = {float(noise.correlation_px)!r}  # sigma of its spatial correlation, background pixels
channel_correlation = {_toml_numbers(noise.channel_correlation)}  # b-g, b-r, g-r
"""
        sink = light.sink_bgr if light.sink_bgr is not None else np.zeros((3, 3))
        terms = (
            f"position_order = {0 if light.position_bgr is None else 1}  # 1: the tables below vary over the field\n"
            f"position_scale_mm = {float(light.position_scale_mm or 1.0)!r}  # x~, y~ = mm from the centre / this\n"
            f"position_range = {_toml_numbers(_finite_range(light.position_range))}  # x~, y~ held within\n"
            f"sink_bgr = [{', '.join(_toml_numbers(row) for row in sink)}]  # per mm of sink: k, kx, ky per channel"
            + (" (then kxx, kxy, kyy; per mm²: the same six)" if light.quadratic_sink else "")
            + "\n"
        )
        if profile.format >= 3:
            terms += f"sink_max_mm = {_finite_range([light.sink_max_mm])[0]!r}  # deeper, the sink terms stay at this\n"
        if light.sink_table_bgr is not None:
            terms += "# per mm of sink at each normal (the pressed-in gel's own response to a tilt)\n"
            terms += "\n".join(f"sink_table_{c} = {_toml_rows(light.sink_table_bgr[i])}" for i, c in enumerate("bgr"))
            terms += "\n"
        if light.position_bgr is not None:
            terms += (
                "\n".join(
                    f"position_{axis}_{c} = {_toml_rows(light.position_bgr[i, k])}"
                    for i, c in enumerate("bgr")
                    for k, axis in enumerate("xy")
                )
                + "\n"
            )
    fmt_line = "" if profile.format == 1 else f"format = {profile.format}\n"
    text = f'''# Sensor profile (sensor_sim.profile): one tactile sensor's frame, gel, optics, markers and noise.
[sensor]
{fmt_line}name = {_toml_str(profile.name)}
source = {_toml_str(profile.source)}
width_px = {profile.width_px}
height_px = {profile.height_px}
mm_per_px = {profile.mm_per_px!r}
{noise_line}background = "{bg_path.name}"  # no-contact frame, resized to the frame
{noise_section}
[gel]
thickness_mm = {profile.gel_thickness_mm!r}
E_MPa = {profile.gel_E_MPa!r}

[markers]  # used by the rgb_markers and white_markers kinds
pitch_mm = {profile.marker_pitch_mm!r}
radius_mm = {profile.marker_radius_mm!r}
darkness = {profile.marker_darkness!r}  # 1 = black markers

[optics]  # colour change (grey levels) per surface normal (nx, ny) in [-1, 1]²: rows ny, columns nx
shading = "{light.shading}"
blur_mm = {light.blur_mm!r}
reference_bgr = [{", ".join(f"{v!r}" for v in light.reference_bgr)}]
table_bins = {light.bins}
{terms}{tables}
'''
    path.write_text(text)
    return path
