"""The sink table (profile format 5): per channel a table U(n) of the colour change per mm of sink at each
surface normal, fitted on what the light's other terms leave (issue 40, the contact's centre).

    terms, table = fit_alternating(samples, fit_terms, bins, crease)  # the light's other terms and U (3, N, N)
    sink_table_choice(samples, bins, crease)                          # whether leaving presses out says it helps

Why: the tables T(n) are one function of the normal, but the same normals lie in two places around a ball:
inside the contact (the gel pressed in by its full depth) and in the gel around it (barely pressed). Measured
on the original GelSight's five spread presses at their fitted contacts, the real change per unit of normal
at |n| 0.05-0.15 is blue 44, green 56, red 77 grey levels inside 0.6 contact radii and 80, 99, 106 in the
gel beyond 1.1 radii; one table gives both 61, 72, 85. s·U(n) lets the pressed-in gel answer a tilt
differently. Fitted on what the other terms leave, then those terms again on what U leaves, in turns (the
order and its choices are those without it), with the tables' own smoothness and crease penalty, the flat
entry held at 0 (the sink terms hold the flat normal's sink change). numpy/scipy only.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from sensor_sim.light_fit import (
    SMOOTHING,
    LightTerms,
    PressSamples,
    _Design,
    _low_rank_change,
    _normal,
    _smoothness,
    _solve,
)

# The other terms refitted on the change less s·U, then U on what they leave, this many times after the first U:
# the original GelSight's spread five, blind near / centre 20.2 / 34.0 % with none, 19.9 / 33.5 % with 2, 20.0 /
# 33.7 % with 4; one quadrant top-left k = 3: 28.6 / 57.2, 28.4 / 57.5, 28.3 / 57.5 % (20.4 / 36.1 and 28.4 /
# 61.7 % without U).
SINK_TABLE_ROUNDS = 2


def residual(s: PressSamples, terms: LightTerms) -> np.ndarray:
    """(n, 3) the change over the shading that ``terms`` leave unexplained at the samples."""
    position = terms.position if terms.position is not None else np.zeros((3, 2, *terms.table.shape[1:]))
    return s.target / s.shade - _low_rank_change(s, terms.table, position, terms.sink)


def _rows(design: _Design, s: PressSamples) -> sp.csr_matrix:
    """The press's rows of U: its table lookups times its sink (mm)."""
    return (sp.diags(s.sink) @ design.tables_of(design.matrix(s))).tocsr()


def fit_sink_table(samples: list[PressSamples], residuals: list[np.ndarray], bins: int, crease: float) -> np.ndarray:
    """(3, bins, bins) U: each pixel's residual (n, 3) explained as its sink times U at its normal (weighted
    least squares, the tables' smoothness and crease penalty ``crease``), clipped to ±1000 grey levels per mm."""
    design = _Design(bins, crease)
    G = None
    b = np.zeros((design.table_cols, 3))
    for s, r in zip(samples, residuals):
        A = _rows(design, s)
        part = A.T @ sp.diags(s.weights) @ A
        G = part if G is None else G + part
        b += np.asarray(A.T @ (r * s.weights[:, None]))
    n = sum(s.n for s in samples)
    reg = (SMOOTHING * n / 1000.0) * _smoothness(bins, crease)
    u = splu((G + reg).tocsc()).solve(np.ascontiguousarray(b)).T
    out = np.zeros((3, bins * bins))
    out[:, design.keep] = u
    return np.clip(out, -1000, 1000).reshape(3, bins, bins)


def fit_alternating(
    samples: list[PressSamples], fit_terms: Callable[[list[PressSamples]], LightTerms], bins: int, crease: float
) -> tuple[LightTerms, np.ndarray]:
    """(the other terms, U): ``fit_terms`` on the samples, U on their residual, then SINK_TABLE_ROUNDS times
    ``fit_terms`` on the change less s·U (shaded) and U on what those terms leave."""
    design = _Design(bins, crease)
    terms = fit_terms(samples)
    table = fit_sink_table(samples, [residual(s, terms) for s in samples], bins, crease)
    for _ in range(SINK_TABLE_ROUNDS):
        u = table.reshape(3, -1)[:, design.keep]
        less = [dataclasses.replace(s, target=s.target - np.asarray(_rows(design, s) @ u.T) * s.shade) for s in samples]
        terms = fit_terms(less)
        table = fit_sink_table(samples, [residual(s, terms) for s in samples], bins, crease)
    return terms, table


def left_out_errors(samples: list[PressSamples], bins: int, crease: float, with_table: bool) -> tuple[float, float]:
    """The table-and-sink model's (with the sink table or without) leave-one-press-out mean absolute error
    (grey levels, the shading applied) near the contacts and at their centres (``PressSamples.centre``)."""
    design = _Design(bins, crease)
    parts = [_normal(design, s) for s in samples]
    near = centre = 0.0
    n_near = n_centre = 0
    for k, held in enumerate(samples):
        rest = samples[:k] + samples[k + 1 :]
        t = _solve(design, parts[:k] + parts[k + 1 :])
        predicted = np.asarray(design.matrix(held) @ t.T)
        if with_table:
            left = [s.target / s.shade - np.asarray(design.matrix(s) @ t.T) for s in rest]
            u = fit_sink_table(rest, left, bins, crease).reshape(3, -1)[:, design.keep]
            predicted = predicted + np.asarray(_rows(design, held) @ u.T)
        err = np.abs(predicted * held.shade - held.target)
        centre_mask = held.centre if held.centre is not None else np.zeros(held.n, bool)
        near += float(err[held.near].sum())
        centre += float(err[centre_mask].sum())
        n_near += int(held.near.sum())
        n_centre += int(centre_mask.sum())
    return near / (3 * max(n_near, 1)), centre / (3 * max(n_centre, 1))


def sink_table_choice(samples: list[PressSamples], bins: int, crease: float, tolerance: float = 0.01) -> bool:
    """Whether to fit the sink table: when, each press left out in turn, it lowers the error at the contacts'
    centres and costs at most ``tolerance`` near them (the rule the crease penalty is taken by). Fewer than two
    presses, or no centre pixels: no."""
    if len(samples) < 2 or not all(s.centre is not None and s.centre.any() for s in samples):
        return False
    near_without, centre_without = left_out_errors(samples, bins, crease, False)
    near_with, centre_with = left_out_errors(samples, bins, crease, True)
    return centre_with < centre_without and near_with <= (1 + tolerance) * near_without
