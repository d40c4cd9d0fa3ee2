"""The tactile camera's frames as video files (PyAV): which codecs, how each is written and read back.

``lossless`` is H.264 in its RGB profile at quantiser 0 (``libx264rgb``, ``qp=0``): every decoded pixel
equals the run file's, which export checks frame by frame. ``av1`` is the ecosystem's default (SVT-AV1,
``crf=30``, 4:2:0 chroma) and ``h264`` the common lossy H.264 (``crf=23``, 4:2:0): a tenth to a hundredth of
the size, and an error export measures and reports (mean squared error against the run's frames).
Every file puts a keyframe every 2 frames (``g=2``), as the ecosystem does, so a reader seeking one
frame decodes at most two.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from common.errors import ToolError
from common.scheduling import kept_normal


class VideoError(ToolError):
    pass


@dataclass(frozen=True)
class Codec:
    name: str  # what --codec takes
    encoder: str  # FFmpeg's encoder
    pix_fmt: str  # the pixels the encoder is given
    options: dict
    lossless: bool
    info_codec: str  # info.json's video.codec, as ffprobe names the stream
    info_pix_fmt: str  # info.json's video.pix_fmt: what a decoder gives back


CODECS = {
    c.name: c
    for c in (
        Codec("lossless", "libx264rgb", "rgb24", {"qp": "0", "g": "2", "preset": "veryfast"}, True, "h264", "gbrp"),
        Codec("av1", "libsvtav1", "yuv420p", {"crf": "30", "g": "2", "preset": "8"}, False, "av1", "yuv420p"),
        Codec("h264", "libx264", "yuv420p", {"crf": "23", "g": "2", "preset": "veryfast"}, False, "h264", "yuv420p"),
    )
}
DEFAULT_CODEC = "lossless"


def codec(name: str) -> Codec:
    if name not in CODECS:
        raise VideoError(f"--codec {name!r}: expected one of {', '.join(CODECS)}")
    return CODECS[name]


def write_video(path: Path, frames_bgr: Iterable[np.ndarray], fps: int, chosen: Codec) -> int:
    """Frames (H, W, 3) uint8 BGR, as the run file holds them, into an MP4 at ``fps``; the frame count.
    Frame i has presentation time i / fps s."""
    import av

    os.environ.setdefault("SVT_LOG", "1")  # SVT-AV1 prints its configuration to stderr unless told: errors only
    n = 0
    # SVT-AV1 switches the thread that opens it, and so its own threads, to real-time priority when it may
    # (common/scheduling.py): put back on the normal policy once made, and again at the end
    with kept_normal() as settle:
        container = av.open(str(path), mode="w", format="mp4")
        try:
            stream: Any = None  # the video stream, made once the first frame gives its size
            for frame in frames_bgr:
                if stream is None:
                    stream = container.add_stream(chosen.encoder, rate=fps, options=dict(chosen.options))
                    stream.height, stream.width = frame.shape[:2]
                    stream.pix_fmt = chosen.pix_fmt
                picture = av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="bgr24")
                picture.pts = n
                for packet in stream.encode(picture):
                    container.mux(packet)
                if n == 0:
                    settle()  # the encoder is open and its threads made
                n += 1
            if stream is not None:
                for packet in stream.encode():
                    container.mux(packet)
        finally:
            container.close()
    return n


def read_video(path: Path) -> Iterator[np.ndarray]:
    """The frames of ``path`` in order, (H, W, 3) uint8 BGR; VideoError naming the file when it cannot be
    decoded (truncated, not a video)."""
    import av

    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise VideoError(f"{path}: holds no video stream")
            for picture in container.decode(video=0):
                yield picture.to_ndarray(format="bgr24")
    except (av.FFmpegError, OSError, EOFError) as exc:
        raise VideoError(f"{path}: cannot be decoded ({getattr(exc, 'strerror', None) or exc})") from None


@dataclass(frozen=True)
class VideoInfo:
    frames: int
    height: int
    width: int
    codec: str
    pix_fmt: str
    fps: float


def probe(path: Path) -> VideoInfo:
    """What the container says of its video stream, and the frames counted by decoding each one (a
    truncated file has fewer than its header promises)."""
    import av

    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise VideoError(f"{path}: holds no video stream")
            s = container.streams.video[0]
            ctx = s.codec_context
            rate = float(s.average_rate) if s.average_rate else 0.0
            head = (ctx.height, ctx.width, ctx.name, ctx.pix_fmt or "", rate)
            n = sum(1 for _ in container.decode(video=0))
    except (av.FFmpegError, OSError, EOFError) as exc:
        raise VideoError(f"{path}: cannot be decoded ({getattr(exc, 'strerror', None) or exc})") from None
    return VideoInfo(n, head[0], head[1], head[2], head[3], head[4])
