"""A protocol file: the object, the sensor, the press/shear/twist parameters, capture.

Files live in ``protocols/library/NAME.toml`` (or anywhere: pass a path). Every key
is validated at load; errors name the file, the key and what was allowed.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from common.errors import ConfigError
from common.gauge_range import MAX_FORCE_LIMIT_N, MAX_TORQUE_LIMIT_NMM
from common.sensors import SENSOR_KINDS
from common.table import Table, toml_table

LIBRARY = Path(__file__).parent / "library"
MAX_DEPTH_MM = 10.0  # see parse_protocol


@dataclass(frozen=True)
class Protocol:
    path: str
    text: str  # the file as written: stored in every run file
    name: str
    description: str
    object: str  # library object name, or an object file's absolute path (the simulated rig presses it)
    sensor: str  # sensor kind
    depth_step_mm: float
    max_depth_mm: float
    shear_mm: float
    twist_deg: float
    speed_mm_s: float  # path speed of every linear move
    twist_speed_deg_s: float
    approach_mm: float  # start this far above the contact point
    approach_speed_mm_s: float  # to and from the start, not captured
    capture_hz: float
    # [limits]: the force/torque limits this protocol runs under (|Fx|, |Fy|, |Fz| N; |Mx|, |My|,
    # |Mz| N·mm), derived from the object's contact area and the gel's stiffness; None: the rig's own
    max_force_N: tuple[float, float, float] | None = None
    max_torque_Nmm: tuple[float, float, float] | None = None

    def same_motion(self, other: "Protocol") -> bool:
        """Every setting equal (file path, text and comments aside): what ``--resume`` needs."""
        skip = ("path", "text", "description")
        return all(getattr(self, f) == getattr(other, f) for f in self.__dataclass_fields__ if f not in skip)

    @property
    def levels(self) -> list[float]:
        n = round(self.max_depth_mm / self.depth_step_mm)
        return [self.depth_step_mm * (i + 1) for i in range(n)]


def parse_protocol(text: str, path: str = "<string>") -> Protocol:
    top, _ = toml_table(text, path)
    meta = Table(path, "protocol", top.get("protocol", dict))
    motion = Table(path, "motion", top.get("motion", dict))
    capture = Table(path, "capture", top.get("capture", dict, {}))
    limits = Table(path, "limits", top.get("limits", dict, {}))
    from objects.indenters import INDENTERS

    p = Protocol(
        path=path,
        text=text,
        name=meta.get("name", str),
        description=meta.get("description", str, ""),
        object=_object(meta, path, tuple(INDENTERS)),
        sensor=meta.get("sensor", str, "rgb", choices=SENSOR_KINDS),
        # 1 µm per level is below what the stages repeat; 10 mm is deeper than any tactile gel
        # is thick (a few mm) — deeper presses only crush the sensor. The planner also caps
        # the number of levels (protocols/plan.py).
        depth_step_mm=motion.get("depth_step_mm", float, 0.4, low=0.001, high=MAX_DEPTH_MM),
        max_depth_mm=motion.get("max_depth_mm", float, 1.6, low=0.001, high=MAX_DEPTH_MM),
        shear_mm=motion.get("shear_mm", float, 2.0, low=0.0, high=20.0),
        twist_deg=motion.get("twist_deg", float, 5.0, low=0.0, high=90.0),
        speed_mm_s=motion.get("speed_mm_s", float, 0.01, low=1e-4, high=10.0),
        twist_speed_deg_s=motion.get("twist_speed_deg_s", float, 0.25, low=1e-3, high=90.0),
        approach_mm=motion.get("approach_mm", float, 1.0, low=0.05, high=50.0),
        approach_speed_mm_s=motion.get("approach_speed_mm_s", float, 0.5, low=1e-3, high=10.0),
        capture_hz=capture.get("rate_hz", float, 1.0, low=0.01, high=100.0),
        **_limits(limits),
    )
    for table in (meta, motion, capture, limits):
        table.done()
    # 0 turns a move off; a sub-micrometre (or micro-degree) one is below what the stages
    # repeat, and at 1e-311 its length underflows to zero, leaving a move with no duration
    for key, value, least, unit in (("shear_mm", p.shear_mm, 0.001, "mm"), ("twist_deg", p.twist_deg, 0.001, "deg")):
        if 0 < value < least:
            raise ConfigError(path, f"motion.{key}", f"must be 0 (none) or at least {least} {unit}, got {value!r}")
    top.done()
    levels = p.max_depth_mm / p.depth_step_mm
    if abs(levels - round(levels)) > 1e-6:
        raise ConfigError(
            path,
            "motion.max_depth_mm",
            f"must be a whole number of depth steps ({p.depth_step_mm} mm), got {p.max_depth_mm}",
        )
    return p


def _limits(limits: Table) -> dict:
    """``[limits]``: both vectors or neither, each component > 0 and within a gauge's full scale
    (common/gauge_range.py): a limit the gauge cannot read never trips."""
    if not limits.data:
        return {}
    force = limits.vector("max_force_N", 3, positive=True, high=MAX_FORCE_LIMIT_N)
    torque = limits.vector("max_torque_Nmm", 3, positive=True, high=MAX_TORQUE_LIMIT_NMM)
    return {"max_force_N": force, "max_torque_Nmm": torque}


def _object(meta: Table, path: str, library: tuple[str, ...]) -> str:
    """A library object's name, or an object file (``.toml``, relative to the protocol file or
    absolute) as its absolute path, loaded here so that a broken object file fails at load."""
    from objects.object_file import is_object_file, load_object_file

    value = meta.get("object", str)
    if not is_object_file(value):
        if value not in library:
            raise meta.error(
                "object", f"must be one of {', '.join(map(repr, library))} or an object file (.toml), got {value!r}"
            )
        return value
    file = Path(value).expanduser()
    file = file if file.is_absolute() else Path(path).parent / file
    if not file.is_file():
        raise meta.error("object", f"object file {value!r} not found (looked at {file.absolute()})")
    load_object_file(file)
    return str(file.absolute())


def protocol_names() -> list[str]:
    return sorted(p.stem for p in LIBRARY.glob("*.toml"))


def apply_settings(text: str, settings: list[str], path: str) -> str:
    """``section.key=value`` settings (``rig run-protocol --set``) written into a protocol's
    text, which the run file stores: the file records what actually ran."""
    import json
    import re
    import tomllib

    lines = text.splitlines()
    for setting in settings:
        name, sep, value = setting.partition("=")
        section, dot, key = name.strip().partition(".")
        if not sep or not dot or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", key) or not section:
            raise ConfigError(
                path,
                name.strip() or "-",
                f"--set {setting!r}: expected section.key=value, such as motion.speed_mm_s=0.1",
            )
        value = value.strip()
        try:
            parsed = tomllib.loads(f"v = {value}")
        except tomllib.TOMLDecodeError:
            value = json.dumps(value)  # a bare word: a string
        else:
            # one value on one line: a newline would let a --set add keys or whole tables
            if "\n" in value or "\r" in value or set(parsed) != {"v"}:
                raise ConfigError(
                    path, name.strip(), f"--set {setting!r}: the value must be one TOML value on one line"
                )
        entry = f"{key} = {value}  # set on the command line"
        in_section, done, header = False, False, None
        for i, line in enumerate(lines):
            head = re.fullmatch(r"\s*\[([^\]]+)\]\s*(#.*)?", line)
            if head:
                in_section = head.group(1).strip() == section
                header = i if in_section else header
            elif in_section and re.match(rf"\s*{key}\s*=", line):
                lines[i], done = entry, True
                break
        if not done:
            if header is None:
                lines += ["", f"[{section}]", entry]
            else:
                lines.insert(header + 1, entry)
    return "\n".join(lines) + "\n"


def load_protocol(name_or_path: str | Path, settings: list[str] | None = None) -> Protocol:
    """A library protocol by name, or a protocol file by path; ``settings`` (section.key=value)
    change it for this run."""
    candidate = Path(name_or_path)
    if candidate.suffix != ".toml":
        candidate = LIBRARY / f"{name_or_path}.toml"
        if not candidate.exists():
            raise ConfigError(
                str(name_or_path),
                "-",
                f"no such protocol; the library has: {', '.join(protocol_names())} (or pass a .toml path)",
            )
    try:
        text = candidate.read_text()
    except FileNotFoundError as exc:
        raise ConfigError(str(candidate), "-", "file not found") from exc
    if settings:
        text = apply_settings(text, settings, str(candidate))
    return parse_protocol(text, str(candidate))
