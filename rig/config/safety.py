"""A rig config's [safety] and [pendant] tables: ``SafetyConfig`` (force limits, the depth guard's
gel, the speed envelope's stiffnesses and margins, with their defaults and the deepest fraction a
gel allows) and ``PendantConfig``, each read and checked from its TOML table. rig/config/__init__.py
reads the rest of the file and holds both in a ``RigConfig``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from common.gauge_range import MAX_FORCE_LIMIT_N, MAX_TORQUE_LIMIT_NMM
from common.table import Table
from rig.config.registry import TRAVEL_LIMIT

# The speed envelope's defaults (docs/safety.md, "Speed envelope"). The stiffnesses are worst
# cases of the simulated GelSight Mini gel (3 mm, 0.25 MPa) with a rigid 20 mm plate covering
# the pad, rounded up (docs/simulator.md, "Contact stiffness"); a stiffer gel, a thinner one or
# a stiffer object needs its own numbers. The window: a steel face on acrylic, ~30 N/µm for 8 mm.
DEFAULT_MAX_DEPTH_FRACTION = 0.6
# The floor must stay clear of the window with the surface known only so well: a first contact
# is seen up to DETECTION_LAG_MM late (a 4 mm sphere needs ~0.2 mm for 0.05 N), and a remembered
# surface is kept against a lower first contact within min(0.25 mm, a tenth of the gel). The
# deepest fraction a config may ask is what leaves 5 % of the gel below all of that.
DETECTION_LAG_MM = 0.2
SURFACE_TOLERANCE_MM = 0.25
SURFACE_TOLERANCE_FRACTION = 0.1


def surface_tolerance_mm(thickness_mm: float) -> float:
    return min(SURFACE_TOLERANCE_MM, SURFACE_TOLERANCE_FRACTION * thickness_mm)


def deepest_fraction(thickness_mm: float) -> float:
    """The largest max_depth_fraction a gel this thick allows (0.80 for 3 mm, 0.65 for 1 mm)."""
    return 0.95 - (surface_tolerance_mm(thickness_mm) + DETECTION_LAG_MM) / thickness_mm


DEFAULT_STIFFNESS_N_PER_MM = 100.0
DEFAULT_SHEAR_STIFFNESS_N_PER_MM = 20.0
DEFAULT_TWIST_STIFFNESS_NMM_PER_DEG = 10.0
DEFAULT_WINDOW_STIFFNESS_N_PER_MM = 60000.0  # a rigid plate over a 14 mm pad on acrylic: ~57 N/µm
DEFAULT_OVERSHOOT_MARGIN = 0.1
# How far the real gel surface may lie above the remembered one without the rig being told (a
# longer indenter, a thicker gel, a sensor moved): descents leave full speed this far above it
# plus the clearance, so that an approach frozen in mid-move stops short of the gel.
DEFAULT_SURFACE_UNCERTAINTY_MM = 1.0
DEFAULT_SURFACE_MAX_AGE_H = 24.0  # a remembered surface older than this is forgotten


@dataclass(frozen=True)
class SafetyConfig:
    max_force_N: tuple[float, float, float]  # |Fx|, |Fy|, |Fz| limits
    max_torque_Nmm: tuple[float, float, float]  # |Mx|, |My|, |Mz| limits
    poll_s: float = 0.02  # how often a moving rig checks the wrench
    # The depth guard and the speed envelope (rig/envelope.py, docs/safety.md). gel_thickness_mm
    # is required where a z axis is configured: a guessed gel would put the window behind it anywhere.
    gel_thickness_mm: float | None = None
    max_depth_fraction: float = DEFAULT_MAX_DEPTH_FRACTION  # no deeper below the gel surface than this × thickness
    stiffness_N_per_mm: float = DEFAULT_STIFFNESS_N_PER_MM  # worst-case dFz/dz of a contact inside the gel
    shear_stiffness_N_per_mm: float = DEFAULT_SHEAR_STIFFNESS_N_PER_MM  # worst-case dFx/dx while pressed
    twist_stiffness_Nmm_per_deg: float = DEFAULT_TWIST_STIFFNESS_NMM_PER_DEG  # worst-case dMz/dθ while pressed
    window_stiffness_N_per_mm: float = DEFAULT_WINDOW_STIFFNESS_N_PER_MM  # the indenter on the window behind the gel
    overshoot_margin: float = DEFAULT_OVERSHOOT_MARGIN  # a stop may overshoot a limit by this fraction of it
    surface_uncertainty_mm: float = DEFAULT_SURFACE_UNCERTAINTY_MM  # the real surface may be this much higher
    surface_max_age_h: float = DEFAULT_SURFACE_MAX_AGE_H  # a remembered surface older than this is unknown


@dataclass(frozen=True)
class PendantConfig:
    vendor_id: int | None = None
    product_id: int | None = None
    deadband: float = 0.15


def _three(v: tuple[float, ...]) -> tuple[float, float, float]:
    return v[0], v[1], v[2]  # Table.vector checked the length


def parse_safety(path: str, data: Any) -> SafetyConfig:
    """The [safety] table: force and torque limits, the check period, the depth guard's gel and the
    speed envelope's stiffnesses, each checked against its bounds."""
    t = Table(path, "safety", data)
    thickness = t.get("gel_thickness_mm", float, None, low=0.3, high=50.0)
    cfg = SafetyConfig(
        max_force_N=_three(t.vector("max_force_N", 3, positive=True, high=MAX_FORCE_LIMIT_N)),
        max_torque_Nmm=_three(t.vector("max_torque_Nmm", 3, positive=True, high=MAX_TORQUE_LIMIT_NMM)),
        poll_s=t.get("poll_s", float, 0.02, low=0.001, high=1.0),
        gel_thickness_mm=thickness,
        max_depth_fraction=_depth_fraction(t, thickness),
        stiffness_N_per_mm=t.get("stiffness_N_per_mm", float, DEFAULT_STIFFNESS_N_PER_MM, positive=True, high=1e6),
        shear_stiffness_N_per_mm=t.get(
            "shear_stiffness_N_per_mm", float, DEFAULT_SHEAR_STIFFNESS_N_PER_MM, positive=True, high=1e6
        ),
        twist_stiffness_Nmm_per_deg=t.get(
            "twist_stiffness_Nmm_per_deg", float, DEFAULT_TWIST_STIFFNESS_NMM_PER_DEG, positive=True, high=1e6
        ),
        window_stiffness_N_per_mm=t.get(
            "window_stiffness_N_per_mm", float, DEFAULT_WINDOW_STIFFNESS_N_PER_MM, positive=True, high=1e8
        ),
        overshoot_margin=t.get("overshoot_margin", float, DEFAULT_OVERSHOOT_MARGIN, positive=True, high=1.0),
        surface_uncertainty_mm=t.get(
            "surface_uncertainty_mm", float, DEFAULT_SURFACE_UNCERTAINTY_MM, low=0.0, high=TRAVEL_LIMIT
        ),
        surface_max_age_h=t.get("surface_max_age_h", float, DEFAULT_SURFACE_MAX_AGE_H, positive=True, high=24.0 * 365),
    )
    t.done()
    return cfg


