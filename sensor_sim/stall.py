"""When an iterative contact solve has stopped making progress.

Both solvers (normal: Polonsky–Keer conjugate gradient; tangential: FISTA) stop
improving at the float32 floor long before their iteration cap. A solve counts as
stalled when its residual has not halved in ``patience`` iterations; the solver then
goes on in float64, and stops with ``converged=False`` if it stalls there too.
"""

from __future__ import annotations

import math

HALVING = 0.5  # progress means the residual fell to this fraction of the last mark


class StallWatch:
    def __init__(self, patience: int):
        self.patience = patience
        self.mark, self.mark_at = math.inf, 0  # the last residual that halved the one before, and when

    def stalled(self, residual: float, it: int) -> bool:
        """Record iteration ``it``'s residual; True when none halved the mark for ``patience`` iterations."""
        if residual < HALVING * self.mark:
            self.mark, self.mark_at = residual, it
            return False
        return it - self.mark_at >= self.patience

    def restart(self, residual: float, it: int) -> None:
        """Count afresh from here (after switching precision)."""
        self.mark, self.mark_at = residual, it
