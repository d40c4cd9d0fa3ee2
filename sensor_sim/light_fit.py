"""The light model's least squares: tables, position and sink terms from pixels of a few presses.

    samples = [PressSamples.of(...) for each press]         # pixels near one press, their normals and sink
    fit = fit_light_terms(samples, bins, order=1, ...)       # LightTerms: T, Tx, Ty (tables) and k, kx, ky
    choice = choose_order(samples, bins)                     # by leave-one-press-out error

Order 0: the tables and the sink's k; 1: the tables' gain and turn across the field, the sink's k, kx, ky;
2: order 1 with the quadratic sink field (the sink's terms quadratic in x̃, ỹ and in the sink: the contact
centre's colour across the field, issue 40), taken where leaving presses out says it helps.

Per channel the colour change over the shading is linear in every parameter (the tables'
entries, bilinear in the normal; the position terms times x̃, ỹ; the sink terms times the
sink), so all three channels share one design matrix: each press contributes its Gram matrix
once, any subset of presses is a sum, and leaving a press out costs one solve. Normals the
presses never showed are filled smoothly (a grid-Laplacian penalty); the flat normal's
entries are held at 0 (the unpressed gel shows the background); a crease penalty holds the
tables linear near it where leaving presses out allows (``crease_choice``). Each pixel counts with its
``weight`` (weighted least squares; by default 1). The sink table (format 5): ``light_sink_table``. numpy/scipy.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from sensor_sim.light import SINK_FIELD_TERMS

SMOOTHING = 1.0  # λ of the tables' Laplacian penalty per 1000 fitted pixels
# The crease penalty: second differences along nx and along ny through the entries within CREASE_NORMAL of the
# flat normal, weighted ``crease`` × the Laplacian's: a table linear (C¹, no crease) where normals are near
# vertical, so the contact's centre shows no pinwheel point (issue 40). Taken or not by ``crease_choice``.
CREASE, CREASE_NORMAL = 10.0, 0.2
POSITION_RIDGES = (1e-3, 1e-2)  # per fitted pixel, on the position gains and turns: chosen by leave-one-out
# The quadratic sink field (order 2) is tried with the stronger ridge only: with the weaker, leaving presses out
# scored it worse than order 1 on the original GelSight's spread five (5.65 against 5.58 grey levels; 5.30 with it).
QUADRATIC_RIDGE = 1e-2
SINK_RIDGE = 1e-3  # per fitted pixel, on the sink terms (per mm of sink, grey levels)


@dataclass
class PressSamples:
    """One press's fitted pixels: bilinear cells of their normals (idx, w: (n, 4)), position
    (x̃, ỹ), sink (mm), shading (n, 3: the background over the reference; ones if additive), the
    colour change to explain (n, 3), which are near the contact and which at its centre."""

    idx: np.ndarray
    w: np.ndarray
    x: np.ndarray
    y: np.ndarray
    sink: np.ndarray
    shade: np.ndarray
    target: np.ndarray
    near: np.ndarray  # (n,) bool: within 1.5 contact radii (where renders are scored)
    weight: np.ndarray | None = None  # (n,) each pixel's weight in the least squares (mean 1); None: all 1
    centre: np.ndarray | None = None  # (n,) bool: at the contact's centre (where the sink table is judged)
    matrices: dict = field(default_factory=dict, repr=False)  # design rows per table size, made once

    @property
    def n(self) -> int:
        return len(self.target)

    @property
    def weights(self) -> np.ndarray:
        return np.ones(self.n) if self.weight is None else self.weight


@dataclass
class LightTerms:
    table: np.ndarray  # (3, N, N)
    position: np.ndarray | None  # (3, 2, N, N)
    sink: np.ndarray  # (3, 3): k, kx, ky per channel; order 2: (3, SINK_FIELD_TERMS), the quadratic sink field
    rms: float  # in-sample RMS residual over the shading (grey levels)


def _laplacian(bins: int) -> sp.csr_matrix:
    """Graph Laplacian of the bins × bins grid: penalises a table that is not smooth."""
    line = sp.diags([-np.ones(bins - 1), np.r_[1.0, 2 * np.ones(bins - 2), 1.0], -np.ones(bins - 1)], [-1, 0, 1])
    eye = sp.identity(bins)
    return (sp.kron(eye, line) + sp.kron(line, eye)).tocsr()


def _crease(bins: int) -> sp.csr_matrix:
    """Rows of the second differences along nx and along ny at the entries within CREASE_NORMAL of flat."""
    n = np.linspace(-1.0, 1.0, bins)
    rows: list[int] = []
    cols: list[int] = []
    vals: list[float] = []
    for j in range(1, bins - 1):
        for i in range(1, bins - 1):
            if max(abs(n[i]), abs(n[j])) > CREASE_NORMAL + 1e-9:
                continue
            for step in (1, bins):  # along nx (columns), along ny (rows)
                k = j * bins + i
                rows += [len(rows) // 3] * 3
                cols += [k - step, k, k + step]
                vals += [1.0, -2.0, 1.0]
    return sp.csr_matrix((vals, (rows, cols)), shape=(len(rows) // 3, bins * bins))


@functools.cache
def _smoothness(bins: int, crease: float = 0.0) -> sp.csr_matrix:
    """LᵀL of the grid Laplacian on the fitted entries (all but the flat normal's), plus ``crease`` × DᵀD
    of the crease rows."""
    keep = np.ones(bins * bins, bool)
    keep[(bins // 2) * bins + bins // 2] = False
    lap = _laplacian(bins)[:, keep]
    penalty = lap.T @ lap
    if crease:
        d = _crease(bins)[:, keep]
        penalty = penalty + crease * (d.T @ d)
    return penalty.tocsr()


class _Design:
    """Columns of the table-and-sink model: T (bins² less the flat entry), then the sink's k."""

    def __init__(self, bins: int, crease: float = 0.0):
        self.bins, self.crease = bins, crease
        cells = bins * bins
        self.keep = np.ones(cells, bool)
        self.keep[(bins // 2) * bins + bins // 2] = False
        self.column = np.full(cells, -1)
        self.column[self.keep] = np.arange(self.keep.sum())
        self.table_cols = int(self.keep.sum())
        self.size = self.table_cols + 1

    def matrix(self, s: PressSamples) -> sp.csr_matrix:
        """The press's rows (cached on the samples: the same press is fitted many times)."""
        if self.bins not in s.matrices:
            cols = self.column[s.idx]  # (n, 4); -1 for the flat entry (fixed at 0)
            ok = cols >= 0
            cols_all = np.concatenate([np.where(ok, cols, 0), np.full((s.n, 1), self.table_cols)], axis=1)
            vals_all = np.concatenate([np.where(ok, s.w, 0.0), s.sink[:, None]], axis=1)
            rows = np.repeat(np.arange(s.n), cols_all.shape[1])
            s.matrices[self.bins] = sp.csr_matrix((vals_all.ravel(), (rows, cols_all.ravel())), shape=(s.n, self.size))
        return s.matrices[self.bins]

    def tables_of(self, A: sp.csr_matrix) -> sp.csr_matrix:
        return A[:, : self.table_cols]

    def regulariser(self, n: int) -> sp.csc_matrix:
        smooth = (SMOOTHING * n / 1000.0) * _smoothness(self.bins, self.crease)
        return sp.block_diag([smooth, sp.identity(1) * (SINK_RIDGE * n)]).tocsc()

    def full(self, t: np.ndarray) -> np.ndarray:
        """(3, table_cols) fitted entries → (3, N, N) tables (the flat entry 0), bounded."""
        out = np.zeros((3, self.bins * self.bins))
        out[:, self.keep] = t
        return np.clip(out, -255, 255).reshape(3, self.bins, self.bins)


@dataclass
class _Normal:
    """A press's contribution to the normal equations (per channel b, c; G shared)."""

    G: sp.csr_matrix
    b: np.ndarray  # (P, 3)
    c: np.ndarray  # (3,)
    n: int


def _normal(design: _Design, s: PressSamples) -> _Normal:
    A = design.matrix(s)
    y = s.target / s.shade  # the change over the shading: one design for all three channels
    wy = y * s.weights[:, None]
    return _Normal((A.T @ sp.diags(s.weights) @ A).tocsr(), np.asarray(A.T @ wy), (wy * y).sum(axis=0), s.n)


def _solve(design: _Design, parts: list[_Normal]) -> np.ndarray:
    n = sum(p.n for p in parts)
    G = parts[0].G.copy()
    for p in parts[1:]:
        G = G + p.G
    b = sum(p.b for p in parts)
    lu = splu((G + design.regulariser(n)).tocsc())
    return lu.solve(np.ascontiguousarray(b)).T  # (3, P)


def _residual(part: _Normal, t: np.ndarray) -> float:
    """Sum over channels of the squared residual of ``part`` under solution ``t`` (3, P)."""
    Gt = part.G @ t.T  # (P, 3)
    return float(np.sum(t.T * Gt) - 2 * np.sum(t.T * part.b) + part.c.sum())


def fit_light_terms(
    samples: list[PressSamples], bins: int, order: int, position_ridge: float = 1e-3, crease: float = 0.0
) -> LightTerms:
    """Order 0: the table and the sink's k (a linear least squares); order 1: the low-rank position
    terms besides (``fit_low_rank``). ``crease``: the crease penalty's weight (CREASE or 0)."""
    if order in (1, 2):
        table, position, sink = fit_low_rank(samples, bins, position_ridge, crease=crease, quadratic=order == 2)
        rss, n = _low_rank_residual(samples, table, position, sink)
        return LightTerms(table, position, sink, math.sqrt(max(rss, 0.0) / (3 * n)))
    design = _Design(bins, crease)
    parts = [_normal(design, s) for s in samples]
    t = _solve(design, parts)
    rss = sum(_residual(p, t) for p in parts)
    sink = np.zeros((3, 3))
    sink[:, 0] = t[:, design.table_cols]
    n = sum(p.n for p in parts)
    return LightTerms(design.full(t[:, : design.table_cols]), None, sink, math.sqrt(max(rss, 0.0) / (3 * n)))


def rotation_derivative(table: np.ndarray) -> np.ndarray:
    """∂T/∂φ of (..., N, N) tables over the normal (rows ny, columns nx): how a table changes when
    the light turns about the gel's normal (nx ∂T/∂ny − ny ∂T/∂nx)."""
    bins = table.shape[-1]
    n = np.linspace(-1.0, 1.0, bins)
    d_ny, d_nx = np.gradient(table, 2.0 / (bins - 1), axis=(-2, -1))
    nx, ny = np.meshgrid(n, n)
    return nx * d_ny - ny * d_nx


def sink_basis(s: PressSamples, quadratic: bool) -> np.ndarray:
    """(n, 3) the sink times 1, x̃, ỹ; ``quadratic``: (n, SINK_FIELD_TERMS), the sink times 1, x̃, ỹ, x̃², x̃ỹ, ỹ²,
    then the sink² times the same (the columns of ``LightModel.sink_bgr``)."""
    if not quadratic:
        return np.stack([s.sink, s.sink * s.x, s.sink * s.y], axis=1)
    field = np.stack([np.ones_like(s.x), s.x, s.y, s.x * s.x, s.x * s.y, s.y * s.y], axis=1)
    return np.concatenate([field * s.sink[:, None], field * (s.sink * s.sink)[:, None]], axis=1)


def _features(
    A: sp.csr_matrix, s: PressSamples, t_ch: np.ndarray, rt_ch: np.ndarray, quadratic: bool = False
) -> np.ndarray:
    """(n, 4 + sink terms) columns of the low-rank position model for one channel: the table's and its
    rotation's lookups times x̃ and ỹ, then the sink's terms (``sink_basis``)."""
    tv, rv = A @ t_ch, A @ rt_ch
    return np.concatenate([np.stack([tv * s.x, tv * s.y, rv * s.x, rv * s.y], axis=1), sink_basis(s, quadratic)], 1)


LOW_RANK_ITERATIONS = 2


def table_factor(samples: list[PressSamples], bins: int, crease: float = 0.0):
    """The LU factor of the tables' regularised normal matrix over ``samples`` (``fit_low_rank``'s; made once
    per set of presses when several models are fitted to it)."""
    design = _Design(bins, crease)
    A_T = [design.tables_of(design.matrix(s)) for s in samples]
    G = A_T[0].T @ sp.diags(samples[0].weights) @ A_T[0]
    for a, smp in zip(A_T[1:], samples[1:]):
        G = G + a.T @ sp.diags(smp.weights) @ a
    reg = design.regulariser(sum(s.n for s in samples))[: design.table_cols, : design.table_cols]
    return splu((G + reg).tocsc())


def fit_low_rank(
    samples: list[PressSamples],
    bins: int,
    ridge: float,
    base: np.ndarray | None = None,
    crease: float = 0.0,
    quadratic: bool = False,
    lu=None,
):
    """Tables T plus, per channel, a gain and a turn of T across the field (Tx = gx·T + rx·∂T/∂φ,
    Ty likewise) and the sink terms k, kx, ky (``quadratic``: the SINK_FIELD_TERMS of the quadratic sink
    field): 7 (16) numbers per channel beside the table, fitted with
    T in turns (the features of the previous T, which the position tables are made of, so that the
    model rendered is the one fitted). ``base``: the table-and-sink fit's entries to start from; ``lu``:
    ``table_factor`` of the same samples (it depends on neither the ridge nor the sink's terms).
    Returns (table (3, N, N), position (3, 2, N, N), sink (3, 3) or (3, SINK_FIELD_TERMS))."""
    design = _Design(bins, crease)
    m = 4 + (SINK_FIELD_TERMS if quadratic else 3)
    A_T = [design.tables_of(design.matrix(s)) for s in samples]
    n = sum(s.n for s in samples)
    lu = lu or table_factor(samples, bins, crease)
    if base is None:
        base = _solve(design, [_normal(design, smp) for smp in samples])[:, : design.table_cols]
    table = np.array(base, dtype=np.float64)
    beta = np.zeros((3, m))
    position = np.zeros((3, 2, bins * bins))
    for _ in range(LOW_RANK_ITERATIONS):
        full = np.zeros((3, bins * bins))
        full[:, design.keep] = table
        rot = rotation_derivative(full.reshape(3, bins, bins)).reshape(3, -1)[:, design.keep]
        for ch in range(3):
            GTF = np.zeros((design.table_cols, m))
            GFF = np.zeros((m, m))
            bT = np.zeros(design.table_cols)
            bF = np.zeros(m)
            for a, smp in zip(A_T, samples):
                F = _features(a, smp, table[ch], rot[ch], quadratic)
                y = smp.target[:, ch] / smp.shade[:, ch]
                wF, wy = F * smp.weights[:, None], y * smp.weights
                GTF += np.asarray(a.T @ wF)
                GFF += F.T @ wF
                bT += a.T @ wy
                bF += F.T @ wy
            GFF += np.eye(m) * (ridge * n)
            # Schur complement: (GFF - GTFᵀ (G+R)⁻¹ GTF) β = bF - GTFᵀ (G+R)⁻¹ bT
            inv_bT = lu.solve(bT)
            inv_GTF = lu.solve(np.ascontiguousarray(GTF))
            beta[ch] = np.linalg.solve(GFF - GTF.T @ inv_GTF, bF - GTF.T @ inv_bT)
            position[ch, 0] = 0.0
            position[ch, 1] = 0.0
            position[ch, 0, design.keep] = beta[ch, 0] * table[ch] + beta[ch, 2] * rot[ch]
            position[ch, 1, design.keep] = beta[ch, 1] * table[ch] + beta[ch, 3] * rot[ch]
            table[ch] = inv_bT - inv_GTF @ beta[ch]
    return (
        design.full(table),
        np.clip(position, -255, 255).reshape(3, 2, bins, bins),
        np.clip(beta[:, 4:], -1000, 1000),
    )


def _low_rank_change(s: PressSamples, table, position, sink) -> np.ndarray:
    """(n, 3) change over the shading that a low-rank fit predicts at the samples."""
    out = np.empty((s.n, 3))
    basis = sink_basis(s, sink.shape[1] == SINK_FIELD_TERMS)
    for ch in range(3):
        t = (table[ch].ravel()[s.idx] * s.w).sum(axis=1)
        tx = (position[ch, 0].ravel()[s.idx] * s.w).sum(axis=1)
        ty = (position[ch, 1].ravel()[s.idx] * s.w).sum(axis=1)
        out[:, ch] = t + s.x * tx + s.y * ty + basis @ sink[ch]
    return out


def _low_rank_residual(samples: list[PressSamples], table, position, sink) -> tuple[float, int]:
    """Weighted squared residual (over the shading, all channels) of samples under a low-rank fit."""
    rss, n = 0.0, 0
    for s in samples:
        r2 = (s.target / s.shade - _low_rank_change(s, table, position, sink)) ** 2
        rss += float(np.sum(r2 * s.weights[:, None]))
        n += s.n
    return rss, n


def held_out_mae(samples: list[PressSamples], bins: int, crease: float = 0.0) -> float:
    """The table-and-sink model's leave-one-press-out mean absolute error (grey levels, the shading
    applied) near the contacts: what the blur is chosen by. The squared residual over the whole fit
    window (what the tables are fitted to) chooses a blur that smooths the rim away to match the
    gel's relaxation further out; near the contact, as renders are scored, it does not. One press:
    in-sample."""
    design = _Design(bins, crease)
    parts = [_normal(design, s) for s in samples]
    total = n = 0.0
    for k, held in enumerate(samples):
        t = _solve(design, parts[:k] + parts[k + 1 :] if len(parts) > 1 else parts)
        predicted = np.asarray(design.matrix(held) @ t.T) * held.shade
        total += float(np.abs(predicted - held.target)[held.near].sum())
        n += int(held.near.sum())
    return total / (3 * max(n, 1))


@dataclass
class OrderChoice:
    order: int
    position_ridge: float
    held_out_rms: dict[tuple[int, float], float]  # (order, ridge) → leave-one-press-out RMS (over the shading)


def choose_order(samples: list[PressSamples], bins: int, crease: float = 0.0) -> OrderChoice:
    """The model whose terms, fitted on all presses but one, explain the one left out best, over
    every press: position order 0 (table and sink), 1 (the low-rank position terms, with one of
    POSITION_RIDGES) or 2 (with the quadratic sink field besides, QUADRATIC_RIDGE): the spatial terms are
    kept only where the presses' spread supports them.
    Fewer than three presses: order 0."""
    if len(samples) < 3:
        return OrderChoice(0, 0.0, {})
    scores: dict[tuple[int, float], float] = {}
    design = _Design(bins, crease)
    parts = [_normal(design, s) for s in samples]
    rss = n = 0.0
    bases = []
    for k, part in enumerate(parts):
        t = _solve(design, parts[:k] + parts[k + 1 :])
        bases.append(t[:, : design.table_cols])
        rss += _residual(part, t)
        n += part.n
    scores[(0, 0.0)] = math.sqrt(max(rss, 0.0) / (3 * n))
    candidates = [(1, ridge) for ridge in POSITION_RIDGES] + [(2, QUADRATIC_RIDGE)]
    rss_of = dict.fromkeys(candidates, 0.0)
    n = 0.0
    for k, held in enumerate(samples):
        rest = samples[:k] + samples[k + 1 :]
        lu = table_factor(rest, bins, crease)  # the same for every candidate
        for order, ridge in candidates:
            fit = fit_low_rank(rest, bins, ridge, base=bases[k], crease=crease, quadratic=order == 2, lu=lu)
            rss_of[(order, ridge)] += _low_rank_residual([held], *fit)[0]
        n += held.n
    for key, rss in rss_of.items():
        scores[key] = math.sqrt(max(rss, 0.0) / (3 * n))
    best = min(scores, key=lambda key: scores[key])
    return OrderChoice(best[0], best[1], scores)


def crease_choice(samples: list[PressSamples], bins: int, tolerance: float = 0.01) -> float:
    """CREASE when the table-and-sink model with it explains presses left out (near the contacts,
    ``held_out_mae``) within ``tolerance`` of the model without it, else 0: the original GelSight's deep
    presses cost nothing (their contacts span every tilt), the GelSight Mini's shallow ones (all their
    normals within ~0.45 of vertical) 11-13 %. One press: in-sample, so 0."""
    if len(samples) < 2:
        return 0.0
    return CREASE if held_out_mae(samples, bins, CREASE) <= (1 + tolerance) * held_out_mae(samples, bins) else 0.0
