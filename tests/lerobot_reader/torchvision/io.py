"""torchvision.io.VideoReader, the part the reader's "pyav" backend uses, implemented with PyAV.

Yields {"data": uint8 tensor (C, H, W) RGB, "pts": seconds} per frame, from the frame at or before the
time given to seek() (from the key frame before it when keyframes_only=True, as torchvision's pyav
backend does); see ledataset.datasets.video_utils.decode_video_frames_torchvision, which also closes
`reader.container` itself.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import av
import torch


class VideoReader:
    def __init__(self, src: str, stream: str = "video", num_threads: int = 0) -> None:
        if stream.split(":")[0] != "video":
            raise NotImplementedError(f"torchvision stub (tests/lerobot_reader): VideoReader({stream!r}): video only")
        self.container = av.open(str(src))
        self._stream = self.container.streams.video[0]
        self._seek_s = 0.0
        self._frames: Iterator[Any] | None = None

    def seek(self, time_s: float, keyframes_only: bool = False) -> VideoReader:
        tb = self._stream.time_base
        self.container.seek(int(time_s / tb), stream=self._stream, backward=True, any_frame=False)
        self._seek_s = -1.0 if keyframes_only else float(time_s)
        self._frames = None
        return self

    def __iter__(self) -> VideoReader:
        return self

    def __next__(self) -> dict[str, Any]:
        if self._frames is None:
            self._frames = self.container.decode(self._stream)
        while True:
            frame = next(self._frames)  # StopIteration ends the reading
            pts = float(frame.pts * self._stream.time_base)
            # torchvision's own pyav path skips frames before the seek time unless seeking to key frames only
            if pts + 1e-9 >= self._seek_s:
                data = torch.from_numpy(frame.to_ndarray(format="rgb24")).permute(2, 0, 1).contiguous()
                return {"data": data, "pts": pts}

    def get_metadata(self) -> dict[str, Any]:
        fps = float(self._stream.average_rate or 0)
        duration = float(self._stream.duration * self._stream.time_base) if self._stream.duration else 0.0
        return {"video": {"fps": [fps], "duration": [duration]}}

    def close(self) -> None:
        self.container.close()

    def __del__(self) -> None:
        try:
            self.container.close()
        except Exception:
            pass
