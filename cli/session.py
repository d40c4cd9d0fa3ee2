"""Open the rig a command needs: from --config FILE, or the built-in simulated rig (--sim)."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from common.errors import ConfigError, ToolError

DEFAULT_CONFIG = "rig.toml"


def resolve_config_path(config: Path | None) -> Path:
    if config is not None:
        return config
    env = os.environ.get("RIG_CONFIG")
    if env:
        return Path(env)
    if Path(DEFAULT_CONFIG).exists():
        return Path(DEFAULT_CONFIG)
    raise NoRigConfig(
        f"no rig config: no --config FILE given, RIG_CONFIG not set and no ./{DEFAULT_CONFIG} here; "
        "pass --config FILE (docs/rig.example.toml is a start) or use --sim for the built-in simulated rig"
    )


class NoRigConfig(ToolError):
    """No --config, no $RIG_CONFIG and no ./rig.toml."""


@contextlib.contextmanager
def open_rig(
    config: Path | None,
    sim: bool,
    *,
    axes: tuple[str, ...] | None = None,
    gauge: bool = True,
    camera: bool | None = False,
    profile: Path | None = None,
    discrete: bool = False,
    indenter: str | None = None,
):
    """Yield an open ``Rig`` with only the devices asked for; closes everything on exit.
    ``camera=None``: the camera when the config has a [camera] section. ``profile``: the
    simulated sensor's profile TOML (--sim only; default the shipped GelSight Mini).
    ``discrete``: with --sim, the simulated rig runs on discrete-event time (as `rig
    run-protocol --sim`): a wait advances simulated time at once, the camera renders when asked.
    ``indenter``: the object now mounted (``--object``; None: the one named last).

    Signals (SIGINT, SIGTERM, SIGHUP) are held while the rig opens, then raise MotionInterrupted
    for the whole command, not only while something moves; one that no motion session met still
    stops the axes and lifts z when it may be pressed, and the closing runs to its end
    (rig/signal_safety.py): a gauge left streaming would break every later command.
    """
    from rig.config import load_config
    from rig.rig import Rig
    from rig.signal_safety import opened_safely

    check_profile_option(profile, sim)
    if sim:
        from rig.clock import ManualClock
        from rig.sim.rig_sim import SimulatedRig

        @contextlib.contextmanager
        def opener():
            clock = ManualClock() if discrete else None
            with SimulatedRig(clock, profile=load_sim_profile(profile)) as simulated:
                simulated.triggered_camera = discrete
                cfg = simulated.config()
                with Rig.open(
                    cfg,
                    simulated.clock,
                    axes=axes,
                    gauge=gauge,
                    camera=_camera(cfg, camera),
                    sim=simulated,
                    indenter=indenter,
                ) as rig:
                    yield rig

        with opened_safely(opener) as rig:
            yield rig
    else:
        cfg = load_config(resolve_config_path(config))
        with opened_safely(
            lambda: Rig.open(cfg, axes=axes, gauge=gauge, camera=_camera(cfg, camera), indenter=indenter)
        ) as rig:
            yield rig


def has_z(config: Path | None, sim: bool) -> bool:
    """Whether the rig a command opens has a z axis (the simulated rig always does)."""
    if sim:
        return True
    from rig.config import load_config

    return "z" in load_config(resolve_config_path(config)).axes


def _camera(cfg, camera: bool | None) -> bool:
    return cfg.camera is not None if camera is None else camera


def check_profile_option(profile: Path | None, sim: bool) -> None:
    """--profile describes the simulated sensor: with hardware it would be silently ignored."""
    if profile is not None and not sim:
        raise ConfigError(str(profile), "--profile", "a sensor profile sets up the simulated sensor: use it with --sim")


def load_sim_profile(profile: Path | None):
    """The SensorProfile at ``profile`` (None: the shipped default); a bad file is a ConfigError
    naming the file and key."""
    from sensor_sim.profile import ProfileError, resolve_profile

    try:
        return resolve_profile(profile)
    except ProfileError as exc:
        message = str(exc).removeprefix(f"{profile}: ")  # ConfigError names the file itself
        raise ConfigError(str(profile), "--profile", message) from None
