"""Product quadrature on the sphere, SH projection and evaluation (xing §4).

The coefficients of the paper's expansions, a_i = ∫ L(ω) Y_i(ω) dω and
b_j(x) = ∫ T(x, ω) Y_j(ω) dω, are integrals over the sphere.  For a function band-limited
to lmax, f·Y_i is a spherical polynomial of degree ≤ 2·lmax, and the rule below integrates
those exactly, so :func:`project` recovers the coefficients up to rounding.

Rule of order L: Gauss–Legendre in z = cos θ with L+1 nodes (exact for polynomials in z
of degree ≤ 2L+1) times 2L+1 equally spaced azimuths (exact for e^{ikφ}, |k| ≤ 2L):
(L+1)(2L+1) points, exact for every spherical polynomial of degree ≤ 2L.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ValidationError
from ._basis import _as_int, _sh_unit, check_dirs, check_lmax, real_sh

MAX_GRID_ORDER = 1024


@dataclasses.dataclass(frozen=True, eq=False)
class GaussLegendreGrid:
    """Gauss–Legendre(z) × uniform(φ) rule of order L, exact to spherical degree 2L.

    Attributes (read-only NumPy float64):
        L: the order.
        z: (L+1,) Gauss–Legendre nodes in (−1, 1), ascending.
        phi: (2L+1,) azimuths 2πk/(2L+1), measured from +x toward +y.
        dirs: (N, 3) unit vectors, N = (L+1)(2L+1), z-major (index = iz·(2L+1) + iφ).
        weights: (N,) positive weights summing to 4π.
    """

    L: int
    z: np.ndarray
    phi: np.ndarray
    dirs: np.ndarray
    weights: np.ndarray

    @property
    def size(self) -> int:
        return int(self.weights.shape[0])

    @property
    def degree(self) -> int:
        """Largest spherical-polynomial degree integrated exactly (2L)."""
        return 2 * self.L

    def integrate(self, values) -> np.ndarray:
        """∫ f dω from samples ``values`` (..., N) at ``dirs`` (NumPy float64)."""
        values = np.asarray(values, dtype=np.float64)
        if values.ndim < 1 or values.shape[-1] != self.size:
            raise ValidationError("values", values, f"the last axis must have the grid's {self.size} samples")
        return values @ self.weights


def _check_order(L, field: str = "L") -> int:
    L = _as_int(field, L)
    if not 0 <= L <= MAX_GRID_ORDER:
        raise ValidationError(field, L, f"the grid order must be in [0, {MAX_GRID_ORDER}]")
    return L


@functools.lru_cache(maxsize=32)
def _grid(L: int) -> GaussLegendreGrid:
    z, wz = np.polynomial.legendre.leggauss(L + 1)
    nphi = 2 * L + 1
    phi = 2.0 * np.pi * np.arange(nphi) / nphi
    s = np.sqrt((1.0 - z) * (1.0 + z))  # sin θ, accurate near the poles
    dirs = np.stack([np.outer(s, np.cos(phi)), np.outer(s, np.sin(phi)), np.repeat(z[:, None], nphi, axis=1)], axis=-1).reshape(
        -1, 3
    )
    weights = np.repeat(wz * (2.0 * np.pi / nphi), nphi)
    for a in (z, phi, dirs, weights):
        a.setflags(write=False)
    return GaussLegendreGrid(L, z, phi, dirs, weights)


def sphere_grid(L: int) -> GaussLegendreGrid:
    """The cached order-L product rule: (L+1)(2L+1) points, exact to degree 2L."""
    return _grid(_check_order(L))


@functools.lru_cache(maxsize=32)
def _weighted_basis(L: int, lmax: int) -> np.ndarray:
    """W[q, i] = w_q Y_i(d_q) on the order-L grid, float64, read-only."""
    grid = _grid(L)
    w = np.asarray(real_sh(lmax, grid.dirs)) * grid.weights[:, None]
    w.setflags(write=False)
    return w


@jax.jit
def _project_kernel(values, wbasis):
    return jnp.matmul(values, wbasis.astype(values.dtype), precision=jax.lax.Precision.HIGHEST)


def _float_dtype(*dtypes) -> np.dtype:
    """float32 only when every input is float32 (or narrower float); else float64."""
    narrow = all(np.dtype(d).name in ("float32", "float16", "bfloat16") for d in dtypes)
    return np.dtype(np.float32 if narrow else np.float64)


def _concrete_finite(field: str, arr) -> np.ndarray:
    arr = np.asarray(arr)
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)) or arr.dtype == np.bool_:
        raise ValidationError(field, arr, f"must be real numbers, got dtype {arr.dtype}")
    if not np.all(np.isfinite(arr)):
        raise ValidationError(field, arr, "contains NaN or infinity")
    return arr


def project(values, grid: GaussLegendreGrid, lmax: int):
    """SH coefficients c_i = Σ_q w_q f(d_q) Y_i(d_q) ≈ ∫ f Y_i dω (xing §4, a_i and b_j).

    Args:
        values (array_like): samples f(grid.dirs), shape (..., N) — the grid axis is last.
        grid (GaussLegendreGrid): the quadrature grid; exact when f is band-limited to lmax ≤ grid.L.
        lmax (int): band limit of the result.

    Returns:
        jax.Array: (..., (lmax+1)²); float32 for float32 values, else float64.
    """
    lmax = check_lmax(lmax)
    if not isinstance(grid, GaussLegendreGrid):
        raise ValidationError("grid", grid, "expected a GaussLegendreGrid (see sphere_grid)")
    if lmax > grid.L:
        raise ValidationError("lmax", lmax, f"an order-{grid.L} grid projects exactly only up to lmax = {grid.L}")
    if not isinstance(values, jax.core.Tracer):
        values = _concrete_finite("values", values)
    if values.ndim < 1 or values.shape[-1] != grid.size:
        raise ValidationError("values", values, f"the last axis must have the grid's {grid.size} samples, got {values.shape}")
    dt = _float_dtype(values.dtype)
    wbasis = _weighted_basis(grid.L, lmax)
    if isinstance(values, jax.core.Tracer):
        return _project_kernel(values, jnp.asarray(wbasis, values.dtype))
    if dt == np.float64:
        with jax.enable_x64(True):
            return _project_kernel(jnp.asarray(values, jnp.float64), jnp.asarray(wbasis))
    return _project_kernel(jnp.asarray(values, jnp.float32), jnp.asarray(wbasis, jnp.float32))


def project_function(f, lmax: int, *, L: int | None = None):
    """Project a callable f: (N, 3) float64 unit vectors → (N, *extra) onto SH up to lmax.

    Samples f on ``sphere_grid(L)`` (default L = lmax, exact for band-limit ≤ lmax) and
    returns float64 coefficients of shape (*extra, (lmax+1)²).
    """
    lmax = check_lmax(lmax)
    grid = sphere_grid(lmax if L is None else L)
    values = np.asarray(f(grid.dirs))
    if values.ndim < 1 or values.shape[0] != grid.size:
        raise ValidationError("f", f, f"must return an array whose first axis has {grid.size} samples, got {values.shape}")
    return project(np.moveaxis(values, 0, -1).astype(np.float64), grid, lmax)


@jax.jit
def _evaluate_kernel(coeffs, dirs):
    lmax = math.isqrt(coeffs.shape[-1]) - 1
    x, y, z = dirs[..., 0], dirs[..., 1], dirs[..., 2]
    inv = jax.lax.rsqrt(x * x + y * y + z * z)
    basis = _sh_unit(x * inv, y * inv, z * inv, lmax)
    return jnp.sum(basis * coeffs, axis=-1)


def evaluate(coeffs, dirs, *, normalize: bool = False):
    """f(d) = Σ_i c_i Y_i(d), e.g. L(ω) ≈ Σ a_i Y_i(ω) (xing §4).

    Args:
        coeffs (array_like): (..., (lmax+1)²); its batch shape broadcasts against that of ``dirs``
            (use ``coeffs[:, None, :]`` with dirs (M, 3) for every-set-at-every-direction).
        dirs (array_like): (..., 3) unit vectors (see :func:`real_sh` for ``normalize``).
        normalize (bool): accept any finite nonzero vectors.

    Returns:
        jax.Array: the broadcast batch shape; float32 only if both inputs are float32.
    """
    dirs = check_dirs(dirs, normalize=normalize)
    if not isinstance(coeffs, jax.core.Tracer):
        coeffs = _concrete_finite("coeffs", coeffs)
    n = coeffs.shape[-1] if coeffs.ndim else 0
    if n < 1 or math.isqrt(n) ** 2 != n:
        raise ValidationError("coeffs", coeffs, f"the last axis must hold (lmax+1)² coefficients, got shape {coeffs.shape}")
    check_lmax(math.isqrt(n) - 1, field="coeffs")
    try:
        np.broadcast_shapes(tuple(coeffs.shape[:-1]), tuple(dirs.shape[:-1]))
    except ValueError:
        reason = f"batch shape {coeffs.shape[:-1]} does not broadcast with dirs {dirs.shape[:-1]}"
        raise ValidationError("coeffs", coeffs, reason) from None
    if isinstance(coeffs, jax.core.Tracer) or isinstance(dirs, jax.core.Tracer):
        return _evaluate_kernel(jnp.asarray(coeffs), jnp.asarray(dirs))
    dt = _float_dtype(coeffs.dtype, dirs.dtype)
    if dt == np.float64:
        with jax.enable_x64(True):
            return _evaluate_kernel(jnp.asarray(coeffs, jnp.float64), jnp.asarray(dirs, jnp.float64))
    return _evaluate_kernel(jnp.asarray(coeffs, jnp.float32), jnp.asarray(dirs, jnp.float32))
