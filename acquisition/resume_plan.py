"""Where ``--resume`` starts again: the beginning of the level it interrupted (docs/run-file.md,
"Resuming a run").

An interruption lifts z off the gel (rig/lift.py), and with it goes the gel's stick/slip state: a
shear or twist continued from the middle of a level after that is a different press (one such
resume met Fy -10 N against a limit the original run never neared). So a resume goes back to the
first step of the level that was running (its press), presses there again from the gel's surface
along the protocol's vertical path, and records that level anew from its first capture. The frames
the interrupted level had committed are not mixed with the new ones: the run file moves them into
``superseded/retake-N`` (acquisition/run_resume.py) and marks the frames that replace them with
``retake = N``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from acquisition import schema as S
from acquisition.writer_lock import RunFileError
from protocols.plan import Plan, Step


@dataclass(frozen=True)
class Restart:
    k: int  # the first capture index taken again (the frames kept before it)
    k_before: int  # the frames the file had: captures k .. k_before - 1 are retaken
    step: Step  # the captured step the run starts again with: its level's first
    t_s: float  # that step's start, protocol time
    level: int

    @property
    def retaken(self) -> int:
        return self.k_before - self.k

    def why(self, reason: str) -> str:
        return (
            f"captures {self.k}..{self.k_before - 1} of level {self.level} were taken before the run stopped "
            f"({_reason(reason)}); lifting off the gel lost its stick/slip state, so the resume "
            f"pressed level {self.level} again from its start"
        )


def restart_point(plan: Plan, frames: int) -> Restart:
    """Where a run whose file holds ``frames`` (captures 0 .. frames-1) starts again."""
    captured = plan.captured_steps
    starts, t = [], 0.0
    for step in captured:
        starts.append(t)
        t += step.duration_s
    if frames == 0:
        return Restart(0, 0, captured[0], 0.0, captured[0].level)
    # the level in progress just after the last committed capture: the one the interruption broke
    running, _ = plan.locate(plan.capture_time(frames - 1) + 1e-6)
    first = next(i for i, step in enumerate(captured) if step.level == running.level)
    t_start = starts[first]
    k = min(frames, math.ceil(t_start * plan.protocol.capture_hz - 1e-9))
    return Restart(k, frames, captured[first], t_start, running.level)


def _text(value) -> str:
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)


def superseder(plan: Plan, path: Path, same_protocol, found: dict, reason: str = ""):
    """The ``supersede`` callback of ``RunWriter.reopen``: refuses a file of another protocol before
    anything in it changes; else keeps the frames before the interrupted level (``found["restart"]``
    says where the run starts again)."""

    def supersede(frames: int, attrs: dict) -> tuple[int, str]:
        recorded = _text(attrs.get(S.ATTR_PROTOCOL, ""))
        if recorded != plan.protocol.text and not same_protocol(recorded, plan.protocol, path):
            raise RunFileError(
                f"{path}: was recorded with a different protocol (another setting than now); "
                "resume needs the same settings"
            )
        if frames >= plan.frame_count:  # finished: nothing to take again
            found["restart"] = None
            return frames, ""
        restart = restart_point(plan, frames)
        found["restart"] = restart
        return restart.k, restart.why(reason)

    return supersede


def _reason(reason: str) -> str:
    """Why the run stopped, without its status word again ("interrupted (SIGINT)…" → "SIGINT…")."""
    from common.wording import reason_only

    return reason_only("interrupted", reason) or "no reason recorded"
