"""Sector density fields: sums of strand Gaussians on a parametric grid (satf §3.3).

For a :class:`~hairlut.geometry.splats.SplatBatch` (see ``splats`` for the coordinates,
σ = r/√2 and the mass κ·π r²), the density of cell (i, j) of sector n is

    ρ[n, i, j] = Σ_k m_k · ΔΦ_s[k, i] · ΔΦ_r[k, j] / area[n, j],
    ΔΦ_s[k, i] = Φ((s_{i+1} − c_k,s)/σ_k,s) − Φ((s_i − c_k,s)/σ_k,s)   (likewise r),

Φ the standard normal CDF and area[n, j] the exact metric area of a cell in row j.  The
cell masses are exact integrals of the Gaussian (separable erf differences, not point
samples), so Σ ρ·area over the grid is a strand's mass times the fraction of its
Gaussian that lies inside the sector — all of it for a strand well inside, exactly half
for one centred on an edge.

:func:`sector_density` runs one jitted kernel (vmapped over sectors; splats padded to a
common width and masked) over all sectors of all clusters, in chunks of ``chunk``
sectors taken in order of their splat count, so that each chunk is padded only to the
next width of 8, 12, 16, 24, 32, 48, … above its own largest count (real clusters have
a long tail: a few sectors hold many more strands than the mean).  Chunk shapes come from a small set, so the
compiled kernel is reused.  ``chunk=1`` (the HRIR bake's: a sector's bits must not depend on
its neighbours) pads each sector to its own width and maps the one-sector program over the
sectors of each width inside one call, bitwise the same as one call per sector at a
fraction of the host's cost.  float32 by default; float64 under ``jax.enable_x64`` when asked.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import erfc

from ..errors import ValidationError
from .splats import SplatBatch

DEFAULT_GRID = (32, 32)
_INV_SQRT2 = float(1.0 / np.sqrt(2.0))  # a Python float: weakly typed, keeps the array dtype


def check_grid(grid) -> tuple[int, int]:
    """(n_s, n_r) from an int or a pair; each ≥ 1."""
    pair = (grid, grid) if np.ndim(grid) == 0 else tuple(grid)
    if len(pair) != 2 or any(isinstance(g, bool) or not isinstance(g, (int, np.integer)) or g < 1 for g in pair):
        raise ValidationError("grid", grid, "the grid is an integer ≥ 1 or a pair (n_s, n_r) of them")
    return int(pair[0]), int(pair[1])


def _cdf_diff(edges, center, sigma):
    """(K, n) Φ(b) − Φ(a) over the cells [a, b] (standardised).

    One erfc per edge: T(z) = ½ erfc(|z|/√2) is the tail beyond z, and a cell is
    T(a) − T(b) above the mean, T(b) − T(a) below it and 1 − T(a) − T(b) across it —
    differences of tails, which keep float32 relative precision far from the mean.
    """
    z = (edges[None, :] - center[:, None]) / sigma[:, None]
    tail = 0.5 * erfc(jnp.abs(z) * _INV_SQRT2)
    lo, hi = z[:, :-1], z[:, 1:]
    t_lo, t_hi = tail[:, :-1], tail[:, 1:]
    return jnp.where(lo >= 0, t_lo - t_hi, jnp.where(hi <= 0, t_hi - t_lo, 1.0 - t_lo - t_hi))


def _cell_mass(center, sigma, mass, n_s: int, n_r: int):
    """(n_s, n_r) Gaussian mass per cell for one sector's K splats."""
    es = jnp.linspace(0.0, 1.0, n_s + 1, dtype=center.dtype)
    er = jnp.linspace(0.0, 1.0, n_r + 1, dtype=center.dtype)
    ws = _cdf_diff(es, center[:, 0], sigma[:, 0])
    wr = _cdf_diff(er, center[:, 1], sigma[:, 1])
    return jnp.einsum("k,ki,kj->ij", mass, ws, wr, precision=jax.lax.Precision.HIGHEST)


def _row_area(area_scale, v_range, n_s: int, n_r: int):
    """½ (v_{j+1}² − v_j²) · area_scale / n_s, written as Δ (v0 + (j + ½) Δ) to avoid cancellation."""
    step = (v_range[1] - v_range[0]) / n_r
    mid = v_range[0] + (jnp.arange(n_r, dtype=v_range.dtype) + 0.5) * step
    return area_scale / n_s * step * mid


