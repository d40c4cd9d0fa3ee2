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
import threading

import numpy as np
import scipy.fft as sfft

try:  # scipy.fft's own transforms without its per-call argument handling (most of a small FFT's cost)
    from scipy.fft._pocketfft import pypocketfft as _pocketfft
except ImportError:  # another scipy: the public calls, the same numbers
    _pocketfft = None

from sensor_sim.elastomer import Elastomer


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


# Hankel-transform quadrature: the integrands decay like exp(−2x), so x ≤ 20 suffices;
# a 0.01 step resolves J(xρ) up to ρ = 60 with 10 points a period; the tables are
# smooth in ρ on the scale of 1, so a 0.05 step interpolates them to ~1e-4.
_X = np.linspace(0.0, 20.0, 2001)
_W = np.full_like(_X, _X[1] - _X[0])
_W[0] = _W[-1] = _W[0] / 2
_RHO = np.linspace(0.0, 60.0, 1201)


def _bessel_j0_j2():
    from scipy.special import j0, j1

    arg = np.outer(_RHO, _X)
    J0 = j0(arg)
    safe = np.where(arg > 1e-8, arg, 1.0)
    J2 = np.where(arg > 1e-8, 2.0 * j1(arg) / safe - J0, 0.0)  # recurrence: J2 = 2J1/z − J0
    return J0, J2


_BESSEL = None


def _bessel():
    global _BESSEL
    if _BESSEL is None:
        _BESSEL = _bessel_j0_j2()
    return _BESSEL


@functools.lru_cache(maxsize=8)
def _layer_correction_table(nu: float) -> tuple[np.ndarray, np.ndarray]:
    """g(ρ) = ∫₀^∞ (S(x) − 1)·J₀(xρ) dx on ρ = r/h ∈ [0, 60], by quadrature.

    Beyond ρ = 60 the layer no longer carries load and g = −1/ρ cancels the
    half-space tail.
    """
    J0, _ = _bessel()
    return _RHO, J0 @ ((layer_factor(_X, nu) - 1.0) * _W)


def layer_correction(r_mm: np.ndarray, thickness_mm: float, nu: float) -> np.ndarray:
    """Surface sink per unit point force, layer minus half-space, times π·E* (1/mm).

    G_layer(r) = G_half(r) + g(r/h)/(π E* h): the bonded layer's Green's function,
    non-periodic, from the Hankel transform of S(qh) − 1.
    """
    rho_tab, g_tab = _layer_correction_table(nu)
    rho = np.asarray(r_mm) / thickness_mm
    inside = np.interp(np.minimum(rho, rho_tab[-1]), rho_tab, g_tab)
    far = -1.0 / np.maximum(rho, 1e-12)
    return np.where(rho <= rho_tab[-1], inside, far) / thickness_mm


