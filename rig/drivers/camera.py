"""Tactile camera: a newest-frame grabber over any OpenCV-style capture source.

OpenCV's V4L2 backend queues about four buffers, so reading on demand returns a
stale frame. A grabber thread reads continuously and keeps only the newest frame,
stamped with the host clock at arrival; ``read`` returns a frame never returned
before. The same class reads recorded frames (``FolderSource``, a video file through
``cv2.VideoCapture``) and the simulated camera.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from rig.clock import Clock
from rig.errors import DeviceDisconnected, DeviceTimeout
from rig.types import Frame

log = logging.getLogger("rig.camera")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


class CaptureSource(Protocol):
    """The part of ``cv2.VideoCapture`` the camera uses."""

    def read(self) -> tuple[bool, np.ndarray | None]: ...

    def release(self) -> None: ...


class FolderSource:
    """Frames from a folder of images in name order, at ``fps`` on ``clock`` (0: as fast as read)."""

    def __init__(self, folder: str | Path, clock: Clock, *, fps: float = 0.0, loop: bool = False):
        import cv2

        self._cv2 = cv2
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise FileNotFoundError(f"recorded frames: {self.folder} is not a folder")
        self.paths = sorted(p for p in self.folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not self.paths:
            raise FileNotFoundError(f"recorded frames: no images ({', '.join(IMAGE_SUFFIXES)}) in {self.folder}")
        self.clock = clock
        self.period_s = 1.0 / fps if fps > 0 else 0.0
        self.loop = loop
        self._i = 0
        self._next_t: float | None = None

    def read(self) -> tuple[bool, np.ndarray | None]:
        if self._i >= len(self.paths):
            if not self.loop:
                return False, None
            self._i = 0
        if self.period_s:
            now = self.clock.now()
            if self._next_t is None:
                self._next_t = now
            self.clock.sleep(self._next_t - now)
            self._next_t += self.period_s
        image = self._cv2.imread(str(self.paths[self._i]), self._cv2.IMREAD_COLOR)
        self._i += 1
        if image is None:
            raise ValueError(f"recorded frames: cannot decode {self.paths[self._i - 1]}")
        return True, image

    def settings(self) -> dict:
        return {"fps": 1.0 / self.period_s if self.period_s else None}  # recorded: nothing to lock

    def release(self) -> None:
        self._i = len(self.paths)
        self.loop = False


def open_v4l2(
    device: str | int,
    *,
    width: int,
    height: int,
    fps: float,
    exposure: float | None,
    white_balance_K: float | None,
    fourcc: str = "MJPG",
):
    """Open a UVC camera through OpenCV's V4L2 backend with exposure and white balance locked.

    Thin on purpose: everything else (grabbing, stamping, discarding) is in ``Camera``.
    Raises DeviceDisconnected if the device cannot be opened.
    """
    import cv2

    cap = cv2.VideoCapture(device, cv2.CAP_V4L2)
    if not cap.isOpened():
        raise DeviceDisconnected(
            f"camera {device}",
            "open",
            None,
            "cannot open V4L2 device (is it plugged in, and are you in group 'video'?)",
        )
    cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*fourcc))
    cap.set(cv2.CAP_PROP_FRAME_WIDTH, width)
    cap.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
    cap.set(cv2.CAP_PROP_FPS, fps)
    cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
    if exposure is not None:
        cap.set(cv2.CAP_PROP_AUTO_EXPOSURE, 1)  # V4L2: 1 = manual, 3 = aperture priority (auto)
        cap.set(cv2.CAP_PROP_EXPOSURE, exposure)
    if white_balance_K is not None:
        cap.set(cv2.CAP_PROP_AUTO_WB, 0)
        cap.set(cv2.CAP_PROP_WB_TEMPERATURE, white_balance_K)
    return cap


@dataclass(frozen=True)
class CameraReport:
    """What `rig status` says about a camera before a run."""

    width_px: int
    height_px: int
    fps: float | None  # what the source says it delivers (None: it does not say)
    exposure_locked: bool | None  # None: not applicable or not reported (recorded frames)
    white_balance_locked: bool | None
    newest_age_s: float  # clock seconds since the newest frame arrived
    frames_arrived: int


def source_settings(source) -> dict:
    """fps and whether exposure and white balance are locked, as the source reports them.

    An OpenCV V4L2 capture is asked (CAP_PROP_AUTO_EXPOSURE: 1 manual, 3 aperture
    priority, or 0.25 / 0.75 on older backends; CAP_PROP_AUTO_WB: 0 off); other sources
    say it themselves (``settings()``) or not at all.
    """
    if hasattr(source, "settings"):
        return source.settings()
    if hasattr(source, "get") and getattr(source, "getBackendName", lambda: "")() == "V4L2":
        import cv2

        return {
            "fps": source.get(cv2.CAP_PROP_FPS) or None,
            "exposure_locked": source.get(cv2.CAP_PROP_AUTO_EXPOSURE) in (1.0, 0.25),
            "white_balance_locked": source.get(cv2.CAP_PROP_AUTO_WB) == 0.0,
        }
    if hasattr(source, "get"):  # a video file
        import cv2

        return {"fps": source.get(cv2.CAP_PROP_FPS) or None}
    return {}


RENDER_WAIT_S = 120.0  # a rendering source's dropped first frames: computed, so bounded by the machine, not a device


class Camera:
    """Newest-frame camera over a capture source; the first ``discard_frames`` are dropped."""

    def __init__(self, source: CaptureSource, clock: Clock, *, name: str = "camera", discard_frames: int = 5):
        self.source = source
        self.clock = clock
        self.name = name
        self.discard_frames = discard_frames
        self._cond = threading.Condition()
        self._newest: Frame | None = None
        self._returned = -1
        self._arrived = 0
        self.error: Exception | None = None
        self.ended = False
        self._stop = threading.Event()
        # A source with ``triggered = True`` (the simulated camera) makes a frame only
        # when asked, as a hardware-triggered camera does; free-running ones ignore it.
        self.triggered = bool(getattr(source, "triggered", False))
        self._trigger = threading.Semaphore(discard_frames if self.triggered else 0)
        self._reading = threading.Lock()  # one source read at a time (the grabber, or a trigger that renders)
        self.render_wait_s = RENDER_WAIT_S
        self._thread = threading.Thread(target=self._grab, name=f"grab-{name}", daemon=True)
        self._thread.start()

    def trigger(self) -> None:
        """Ask a triggered source for one frame; a no-op for free-running cameras.

        A source that renders on trigger (the simulated camera on the discrete-event clock)
        makes the frame here, in the calling thread: the frame is of this instant either
        way, and handing it to the grabber thread and back only costs two thread switches.
        """
        if not self.triggered:
            return
        if getattr(self.source, "renders_on_trigger", False) and not self.ended and self.error is None:
            # the frames dropped after opening come from the grabber first, so they stay the dropped ones;
            # they are rendered, so a loaded machine takes seconds over them: wait for them (bounded), since a
            # frame taken before they are all in would itself be dropped and the reader left without one
            if not self.wait_arrived(self.discard_frames, timeout_s=self.render_wait_s):
                raise DeviceTimeout(
                    self.name,
                    "render the first frames",
                    None,
                    f"the {self.discard_frames} frames dropped after opening took over {self.render_wait_s:g} s",
                )
            self._take_one()
            return
        self._trigger.release()

    def _grab(self) -> None:
        while not self._stop.is_set():
            if self.triggered and not self._trigger.acquire(timeout=0.1):
                continue
            if not self._take_one():
                return

    def _take_one(self) -> bool:
        """Read one frame from the source and publish it; False once the source failed or ended."""
        with self._reading:
            try:
                ok, image = self.source.read()
            except Exception as exc:  # kept and raised to the reader; never swallowed
                with self._cond:
                    self.error = exc
                    self._cond.notify_all()
                return False
            # Prefer the source's exposure time (the simulator knows it); else arrival.
            t = getattr(self.source, "last_exposure_s", None) or self.clock.now()
        if not ok or image is None:
            with self._cond:
                self.ended = True
                self._cond.notify_all()
            return False
        with self._cond:
            self._arrived += 1
            self._cond.notify_all()
            if self._arrived <= self.discard_frames:
                return True  # first frames after opening are dark or not yet exposed
            index = self._newest.index + 1 if self._newest else 0
            self._newest = Frame(t_s=t, index=index, image=image)
            self._cond.notify_all()
        return True

    def read(self, timeout_s: float = 1.0) -> Frame:
        """The newest frame not returned before. Raises DeviceTimeout or DeviceDisconnected."""
        with self._cond:
            fresh = lambda: (
                (self._newest is not None and self._newest.index > self._returned) or self.error or self.ended
            )
            if not self._cond.wait_for(fresh, timeout=timeout_s):
                raise DeviceTimeout(self.name, "read frame", None, f"no new frame within {timeout_s:g} s")
            if self._newest is not None and self._newest.index > self._returned:
                self._returned = self._newest.index
                return self._newest
            if self.error is not None:
                raise DeviceDisconnected(self.name, "read frame", None, f"capture failed: {self.error}")
            raise DeviceDisconnected(
                self.name, "read frame", None, "the capture source ended (camera unplugged or end of recording)"
            )

    def report(self, timeout_s: float = 2.0) -> CameraReport:
        """Take a frame and report resolution, fps, locks and the newest frame's age.
        Raises DeviceTimeout or DeviceDisconnected as ``read`` does."""
        self.trigger()
        frame = self.read(timeout_s)
        settings = source_settings(self.source)
        height, width = frame.image.shape[:2]
        return CameraReport(
            width_px=width,
            height_px=height,
            fps=settings.get("fps"),
            exposure_locked=settings.get("exposure_locked"),
            white_balance_locked=settings.get("white_balance_locked"),
            newest_age_s=max(0.0, self.clock.now() - frame.t_s),
            frames_arrived=self._arrived,
        )

    @property
    def frames_arrived(self) -> int:
        return self._arrived

    def wait_arrived(self, n: int, timeout_s: float) -> bool:
        """Block (bounded) until ``n`` frames have arrived since opening, discarded ones included."""
        with self._cond:
            return self._cond.wait_for(lambda: self._arrived >= n, timeout=timeout_s)

    def close(self) -> None:
        # Let the grabber leave read() before releasing: cv2.VideoCapture is not
        # thread-safe, and releasing it under a read deadlocks. A source that blocks
        # for longer (a stalled device) is released anyway to unblock it.
        self._stop.set()
        self._thread.join(timeout=1.0)
        if self._thread.is_alive():
            log.warning("%s: grabber still waiting for a frame; releasing the source under it", self.name)
        self.source.release()
        self._thread.join(timeout=2.0)