def _density_one(center, sigma, radius, mask, area_scale, v_range, scale, n_s, n_r):
    mass = jnp.where(mask, scale * jnp.pi * radius * radius, 0.0)
    sig = jnp.where(mask[:, None], sigma, 1.0)
    cells = _cell_mass(center, sig, mass, n_s, n_r)
    return cells / _row_area(area_scale, v_range, n_s, n_r)[None, :]


@partial(jax.jit, static_argnames=("n_s", "n_r", "each"))
def density_kernel(center, sigma, radius, mask, area_scale, v_range, scale, *, n_s: int, n_r: int, each: bool = False):
    """(N, n_s, n_r) densities of N padded sectors (the jitted kernel behind :func:`sector_density`).

    ``each``: the sectors one after another (``lax.map`` of the one-sector batch), each computed by the
    very program of a one-sector call, so its bits do not depend on the others: the ``chunk=1`` path
    in one call per splat width instead of one per sector."""
    one = jax.vmap(partial(_density_one, scale=scale, n_s=n_s, n_r=n_r))
    args = (center, sigma, radius, mask, area_scale, v_range)
    if each:
        return jax.lax.map(lambda a: one(*(x[None] for x in a))[0], args)
    return one(*args)


def _bucket(n: int, least: int) -> int:
    return 1 << (max(int(n), least) - 1).bit_length()


