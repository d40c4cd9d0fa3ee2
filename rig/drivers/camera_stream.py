"""A camera whose frames come over a loopback (or LAN) TCP socket: what `rig sim serve`
serves for its simulated tactile camera, so a config can name it like any camera.

The protocol is the project's own and tiny. The host sends one byte ``F`` per frame it
wants; the server answers with a 20-byte header ``>4sIIII`` -- magic ``TFR1``, height,
width, channels (3: BGR, as OpenCV), the server's frame number -- and height × width ×
channels bytes of uint8 pixels, row-major. The host stamps a frame at arrival, as it
does a V4L2 frame. Frames are asked for at the config's fps on the host's clock.
"""

from __future__ import annotations

import socket
import struct

import numpy as np

from rig.clock import Clock
from rig.errors import DeviceDisconnected, DeviceTimeout, FramingError

REQUEST = b"F"
MAGIC = b"TFR1"
HEADER = struct.Struct(">4sIIII")
MAX_SIDE_PX = 8192  # the config's own bound on width and height
SCHEME = "tcp://"


def encode_frame(image: np.ndarray, number: int) -> bytes:
    """Header and pixels of one frame (the server's side; tests)."""
    image = np.ascontiguousarray(image, dtype=np.uint8)
    height, width, channels = image.shape
    return HEADER.pack(MAGIC, height, width, channels, number & 0xFFFFFFFF) + image.tobytes()


def decode_header(header: bytes, device: str) -> tuple[int, int, int, int]:
    """(height, width, channels, number); FramingError on a wrong magic or impossible size."""
    magic, height, width, channels, number = HEADER.unpack(header)
    if magic != MAGIC or not (1 <= height <= MAX_SIDE_PX and 1 <= width <= MAX_SIDE_PX and channels in (1, 3)):
        raise FramingError(
            device, "F", header, "not a camera-stream frame header (magic TFR1, sides 1-8192, 1 or 3 channels)"
        )
    return height, width, channels, number


def parse_address(url: str) -> tuple[str, int]:
    """``tcp://HOST:PORT`` -> (host, port); ValueError naming the expected form."""
    rest = url[len(SCHEME) :] if url.startswith(SCHEME) else None
    host, _, port = (rest or "").rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"camera stream address must be tcp://HOST:PORT, got {url!r}")
    return host, int(port)


class StreamSource:
    """A capture source (``read``/``release``) asking a camera-stream server for frames at ``fps``."""

    def __init__(
        self, url: str, clock: Clock, *, fps: float, timeout_s: float = 2.0, size: tuple[int, int] | None = None
    ):
        self.url = url
        self.name = f"camera stream {url}"
        self.clock = clock
        self.period_s = 1.0 / fps
        self.size = size  # (height, width) the config expects; a server sending another is refused
        self._next_t: float | None = None
        self._released = False
        host, port = parse_address(url)
        try:
            self.sock = socket.create_connection((host, port), timeout=timeout_s)
        except OSError as exc:
            raise DeviceDisconnected(
                self.name, "connect", None, f"cannot connect ({exc.strerror or exc}); is `rig sim serve` running?"
            ) from None
        self.sock.settimeout(timeout_s)

    def settings(self) -> dict:
        """What `rig status` reports: a rendered camera's exposure and white balance never drift."""
        return {"fps": 1.0 / self.period_s, "exposure_locked": True, "white_balance_locked": True}

    def _recv(self, n: int) -> bytes:
        chunks: list[bytes] = []
        got = 0
        while got < n:
            try:
                chunk = self.sock.recv(min(n - got, 1 << 20))
            except socket.timeout:
                raise DeviceTimeout(self.name, "F", b"".join(chunks), f"{got} of {n} bytes") from None
            except OSError as exc:
                raise DeviceDisconnected(self.name, "F", None, f"connection failed: {exc}") from None
            if not chunk:
                raise DeviceDisconnected(self.name, "F", b"".join(chunks)[:32], "the server closed the connection")
            chunks.append(chunk)
            got += len(chunk)
        return b"".join(chunks)

    def read(self) -> tuple[bool, np.ndarray | None]:
        if self._released:
            return False, None
        now = self.clock.now()
        if self._next_t is None:
            self._next_t = now
        self.clock.sleep(self._next_t - now)
        self._next_t = max(self._next_t + self.period_s, self.clock.now())  # a slow frame does not cause a burst
        try:
            self.sock.sendall(REQUEST)
        except OSError as exc:
            if self._released:
                return False, None
            raise DeviceDisconnected(self.name, "F", None, f"connection failed: {exc}") from None
        height, width, channels, _ = decode_header(self._recv(HEADER.size), self.name)
        if self.size is not None and (height, width) != self.size:
            raise FramingError(
                self.name,
                "F",
                None,
                f"the server sends {width}x{height} frames but the config's "
                f"[camera] width x height is {self.size[1]}x{self.size[0]}",
            )
        pixels = np.frombuffer(self._recv(height * width * channels), dtype=np.uint8)
        return True, pixels.reshape(height, width, channels)

    def release(self) -> None:
        self._released = True
        try:
            self.sock.shutdown(socket.SHUT_RDWR)  # unblocks a grabber waiting in recv
        except OSError:
            pass  # already closed by the peer: nothing left to unblock
        self.sock.close()
