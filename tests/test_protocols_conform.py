"""Every driver satisfies its protocol in rig/types.py, at run time and for the type checker.

At run time: ``isinstance`` against the ``runtime_checkable`` protocols on drivers opened
against the simulators (that checks the members are there). Statically: the assignments
in ``_conformance`` below, which never run; tests/test_static.py has mypy check this
module, and mypy compares every signature.
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from pathlib import Path

import cv2
import numpy as np
import pytest

from rig.clock import ManualClock, SystemClock
from rig.drivers.ati_netft import AtiNetFT
from rig.drivers.camera import Camera as CameraDriver
from rig.drivers.camera import FolderSource
from rig.drivers.ft300 import FT300
from rig.drivers.m8128 import M8128
from rig.drivers.pr_drive import PrDriveAxis
from rig.drivers.zaber import ZaberAxis
from rig.motion import Motion
from rig.rig import Rig
from rig.safety import ForceGuard
from rig.sim.rig_sim import SimulatedRig
from rig.types import Axis, Camera, ForceGauge, MotionSession, RigLike, StreamingGauge, WrenchGuard

GAUGES = {"ft300": FT300, "m8128": M8128, "ati_netft": AtiNetFT}


def _conformance(
    zaber: ZaberAxis,
    pr_drive: PrDriveAxis,
    ft300: FT300,
    m8128: M8128,
    netft: AtiNetFT,
    camera: CameraDriver,
    rig: Rig,
    motion: Motion,
    guard: ForceGuard,
) -> None:
    """Never called: mypy checks that each assignment is allowed (the drivers' signatures
    match the protocols'), which ``isinstance`` cannot."""
    axes: list[Axis] = [zaber, pr_drive]
    polled: list[ForceGauge] = [ft300, m8128, netft]
    streaming: list[StreamingGauge] = [ft300, m8128, netft]
    cameras: list[Camera] = [camera]
    rigs: list[RigLike] = [rig]
    sessions: list[MotionSession] = [motion]
    guards: list[WrenchGuard] = [guard]
    opened: AbstractContextManager[MotionSession] = rig.motion("type check")
    del axes, polled, streaming, cameras, rigs, sessions, guards, opened


@pytest.fixture(params=sorted(GAUGES))
def opened(request):
    """A rig on the simulators (Zaber x, y, z; PR-drive θ; the gauge kind; the simulated camera)."""
    clock = ManualClock()
    with SimulatedRig(clock, gauge=request.param) as sim, Rig.open(sim.config(), clock, camera=True, sim=sim) as rig:
        yield request.param, rig


def test_the_simulated_rig_satisfies_every_protocol(opened):
    kind, rig = opened
    assert isinstance(rig, RigLike)
    assert {type(a) for a in rig.axes.values()} == {ZaberAxis, PrDriveAxis}
    for axis in rig.axes.values():
        assert isinstance(axis, Axis), axis.label
    assert type(rig.gauge) is GAUGES[kind]
    assert isinstance(rig.gauge, ForceGauge) and isinstance(rig.gauge, StreamingGauge)
    assert isinstance(rig.camera, Camera)
    with rig.motion("conformance") as m:
        assert isinstance(m, MotionSession)
        assert isinstance(rig.guard, WrenchGuard)


FRAMES = [np.full((8, 8, 3), 40 * i, np.uint8) for i in range(3)]


@pytest.fixture
def recorded(tmp_path: Path) -> Path:
    for i, image in enumerate(FRAMES):
        cv2.imwrite(str(tmp_path / f"frame_{i}.png"), image)
    return tmp_path


def test_camera_over_a_folder_and_over_opencv_capture(recorded, tmp_path):
    """A folder of frames, and cv2.VideoCapture: open_v4l2 hands the camera one of those."""
    clip = str(tmp_path / "clip.avi")
    writer = cv2.VideoWriter(clip, cv2.VideoWriter.fourcc(*"MJPG"), 25, (8, 8))
    for image in FRAMES:
        writer.write(image)
    writer.release()
    for source in (FolderSource(recorded, SystemClock()), cv2.VideoCapture(clip)):
        camera = CameraDriver(source, SystemClock(), discard_frames=0)
        try:
            assert isinstance(camera, Camera)
            assert camera.read(timeout_s=2.0).image.shape == (8, 8, 3)
        finally:
            camera.close()


def test_a_class_missing_a_member_is_refused():
    """The run-time check means something: an axis without ``faults`` is not an Axis."""

    class NoFaults:
        name, unit, label = "x", "mm", "x (test)"

        def position(self) -> float:
            return 0.0

        status = move_to = stop = home = close = position

    assert not isinstance(NoFaults(), Axis)