def _width(k: int) -> int:
    """Padded splat width for a largest count k: the first of 8, 12, 16, 24, 32, 48, … ≥ k."""
    w, step = 8, 0
    while w < k:
        w = 8 * (1 << (step + 1) // 2) * (3 if step % 2 == 0 else 2) // 2
        step += 1
    return w


def _as_dtype(dtype) -> np.dtype:
    dt = np.dtype(dtype)
    if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValidationError("dtype", str(dt), "float32 or float64")
    return dt


def sector_density(
    splats: SplatBatch, grid=DEFAULT_GRID, *, density_scale: float = 1.0, dtype=np.float32, chunk: int = 1024
) -> np.ndarray:
    """(N, n_s, n_r) density of every sector (module docstring); axis 1 is s (phase), axis 2 is r (radius).

    With ``density_scale`` = 1 a value is the fraction of the cell's area covered by hair.
    """
    if not isinstance(splats, SplatBatch):
        raise ValidationError("splats", type(splats).__name__, "must be a SplatBatch")
    n_s, n_r = check_grid(grid)
    scale = float(density_scale)
    if not np.isfinite(scale) or scale <= 0:
        raise ValidationError("density_scale", density_scale, "must be finite and > 0")
    if isinstance(chunk, bool) or not isinstance(chunk, (int, np.integer)) or chunk < 1:
        raise ValidationError("chunk", chunk, "must be an integer ≥ 1")
    dt = _as_dtype(dtype)
    if splats.n_sectors == 0:
        return np.zeros((0, n_s, n_r), dt)
    n = splats.n_sectors
    center, sigma, radius, mask = splats.center, splats.sigma, splats.radius, splats.mask
    if (mask[:, 1:] > mask[:, :-1]).any():  # move each sector's real slots to the front
        perm = np.argsort(~mask, axis=1, kind="stable")
        center, sigma = (np.take_along_axis(a, perm[..., None], 1) for a in (center, sigma))
        radius, mask = (np.take_along_axis(a, perm, 1) for a in (radius, mask))
    counts = mask.sum(axis=1)
    out = np.empty((n, n_s, n_r), dt)
    with jax.enable_x64(dt == np.float64):
        jscale = jnp.asarray(scale, dt)

        def run(idx, size, width, each=False):
            rows = np.concatenate([idx, np.full(size - idx.size, idx[0])])  # fixed chunk shape
            args = [
                _columns(center[rows], width, 0.0),
                _columns(sigma[rows], width, 1.0),
                _columns(radius[rows], width, 0.0),
                _columns(mask[rows], width, False),
                splats.area_scale[rows],
                splats.v_range[rows],
            ]
            arrs = [jnp.asarray(x, dtype=dt if x.dtype.kind == "f" else None) for x in args]
            out[idx] = np.asarray(density_kernel(*arrs, jscale, n_s=n_s, n_r=n_r, each=each))[: idx.size]

        if int(chunk) == 1:  # each sector padded to its own width, as if alone: one call per width
            widths = np.array([_width(int(c)) for c in counts])
            for width in np.unique(widths):
                idx = np.flatnonzero(widths == width)
                run(idx, _bucket(idx.size, 8), int(width), each=True)
            return out
        order = np.argsort(counts, kind="stable")
        size = min(int(chunk), _bucket(n, 8))
        for start in range(0, n, size):
            idx = order[start : start + size]
            run(idx, size, _width(int(counts[idx].max())))  # padding follows the chunk's own largest count
    return out


def _columns(a: np.ndarray, width: int, fill) -> np.ndarray:
    """The first ``width`` slots of ``a`` (N, K, ...), padded with ``fill`` if K < width."""
    if a.shape[1] >= width:
        return a[:, :width]
    pad = [(0, 0), (0, width - a.shape[1])] + [(0, 0)] * (a.ndim - 2)
    return np.pad(a, pad, constant_values=fill)


def sector_density_numpy(splats: SplatBatch, grid=DEFAULT_GRID, *, density_scale: float = 1.0) -> np.ndarray:
    """The same densities by a plain float64 NumPy loop over sectors (a reference and a baseline)."""
    from scipy.special import ndtr as np_ndtr

    def cdf_diff(edges, c, s):
        z = (edges[None, :] - c[:, None]) / s[:, None]
        lo, hi = z[:, :-1], z[:, 1:]
        return np.where(lo > 0, np_ndtr(-lo) - np_ndtr(-hi), np_ndtr(hi) - np_ndtr(lo))

    n_s, n_r = check_grid(grid)
    es, er = np.linspace(0.0, 1.0, n_s + 1), np.linspace(0.0, 1.0, n_r + 1)
    areas = splats.row_areas(n_s, n_r)
    out = np.zeros((splats.n_sectors, n_s, n_r))
    for n in range(splats.n_sectors):
        m = splats.mask[n]
        c, s, r = splats.center[n][m], splats.sigma[n][m], splats.radius[n][m]
        ws, wr = cdf_diff(es, c[:, 0], s[:, 0]), cdf_diff(er, c[:, 1], s[:, 1])
        out[n] = ((density_scale * np.pi * r * r)[:, None] * ws).T @ wr / areas[n][None, :]
    return out


def sector_mean_density(table, *, density_scale: float = 1.0) -> np.ndarray:
    """(N,) float32 ``rho_st`` of every sector of a :class:`~hairlut.geometry.SectorTable` without a density grid.

    ``rho_st`` = Σ ρ a / Σ a (``features``) is grid-independent: the cell masses of :func:`sector_density` are exact
    integrals, so Σ ρ a is each splat's mass κ·π r² times the fraction of its Gaussian inside the sector,
    (Φ((1 − c_s)/σ_s) − Φ(−c_s/σ_s)) · (Φ((1 − c_r)/σ_r) − Φ(−c_r/σ_r)), and Σ a the sector's area
    A·B·Δu·½(v₁² − v₀²).  Computed from the table's flat splats in float64 (one pass over them, no padding): what
    the map methods that read no database keep as their one feature, at a fraction of the grid's cost."""
    from scipy.special import ndtr

    def inside(c, s):
        """Φ((1 − c)/s) − Φ(−c/s), the mass in [0, 1]: symmetric under c → 1 − c, so with c ≤ ½ the upper edge lies
        above the mean, and the mass is a difference of tails (far from the mean keeps its precision) in two Φ."""
        c = np.minimum(c, 1.0 - c)
        lo, hi = -c / s, (1.0 - c) / s
        a, b = ndtr(-np.abs(lo)), ndtr(-hi)
        return np.where(lo > 0, a - b, 1.0 - a - b)

    n = len(table.splat_offsets) - 1
    sector = np.repeat(np.arange(n), np.diff(table.splat_offsets))
    c, s = table.splat_center, table.splat_sigma
    r = table.splat_radius()
    mass = float(density_scale) * np.pi * r * r * inside(c[:, 0], s[:, 0]) * inside(c[:, 1], s[:, 1])
    v0, v1 = table.v_range[:, 0], table.v_range[:, 1]
    area = table.half_axes[:, 0] * table.half_axes[:, 1] * (table.u_range[:, 1] - table.u_range[:, 0]) * 0.5 * (v1**2 - v0**2)
    return (np.bincount(sector, weights=mass, minlength=n) / area).astype(np.float32)