def _depth_fraction(t: Table, thickness: float | None) -> float:
    """The depth floor's fraction: the default (0.6) or what the gel allows, if less; a larger
    one asked for is refused naming the largest."""
    asked = t.get("max_depth_fraction", float, None, positive=True, high=0.95)
    if thickness is None:
        return DEFAULT_MAX_DEPTH_FRACTION if asked is None else asked
    deepest = deepest_fraction(thickness)
    if asked is None:
        return round(min(DEFAULT_MAX_DEPTH_FRACTION, deepest), 3)
    if asked > deepest + 1e-9:
        raise t.error(
            "max_depth_fraction",
            f"must be <= {deepest:.2f} for a {thickness:g} mm gel (the floor keeps 5 % of the gel beyond the "
            f"surface's uncertainty, {surface_tolerance_mm(thickness) + DETECTION_LAG_MM:.2f} mm), got {asked!r}",
        )
    return asked


def parse_pendant(path: str, data: Any) -> PendantConfig:
    """The [pendant] table: which gamepad jogs the rig, and its stick's deadband."""
    t = Table(path, "pendant", data)
    cfg = PendantConfig(
        vendor_id=t.get("vendor_id", int, None, low=0, high=0xFFFF),
        product_id=t.get("product_id", int, None, low=0, high=0xFFFF),
        deadband=t.get("deadband", float, 0.15, low=0.0, high=0.9),
    )
    t.done()
    return cfg
