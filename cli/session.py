"""Open the rig a command needs: from --config FILE, or the built-in simulated rig (--sim)."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from common.errors import ConfigError

DEFAULT_CONFIG = "rig.toml"


def resolve_config_path(config: Path | None) -> Path:
    if config is not None:
        return config
    env = os.environ.get("RIG_CONFIG")
    if env:
        return Path(env)
    if Path(DEFAULT_CONFIG).exists():
        return Path(DEFAULT_CONFIG)
    raise ConfigError(
        DEFAULT_CONFIG,
        "-",
        "no rig config: pass --config FILE, set RIG_CONFIG, or use --sim for the built-in simulated rig",
    )


@contextlib.contextmanager
def open_rig(
    config: Path | None,
    sim: bool,
    *,
    axes: tuple[str, ...] | None = None,
    gauge: bool = True,
    camera: bool | None = False,
):
    """Yield an open ``Rig`` with only the devices asked for; closes everything on exit.
    ``camera=None``: the camera when the config has a [camera] section.

    SIGTERM and SIGHUP (and SIGINT) raise MotionInterrupted for the whole command, not
    only while something moves, so that a signal while the rig opens or closes still
    runs the closing: a gauge left streaming would break every later command.
    """
    from rig.config import load_config
    from rig.motion import SignalsAsExceptions
    from rig.rig import Rig

    with SignalsAsExceptions():
        if sim:
            from rig.sim.rig_sim import SimulatedRig

            with SimulatedRig() as simulated:
                cfg = simulated.config()
                with Rig.open(
                    cfg, simulated.clock, axes=axes, gauge=gauge, camera=_camera(cfg, camera), sim=simulated
                ) as rig:
                    yield rig
        else:
            cfg = load_config(resolve_config_path(config))
            with Rig.open(cfg, axes=axes, gauge=gauge, camera=_camera(cfg, camera)) as rig:
                yield rig


def _camera(cfg, camera: bool | None) -> bool:
    return cfg.camera is not None if camera is None else camera
