"""Influence coefficients of an elastic half-space (or bonded layer) on a regular grid.

Each cell carries a uniform traction; its surface displacement at every other cell
centre is a closed-form integral over the cell (Love 1929 for normal load; the same
corner formula for Cerruti's tangential terms). Kernels are laid out for DC-FFT
(zero padding to 2N), so convolution is linear, not periodic: no image contacts.

Double antiderivatives over a cell, evaluated at its four corners:
    ∬ 1/r      →  x·asinh(y/|x|) + y·asinh(x/|y|)
    ∬ x²/r³    →  y·asinh(x/|y|)
    ∬ xy/r³    →  −r
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.fft as sfft

from rig.sim.tactile.elastomer import Elastomer


def _xasinh(x, y):
    """x·asinh(y/|x|), continuous with value 0 at x = 0."""
    ax = np.abs(x)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = x * np.arcsinh(y / np.where(ax > 0, ax, 1.0))
    return np.where(ax > 0, out, 0.0)


def _corner_sum(F, X, Y, a, b):
    return F(X + a, Y + b) - F(X + a, Y - b) - F(X - a, Y + b) + F(X - a, Y - b)


def _offsets(ny: int, nx: int, dy: float, dx: float):
    """Cell-centre offsets of the (2ny, 2nx) wrap-around layout."""
    iy = np.arange(2 * ny)
    ix = np.arange(2 * nx)
    oy = np.where(iy < ny, iy, iy - 2 * ny) * dy
    ox = np.where(ix < nx, ix, ix - 2 * nx) * dx
    return np.meshgrid(ox, oy)  # X, Y


def cell_integrals(ny: int, nx: int, dy: float, dx: float):
    """(I1, Ixx, Iyy, Ixy): cell integrals of 1/r, x²/r³, y²/r³, xy/r³ (mm)."""
    X, Y = _offsets(ny, nx, dy, dx)
    a, b = dx / 2, dy / 2
    f_xx = lambda x, y: _xasinh(y, x)  # y·asinh(x/|y|)
    f_yy = lambda x, y: _xasinh(x, y)  # x·asinh(y/|x|)
    f_xy = lambda x, y: -np.hypot(x, y)
    Ixx = _corner_sum(f_xx, X, Y, a, b)
    Iyy = _corner_sum(f_yy, X, Y, a, b)
    Ixy = _corner_sum(f_xy, X, Y, a, b)
    # Zero the Nyquist row/column: they are ambiguous in the wrap layout and never
    # reached by offsets between cells of an N-cell grid.
    for arr in (Ixx, Iyy, Ixy):
        arr[ny, :] = 0.0
        arr[:, nx] = 0.0
    return Ixx + Iyy, Ixx, Iyy, Ixy


def layer_factor(qh: np.ndarray, nu: float) -> np.ndarray:
    """Surface compliance of a layer bonded to a rigid base, relative to a half-space.

    S(qh) = [(3−4ν)·sinh 2qh − 2qh] / [(3−4ν)·cosh 2qh + 2(qh)² + 5 − 12ν + 8ν²].
    S → 1 for qh → ∞ (half-space); S ≈ qh(1−2ν)/(2(1−ν)²) for qh → 0, i.e. the
    oedometric thin-layer stiffness u = h·p·(1+ν)(1−2ν)/(E(1−ν)).
    """
    k = 3.0 - 4.0 * nu
    x = np.minimum(2.0 * qh, 60.0)  # beyond this S is 1 to machine precision
    num = k * np.sinh(x) - 2.0 * qh
    den = k * np.cosh(x) + 2.0 * qh**2 + 5.0 - 12.0 * nu + 8.0 * nu**2
    s = np.where(2.0 * qh < 60.0, num / den, 1.0)
    return s


class Kernels:
    """FFTs of the normal (and, on request, tangential) kernels for one grid and gel."""

    def __init__(self, ny: int, nx: int, dx: float, gel: Elastomer, dy: float | None = None):
        self.ny, self.nx, self.dx, self.dy = ny, nx, dx, dy or dx
        self.gel = gel
        self.shape = (2 * ny, 2 * nx)
        I1, self._Ixx, self._Iyy, self._Ixy = cell_integrals(ny, nx, self.dy, dx)
        normal = I1 / (math.pi * gel.E_star_MPa)  # mm per MPa
        normal_hat = sfft.rfft2(normal)
        if math.isfinite(gel.thickness_mm):
            normal_hat = self._layered(normal_hat)
        # Convolutions run in single precision: 2.5x faster, and 7 digits are far
        # beyond the solver tolerances (1e-3..1e-6); sums are taken in float64.
        self.normal_hat = normal_hat.astype(np.complex64)
        self._tangential_hat = None

    def _layered(self, half_space_hat: np.ndarray) -> np.ndarray:
        qy = 2 * np.pi * sfft.fftfreq(self.shape[0], self.dy)
        qx = 2 * np.pi * sfft.rfftfreq(self.shape[1], self.dx)
        q = np.hypot(*np.meshgrid(qx, qy))
        out = half_space_hat * layer_factor(q * self.gel.thickness_mm, self.gel.nu)
        nu, E = self.gel.nu, self.gel.E_MPa
        out[0, 0] = self.gel.thickness_mm * (1 + nu) * (1 - 2 * nu) / (E * (1 - nu))  # Σ K = h/M
        return out

    @property
    def tangential_hat(self):
        """(Kxx, Kyy, Kxy) FFTs of Cerruti's kernel (half-space), mm per MPa."""
        if self._tangential_hat is None:
            nu, E = self.gel.nu, self.gel.E_MPa
            c = (1 + nu) / (math.pi * E)
            I1 = self._Ixx + self._Iyy
            kxx = c * ((1 - nu) * I1 + nu * self._Ixx)
            kyy = c * ((1 - nu) * I1 + nu * self._Iyy)
            kxy = c * nu * self._Ixy
            self._tangential_hat = tuple(sfft.rfft2(k).astype(np.complex64) for k in (kxx, kyy, kxy))
        return self._tangential_hat

    def convolve(self, field_hat_kernel: np.ndarray, field: np.ndarray) -> np.ndarray:
        padded = sfft.rfft2(field.astype(np.float32, copy=False), s=self.shape, workers=1)
        out = sfft.irfft2(padded * field_hat_kernel, s=self.shape, workers=1)[: self.ny, : self.nx]
        return out.astype(np.float64)

    def normal_displacement(self, p: np.ndarray) -> np.ndarray:
        return self.convolve(self.normal_hat, p)

    def tangential_displacement(self, qx: np.ndarray, qy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        kxx, kyy, kxy = self.tangential_hat
        fx = sfft.rfft2(qx.astype(np.float32, copy=False), s=self.shape, workers=1)
        fy = sfft.rfft2(qy.astype(np.float32, copy=False), s=self.shape, workers=1)
        ux = sfft.irfft2(kxx * fx + kxy * fy, s=self.shape, workers=1)[: self.ny, : self.nx]
        uy = sfft.irfft2(kxy * fx + kyy * fy, s=self.shape, workers=1)[: self.ny, : self.nx]
        return ux.astype(np.float64), uy.astype(np.float64)


@functools.lru_cache(maxsize=16)
def kernels_for(ny: int, nx: int, dx: float, gel: Elastomer) -> Kernels:
    return Kernels(ny, nx, dx, gel)
