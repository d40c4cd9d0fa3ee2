"""The simulated tactile camera: frames rendered from the world at ``fps`` on the clock.

Each frame solves the contact at the world's current pose (sharing the gauge's solve
when the pose has not moved) and renders it with the sensor's optics. A world whose
contact model has no fields (the spring placeholder) shows the no-contact frame.
``CameraStreamServer`` serves such frames over loopback TCP for `rig sim serve`.
"""

from __future__ import annotations

import dataclasses
import socket
import threading

from rig.clock import Clock
from rig.drivers.camera_stream import REQUEST, SCHEME, encode_frame
from rig.sim.world import SimWorld
from sensor_sim.light import OpticsSpec
from sensor_sim.optics import Renderer


class SimCameraSource:
    """A capture source (``read``/``release``) producing frames at ``fps`` of clock time."""

    def __init__(
        self,
        world: SimWorld,
        clock: Clock,
        *,
        fps: float = 25.0,
        height: int = 256,
        width: int = 256,
        kind: str = "rgb",
        noise_std: float = 1.0,
        seed: int = 0,
        triggered: bool = False,
        profile=None,
    ):
        """``profile`` (a SensorProfile): its optics, background, noise and markers; None: the
        shipped default's optics with ``noise_std``. The frame is ``width`` × ``height`` over the
        contact model's pad (a profile's frame need not be square)."""
        self.world = world
        self.clock = clock
        self.period_s = 1.0 / fps
        solver = getattr(world.contact, "solver", None)
        geometry = solver.geometry if solver is not None else None
        spec = (
            OpticsSpec(kind=kind, height_px=height, width_px=width, noise_std=noise_std)
            if profile is None
            else dataclasses.replace(profile.optics_spec(kind), height_px=height, width_px=width)
        )
        self.renderer = Renderer(spec, geometry, seed=seed, profile=profile)
        self._next_t: float | None = None
        self._released = False
        self.triggered = triggered  # render only when the Camera is triggered (acquisition)
        self.last_exposure_s: float | None = None

    @property
    def renders_on_trigger(self) -> bool:
        """Triggered on the discrete-event clock: the camera driver may render in the
        triggering thread (rig/drivers/camera.py), the frame is of that instant anyway."""
        return self.triggered and hasattr(self.clock, "add_listener")

    def render_now(self):
        self.last_exposure_s = self.clock.now()
        contact = self.world.contact
        if not hasattr(contact, "solve"):
            return self.renderer.render({})
        result = contact.solve(self.world.pose(), self.renderer.needs())
        return self.renderer.render(result.fields)

    def read(self):
        if self._released:
            return False, None
        if self.triggered:
            return True, self.render_now()
        now = self.clock.now()
        if self._next_t is None:
            self._next_t = now
        self.clock.sleep(self._next_t - now)
        self._next_t += self.period_s
        return True, self.render_now()

    def settings(self) -> dict:
        """A rendered camera's exposure and white balance never drift."""
        return {"fps": 1.0 / self.period_s, "exposure_locked": True, "white_balance_locked": True}

    def release(self) -> None:
        self._released = True


class CameraStreamServer:
    """Serves a source's frames over loopback TCP (rig/drivers/camera_stream.py's protocol):
    one frame rendered per ``F`` received, to any number of clients, each in a thread."""

    def __init__(self, source: SimCameraSource, host: str = "127.0.0.1"):
        self.source = source
        self._render_lock = threading.Lock()  # one renderer, shared by the clients
        self._listener = socket.create_server((host, 0))
        self.url = f"{SCHEME}{host}:{self._listener.getsockname()[1]}"
        self.frames_sent = 0
        self._stop = threading.Event()
        self._clients: list[socket.socket] = []
        self._thread = threading.Thread(target=self._accept, name="sim-camera", daemon=True)
        self._thread.start()

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except OSError:
                return  # the listener was closed
            self._clients.append(conn)
            threading.Thread(target=self._serve, args=(conn,), name="sim-camera-client", daemon=True).start()

    def _serve(self, conn: socket.socket) -> None:
        with conn:
            while not self._stop.is_set():
                try:
                    request = conn.recv(1)
                except OSError:
                    return
                if request != REQUEST:
                    return  # the client left, or spoke another protocol: drop it
                with self._render_lock:
                    image = self.source.render_now()
                    number = self.frames_sent
                    self.frames_sent += 1
                try:
                    conn.sendall(encode_frame(image, number))
                except OSError:
                    return

    def close(self) -> None:
        self._stop.set()
        try:
            self._listener.shutdown(socket.SHUT_RDWR)  # wakes the accept() in progress (Linux)
        except OSError:
            pass  # not every platform lets a listener be shut down; close() below still ends it
        self._listener.close()
        for conn in self._clients:
            try:
                conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass  # the client already left
        self._thread.join(timeout=2.0)