@functools.lru_cache(maxsize=8)
def _tangential_layer_tables(nu: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """g0(ρ) = ∫ c0(x) J₀(xρ) dx and g2(ρ) = ∫ c2(x) J₂(xρ) dx, ρ = r/h ∈ [0, 60].

    Tangential compliance splits into a longitudinal mode L (traction along the
    wavevector) and a transverse one T: half-space L = (1−ν)/(Gq), T = 1/(Gq)
    (Cerruti). A bonded layer multiplies T by tanh(qh) (exact, antiplane shear) and
    L by tanh(qh/(1−ν)), which has the exact thick (1) and thin (simple shear h/G)
    limits. With x = qh: c0 = [(1−ν)(F_L − 1) + (F_T − 1)]/2, c2 = [(1−ν)(F_L − 1) − (F_T − 1)]/2.
    """
    J0, J2 = _bessel()
    dl = (1 - nu) * (np.tanh(_X / (1 - nu)) - 1.0)
    dt = np.tanh(_X) - 1.0
    return _RHO, J0 @ ((dl + dt) / 2 * _W), J2 @ ((dl - dt) / 2 * _W)


_WARMING = threading.Lock()


def warm_tables(nu: float) -> None:
    """Build the layer tables for ``nu`` now (a simulator calls this off its hot path). Several
    simulators warming at once build each table once: the others wait and take it from the cache."""
    with _WARMING:
        _layer_correction_table(nu)
        _tangential_layer_tables(nu)


def tangential_layer_correction(X: np.ndarray, Y: np.ndarray, thickness_mm: float, nu: float):
    """(Δxx, Δyy, Δxy) per unit point force, times 2π·G (1/mm): layer minus half-space.

    ΔK_ij = [g0(ρ)·δij − g2(ρ)·(2 x̂_i x̂_j − δij)] / (2π G h); beyond the table the
    layer carries no load and the correction cancels the half-space kernel.
    """
    rho_tab, g0_tab, g2_tab = _tangential_layer_tables(nu)
    r = np.hypot(X, Y)
    rho = r / thickness_mm
    far = rho > rho_tab[-1]
    rr = np.maximum(rho, 1e-12)
    g0 = np.where(far, -(2 - nu) / (2 * rr), np.interp(np.minimum(rho, rho_tab[-1]), rho_tab, g0_tab))
    g2 = np.where(far, nu / (2 * rr), np.interp(np.minimum(rho, rho_tab[-1]), rho_tab, g2_tab))
    rs = np.where(r > 0, r, 1.0)
    cxx = np.where(r > 0, 2 * X * X / rs**2 - 1, 0.0)
    cxy = np.where(r > 0, 2 * X * Y / rs**2, 0.0)
    return ((g0 - g2 * cxx) / thickness_mm, (g0 + g2 * cxx) / thickness_mm, (-g2 * cxy) / thickness_mm)


class Kernels:
    """FFTs of the normal (and, on request, tangential) kernels for one grid and gel."""

    def __init__(self, ny: int, nx: int, dx: float, gel: Elastomer, dy: float | None = None):
        self.ny, self.nx, self.dx, self.dy = ny, nx, dx, dy or dx
        self.gel = gel
        self.shape = (2 * ny, 2 * nx)
        I1, self._Ixx, self._Iyy, self._Ixy = cell_integrals(ny, nx, self.dy, dx)
        normal = I1 / (math.pi * gel.E_star_MPa)  # mm per MPa: Love's exact cell integral
        if math.isfinite(gel.thickness_mm):
            normal = normal + self._layer_term()
        # Convolutions run in single precision: 2.5x faster, and 7 digits are far
        # beyond the usual solver tolerances (1e-3..1e-5); sums are taken in float64.
        # A solver that stalls on the float32 floor (~1e-7..1e-6 relative change of p,
        # more on larger grids) asks for the float64 transforms (``precise=True``).
        self._normal_real = normal
        self.normal_hat = sfft.rfft2(normal).astype(np.complex64)
        # Built on first use (most solves need neither the float64 nor the tangential kernels).
        self._normal_hat64: np.ndarray | None = None
        self._tangential_real: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._tangential_hat: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._tangential_hat64: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def _layer_term(self) -> np.ndarray:
        """Cell-averaged (3×3 sub-points) layer correction on the wrap-around layout."""
        X, Y = _offsets(self.ny, self.nx, self.dy, self.dx)
        sub = (np.arange(3) - 1) / 3
        acc = np.zeros_like(X)
        for sy in sub:
            for sx in sub:
                r = np.hypot(X + sx * self.dx, Y + sy * self.dy)
                acc += layer_correction(r, self.gel.thickness_mm, self.gel.nu)
        term = acc / 9 * self.dx * self.dy / (math.pi * self.gel.E_star_MPa)
        term[self.ny, :] = 0.0
        term[:, self.nx] = 0.0
        return term

    @property
    def normal_hat64(self) -> np.ndarray:
        """The normal kernel's FFT in double precision, built on first use."""
        if self._normal_hat64 is None:
            self._normal_hat64 = sfft.rfft2(self._normal_real)
        return self._normal_hat64

    def _tangential_kernels(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Kxx, Kyy, Kxy): Cerruti's kernel with the layer correction, mm per MPa, real space."""
        if self._tangential_real is None:
            nu, E = self.gel.nu, self.gel.E_MPa
            c = (1 + nu) / (math.pi * E)
            I1 = self._Ixx + self._Iyy
            kxx = c * ((1 - nu) * I1 + nu * self._Ixx)
            kyy = c * ((1 - nu) * I1 + nu * self._Iyy)
            kxy = c * nu * self._Ixy
            if math.isfinite(self.gel.thickness_mm):
                dxx, dyy, dxy = self._tangential_layer_term()
                kxx, kyy, kxy = kxx + dxx, kyy + dyy, kxy + dxy
            self._tangential_real = (kxx, kyy, kxy)
        return self._tangential_real

    @property
    def tangential_hat(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Kxx, Kyy, Kxy) FFTs of Cerruti's kernel, with the layer correction, mm per MPa."""
        if self._tangential_hat is None:
            kxx, kyy, kxy = (sfft.rfft2(k).astype(np.complex64) for k in self._tangential_kernels())
            self._tangential_hat = (kxx, kyy, kxy)
        return self._tangential_hat

    @functools.cached_property
    def tangential_lipschitz(self) -> float:
        """The largest eigenvalue of the tangential compliance (``tangential_hat``'s 2×2 blocks,
        mm per MPa): the bound on a projected-gradient step, made once per grid and gel."""
        kxx, kyy, kxy = (k.real for k in self.tangential_hat)
        half_trace = (kxx + kyy) / 2
        return float(np.max(half_trace + np.sqrt(((kxx - kyy) / 2) ** 2 + kxy**2)))

    @property
    def tangential_hat64(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``tangential_hat`` in double precision, built on first use."""
        if self._tangential_hat64 is None:
            kxx, kyy, kxy = (sfft.rfft2(k) for k in self._tangential_kernels())
            self._tangential_hat64 = (kxx, kyy, kxy)
        return self._tangential_hat64

    def _tangential_layer_term(self) -> list[np.ndarray]:
        """[Δxx, Δyy, Δxy]: the cell-averaged layer correction of Cerruti's kernel, mm per MPa."""
        X, Y = _offsets(self.ny, self.nx, self.dy, self.dx)
        sub = (np.arange(3) - 1) / 3
        acc = [np.zeros_like(X) for _ in range(3)]
        for sy in sub:
            for sx in sub:
                for a, d in zip(
                    acc,
                    tangential_layer_correction(X + sx * self.dx, Y + sy * self.dy, self.gel.thickness_mm, self.gel.nu),
                ):
                    a += d
        scale = self.dx * self.dy / (9 * 2 * math.pi * self.gel.G_MPa)
        for a in acc:
            a *= scale
            a[self.ny, :] = 0.0
            a[:, self.nx] = 0.0
        return acc

    def convolve(self, field_hat_kernel: np.ndarray, field: np.ndarray) -> np.ndarray:
        """Linear (zero-padded) convolution; the kernel's dtype sets the precision."""
        dtype = np.float64 if field_hat_kernel.dtype == np.complex128 else np.float32
        padded = rfft2_padded(field.astype(dtype, copy=False), self.shape)
        out = irfft2_full(padded * field_hat_kernel, self.shape)[: self.ny, : self.nx]
        return out.astype(np.float64)

    def normal_displacement(self, p: np.ndarray, *, precise: bool = False) -> np.ndarray:
        return self.convolve(self.normal_hat64 if precise else self.normal_hat, p)

    def tangential_displacement(
        self, qx: np.ndarray, qy: np.ndarray, *, precise: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        kxx, kyy, kxy = self.tangential_hat64 if precise else self.tangential_hat
        dtype = np.float64 if precise else np.float32
        fx = rfft2_padded(qx.astype(dtype, copy=False), self.shape)
        fy = rfft2_padded(qy.astype(dtype, copy=False), self.shape)
        ux = irfft2_full(kxx * fx + kxy * fy, self.shape)[: self.ny, : self.nx]
        uy = irfft2_full(kxy * fx + kyy * fy, self.shape)[: self.ny, : self.nx]
        return ux.astype(np.float64), uy.astype(np.float64)


def rfft2_padded(field: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``scipy.fft.rfft2(field, s=shape, axes=(-2, -1))``: zero-padded to ``shape`` over the
    last two axes (float32 or float64 ``field``), the same pocketfft transform called
    directly (bit for bit, tested): a solve makes a few dozen transforms of small crops."""
    ny, nx = field.shape[-2:]
    if _pocketfft is None or field.dtype not in (np.float32, np.float64) or ny > shape[0] or nx > shape[1]:
        return sfft.rfft2(field, s=shape, axes=(-2, -1), workers=1)
    padded = np.zeros((*field.shape[:-2], *shape), field.dtype)
    padded[..., :ny, :nx] = field
    return r2c_2d(padded)


def irfft2_full(spectrum: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``scipy.fft.irfft2(spectrum, s=shape, axes=(-2, -1))`` for a spectrum of ``rfft2_padded``
    at ``shape`` (complex64 or complex128), called directly as that is."""
    if (
        _pocketfft is None
        or spectrum.dtype not in (np.complex64, np.complex128)
        or spectrum.shape[-2:] != (shape[0], shape[1] // 2 + 1)
    ):
        return sfft.irfft2(spectrum, s=shape, axes=(-2, -1), workers=1)
    return c2r_2d(spectrum, shape)


def direct_transforms() -> bool:
    """True when pocketfft can be called directly (``r2c_2d``, ``c2r_2d``)."""
    return _pocketfft is not None


def r2c_2d(padded: np.ndarray) -> np.ndarray:
    """``rfft2_padded`` of a field already zero-padded to the transform's shape (float32
    or float64, the last two axes): pocketfft's forward transform, nothing else."""
    assert _pocketfft is not None, "direct_transforms() is False: use rfft2_padded"
    nd = padded.ndim
    return _pocketfft.r2c(padded, (nd - 2, nd - 1), True, 0, None, 1)


def c2r_2d(spectrum: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``irfft2_full`` without its checks (a spectrum of ``r2c_2d`` at ``shape``)."""
    assert _pocketfft is not None, "direct_transforms() is False: use irfft2_full"
    nd = spectrum.ndim
    return _pocketfft.c2r(spectrum, (nd - 2, nd - 1), shape[1], False, 2, None, 1)


@functools.lru_cache(maxsize=16)
def kernels_for(ny: int, nx: int, dx: float, gel: Elastomer) -> Kernels:
    return Kernels(ny, nx, dx, gel)
