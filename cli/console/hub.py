"""The browsers connected to the console: delivery, control and frame statistics (asyncio side).

Delivery is latest-wins: a browser that draws slowly gets the newest frame and state, never
a backlog (wrench samples of skipped states are merged, not lost). A frame is sent only when
the browser has drawn the previous one (it posts back each frame's index and capture time),
so the frame rate is what the link and the page sustain, and the post-back measures the
capture-to-display latency.

Control: one browser at a time holds it (jog, home, zero); others see who holds it and are
refused with that reason. Stop is accepted from every browser: anyone watching may halt.
"""

from __future__ import annotations

import asyncio
import json
import math
import struct
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from cli.console.worker import FrameOut

FRAME_ACK_TIMEOUT_S = 1.0  # a page that never acks (hidden tab) still gets a frame a second
EVENTS_KEPT = 200  # per browser, while it is slow to read
LATENCIES_KEPT = 5000


@dataclass(eq=False)
class Client:
    send_text: Callable[[str], Any]
    send_bytes: Callable[[bytes], Any]
    peer: str
    since: float = field(default_factory=time.time)
    state: dict | None = None
    frame: FrameOut | None = None
    events: deque = field(default_factory=lambda: deque(maxlen=EVENTS_KEPT))
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    frame_sent_at: float | None = None  # monotonic time of the frame not yet acked
    wants_flow: bool = False  # marker-flow arrows asked for (marker sensors)
    flow: dict | None = None  # the newest marker flow not yet sent


def encode_frame(frame: FrameOut) -> bytes:
    """Binary message: u32 little-endian header length, the JSON header, the JPEG."""
    header = json.dumps({"index": frame.index, "t_s": frame.t_s, "width": frame.width, "height": frame.height}).encode()
    return struct.pack("<I", len(header)) + header + frame.jpeg


class Hub:
    def __init__(self, now: Callable[[], float]):
        self._now = now  # the rig clock: frame capture times are on it
        self.clients: set[Client] = set()
        self.controller: Client | None = None
        self.rig_status: dict | None = None  # who holds the rig (worker.rig_status), told to every page
        self.latencies_s: deque[float] = deque(maxlen=LATENCIES_KEPT)
        self.drawn_at: deque[float] = deque(maxlen=LATENCIES_KEPT)  # time.monotonic() of each ack

    # -- from the worker (through loop.call_soon_threadsafe) -----------------------------------
    def on_state(self, state: dict) -> None:
        for c in self.clients:
            pending = c.state
            if pending is not None and not state.get("reset_trace"):  # not yet sent: keep its wrench samples
                c.state = {
                    **state,
                    "wrench": pending["wrench"] + state["wrench"],
                    "reset_trace": bool(pending.get("reset_trace")),
                }
            else:
                c.state = state
            c.wake.set()

    def on_frame(self, frame: FrameOut) -> None:
        for c in self.clients:
            c.frame = frame
            c.wake.set()

    def on_flow(self, flow: dict) -> None:
        for c in self.clients:
            if c.wants_flow:
                c.flow = flow  # latest wins, as frames
                c.wake.set()

    def on_rig(self, status: dict) -> None:
        self.rig_status = status
        self.broadcast(status)

    def flow_wanted(self) -> int:
        return sum(c.wants_flow for c in self.clients)

    def on_event(self, level: str, text: str) -> None:
        self.broadcast({"type": "event", "level": level, "text": text, "at": time.strftime("%H:%M:%S")})

    def broadcast(self, message: dict) -> None:
        for c in self.clients:
            self.tell(c, message)

    def tell(self, client: Client, message: dict) -> None:
        client.events.append(message)
        client.wake.set()

    # -- clients --------------------------------------------------------------------------------
    def join(self, client: Client) -> None:
        self.clients.add(client)
        if self.rig_status is not None:
            self.tell(client, self.rig_status)
        self.tell(client, self.control_message(client))

    def leave(self, client: Client) -> None:
        self.clients.discard(client)
        if self.controller is client:
            self.controller = None
            self.announce_control()

    def control_message(self, client: Client) -> dict:
        holder = self.controller
        return {
            "type": "control",
            "you": holder is client,
            "holder": holder.peer if holder else None,
            "since": time.strftime("%H:%M:%S", time.localtime(holder.since)) if holder else None,
        }

    def announce_control(self) -> None:
        for c in self.clients:
            self.tell(c, self.control_message(c))

    def take_control(self, client: Client) -> str:
        """'' when ``client`` now holds control, else why not."""
        if self.controller is None or self.controller is client:
            self.controller = client
            client.since = time.time()
            self.announce_control()
            return ""
        holder = self.controller
        return (
            f"refused: another browser ({holder.peer}) holds control since "
            f"{time.strftime('%H:%M:%S', time.localtime(holder.since))}; one controller at a time"
        )

    def release_control(self, client: Client) -> None:
        if self.controller is client:
            self.controller = None
            self.announce_control()

    def frame_drawn(self, client: Client, t_s: float) -> None:
        if math.isfinite(t_s):  # a page's garbage must not poison the statistics
            self.latencies_s.append(self._now() - t_s)
        self.drawn_at.append(time.monotonic())
        client.frame_sent_at = None
        client.wake.set()

    async def pump(self, client: Client) -> None:
        """Send what is pending to ``client`` until its connection fails."""
        while True:
            try:
                await asyncio.wait_for(client.wake.wait(), FRAME_ACK_TIMEOUT_S)
            except TimeoutError:
                pass
            client.wake.clear()
            while client.events:
                await client.send_text(json.dumps(client.events.popleft()))
            if client.state is not None:
                state, client.state = client.state, None
                await client.send_text(json.dumps(state))
            if client.flow is not None:
                flow, client.flow = client.flow, None
                await client.send_text(json.dumps(flow))
            waiting = client.frame_sent_at is not None
            if client.frame is not None and (
                not waiting or time.monotonic() - (client.frame_sent_at or 0.0) > FRAME_ACK_TIMEOUT_S
            ):
                frame, client.frame = client.frame, None
                client.frame_sent_at = time.monotonic()
                await client.send_bytes(encode_frame(frame))

    def reset_stats(self) -> None:
        self.latencies_s.clear()
        self.drawn_at.clear()

    def stats(self) -> dict:
        """Frames drawn by the browsers, the frame rate over the last 5 s, latency percentiles (ms)."""
        import numpy as np

        now = time.monotonic()
        recent = [t for t in self.drawn_at if t > now - 5.0]
        fps = (len(recent) - 1) / (recent[-1] - recent[0]) if len(recent) > 2 and recent[-1] > recent[0] else 0.0
        lat = np.asarray(self.latencies_s, dtype=np.float64) * 1000.0
        pct = {f"p{p}": float(np.percentile(lat, p)) for p in (50, 95, 99)} if lat.size else {}
        return {
            "frames_drawn": len(self.drawn_at),
            "fps_5s": fps,
            "latency_ms": pct,
            "clients": len(self.clients),
        }
