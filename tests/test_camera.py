"""The newest-frame camera over recorded frames and the simulated camera."""

import threading

import cv2
import numpy as np
import pytest

from rig.clock import ScaledClock, SystemClock
from rig.drivers.camera import Camera, FolderSource
from rig.errors import DeviceDisconnected, DeviceTimeout
from rig.sim.rig_sim import SimulatedRig


@pytest.fixture
def recorded(tmp_path):
    """A folder of 30 frames whose first pixel encodes the frame number."""
    for i in range(30):
        img = np.full((48, 64, 3), 100, np.uint8)
        img[0, 0] = (i, i, i)
        cv2.imwrite(str(tmp_path / f"frame_{i:03d}.png"), img)
    return tmp_path


class GatedSource:
    """Wraps a source so the test decides when each frame 'arrives' (no sleeping)."""

    def __init__(self, source):
        self.source = source
        self.gate = threading.Semaphore(0)

    def read(self):
        self.gate.acquire()
        return self.source.read()

    def release(self):
        self.source.release()
        self.gate.release(100)  # unblock a read waiting at the gate


def frame_number(frame):
    return int(frame.image[0, 0, 0])


def test_first_frames_discarded_and_never_stale(recorded):
    src = GatedSource(FolderSource(recorded, SystemClock()))
    cam = Camera(src, SystemClock(), discard_frames=3)
    src.gate.release(5)  # frames 0..4 arrive; 0..2 are discarded
    assert cam.wait_arrived(5, timeout_s=2.0)
    newest = cam.read(timeout_s=1.0)
    assert frame_number(newest) == 4  # frame 3 was superseded before we asked
    with pytest.raises(DeviceTimeout):  # nothing new arrived: no stale frame is returned again
        cam.read(timeout_s=0.1)
    src.gate.release(3)  # three more arrive before we read: we get the newest, skipping the others
    assert cam.wait_arrived(8, timeout_s=2.0)
    f = cam.read(timeout_s=1.0)
    assert frame_number(f) == 7 and f.t_s >= newest.t_s and f.index > newest.index
    cam.close()


def test_end_of_recording_is_reported(recorded):
    cam = Camera(FolderSource(recorded, SystemClock()), SystemClock(), discard_frames=0)
    seen = []
    with pytest.raises(DeviceDisconnected, match="ended"):
        for _ in range(100):
            seen.append(frame_number(cam.read(timeout_s=1.0)))
    assert seen == sorted(set(seen)) and seen[-1] == 29  # increasing, no duplicates, reaches the end
    cam.close()


def test_folder_errors_name_the_path(tmp_path):
    with pytest.raises(FileNotFoundError, match="no images"):
        FolderSource(tmp_path, SystemClock())
    with pytest.raises(FileNotFoundError, match="not a folder"):
        FolderSource(tmp_path / "missing", SystemClock())


def test_video_file_through_the_same_camera(recorded, tmp_path):
    path = str(tmp_path / "clip.avi")
    writer = cv2.VideoWriter(path, cv2.VideoWriter_fourcc(*"MJPG"), 25, (64, 48))
    for p in sorted(recorded.glob("*.png")):
        writer.write(cv2.imread(str(p)))
    writer.release()
    cam = Camera(cv2.VideoCapture(path), SystemClock(), discard_frames=2)
    f = cam.read(timeout_s=2.0)
    assert f.image.shape == (48, 64, 3)
    cam.close()


def test_simulated_camera_sees_contact():
    clock = ScaledClock(10.0)
    with SimulatedRig(clock) as sim:
        cam = Camera(sim.camera_source(fps=25, height=128, width=128), clock, discard_frames=1)
        free = cam.read(timeout_s=2.0).image.astype(float)
        sim.world.stages["z"]._pos = sim.world.spec.geometry["z"].origin + 1.0
        f = cam.read(timeout_s=2.0)
        pressed = cam.read(timeout_s=2.0).image.astype(float)
        cam.close()
    assert np.abs(pressed - free).mean() > 1.0  # the contact shows in the frame
    assert f.t_s < clock.now()


class SlowRenderSource:
    """A source that renders on trigger (as the simulated camera on the discrete-event clock) whose
    first frames take as long as the test says: each read waits at a gate the test opens."""

    triggered = True
    renders_on_trigger = True

    def __init__(self):
        self.gate = threading.Semaphore(0)
        self.count = 0

    def read(self):
        self.gate.acquire()
        self.count += 1
        return True, np.full((8, 8, 3), self.count, np.uint8)

    def release(self):
        self.gate.release(100)


def test_a_rendering_camera_waits_for_its_dropped_first_frames_and_never_hands_out_one_of_them():
    source = SlowRenderSource()
    cam = Camera(source, SystemClock(), name="simulated camera", discard_frames=3)
    try:
        cam.render_wait_s = 0.0  # the first frames still rendering: one line naming it, not a dropped frame
        with pytest.raises(DeviceTimeout, match="3 frames dropped after opening took over 0 s"):
            cam.trigger()
        cam.render_wait_s = 60.0
        source.gate.release(4)  # the three dropped frames, then the one the trigger renders
        cam.trigger()
        frame = cam.read(timeout_s=5.0)
        assert frame.index == 0 and int(frame.image[0, 0, 0]) == 4  # the fourth rendered: the first kept
    finally:
        cam.close()
