"""Strand splats on generalized sectors: the input of the sector density kernel (satf §3.3).

A strand crossing a cross-section at (v, u) of eq 1 is a circular disc of radius r in
the normal plane (r widened to r / √cos γ for a strand tilted by γ: ``sectors``' module docstring).  Its density is a 2-D Gaussian of total mass m = κ·π r² (κ the density
scale) and standard deviation

    σ = r / √2                                            (SIGMA_PER_RADIUS = 1/√2)

chosen so that a lone strand's peak density m/(2πσ²) equals κ: the density then reads
as the fraction of area covered by hair (times κ), the quantity opacity is proportional
to in planar ray tracing (eq 5).

The density grid of a sector is parametric: cell (i, j) spans s ∈ [i/n_s, (i+1)/n_s)
along the phase u and r ∈ [j/n_r, (j+1)/n_r) along the radius v.  Every sector, whatever
its size and shape, then has the same grid, the layout the HRIR database and the
layers' texture space (u, v) use.  The Gaussian is carried into (v, u) by the local
Jacobian of eq 1, keeping its metric area: with φ = q + u,
|∂P/∂u| = v·g_u, g_u = √(A² sin²φ + B² cos²φ) and |∂P/∂v| = g_v = √(A² cos²φ + B² sin²φ),

    σ_u = σ·√(g_v / (g_u A B)) / v,   σ_v = σ·√(g_u / (g_v A B)),   so σ_u σ_v · A B v = σ².

(For a circular cluster this is exact to first order; an elliptical one drops the shear
term.)  σ_u is capped at π/3 near the axis, where a disc covers all phases.  The splat
is then an axis-aligned Gaussian in (u, v), so its mass in any cell is a product of two
1-D normal-CDF differences, and the density of a cell is that mass divided by the
cell's exact metric area A·B·Δu/n_s·(v_{j+1}² − v_j²)/2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ValidationError

SIGMA_PER_RADIUS = float(1.0 / np.sqrt(2.0))
MAX_SIGMA_U = float(np.pi / 3.0)


def param_sigma(sigma, v, phi, a, b) -> tuple[np.ndarray, np.ndarray]:
    """(σ_u, σ_v): a metric σ at (v, φ = q + u) on an ellipse (A, B), in eq-1 parameter units."""
    sigma, v, phi, a, b = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (sigma, v, phi, a, b)))
    g_u = np.sqrt((a * np.sin(phi)) ** 2 + (b * np.cos(phi)) ** 2)
    g_v = np.sqrt((a * np.cos(phi)) ** 2 + (b * np.sin(phi)) ** 2)
    ab = a * b
    s_u = np.full(v.shape, MAX_SIGMA_U)
    ok = v > 0
    np.divide(sigma * np.sqrt(g_v / (g_u * ab)), v, out=s_u, where=ok)
    s_v = sigma * np.sqrt(g_u / (g_v * ab))
    return np.minimum(s_u, MAX_SIGMA_U), s_v


@dataclass(frozen=True, eq=False)
class SplatBatch:
    """Padded splats of N sectors, K slots each, plus the sector shapes the kernel needs.

    ``center`` (N, K, 2) and ``sigma`` (N, K, 2) are (s, r) in the sector's parametric
    units (centres may lie outside [0, 1]²: a neighbour's strand); ``radius`` (N, K) the
    metric radius of the splat's disc (a strand's, widened for its tilt: ``sectors``); ``mask`` (N, K) marks real slots.  ``area_scale`` (N,) is
    A·B·Δu and ``v_range`` (N, 2) the sector's radial range, so that the metric area of
    cell row j is area_scale/n_s · (v_{j+1}² − v_j²)/2.
    """

    center: np.ndarray
    sigma: np.ndarray
    radius: np.ndarray
    mask: np.ndarray
    area_scale: np.ndarray
    v_range: np.ndarray

    def __post_init__(self) -> None:
        n, k = np.shape(self.mask)
        shapes = {"center": (n, k, 2), "sigma": (n, k, 2), "radius": (n, k), "area_scale": (n,), "v_range": (n, 2)}
        for name, shape in shapes.items():
            if np.shape(getattr(self, name)) != shape:
                raise ValidationError(name, np.shape(getattr(self, name)), f"expected shape {shape}")
        m = np.asarray(self.mask, dtype=bool)
        object.__setattr__(self, "mask", m)
        if not (np.asarray(self.sigma)[m] > 0).all():
            raise ValidationError("sigma", "≤ 0", "splat widths must be > 0")
        if not (np.asarray(self.radius)[m] >= 0).all():
            raise ValidationError("radius", "< 0", "strand radii must be ≥ 0")
        if not (np.asarray(self.area_scale) > 0).all():
            raise ValidationError("area_scale", "≤ 0", "sector area scales must be > 0")
        vr = np.asarray(self.v_range)
        if not ((vr[:, 1] > vr[:, 0]) & (vr[:, 0] >= 0)).all():
            raise ValidationError("v_range", "bad", "sector radial ranges need 0 ≤ v0 < v1")

    @property
    def n_sectors(self) -> int:
        return self.mask.shape[0]

    @property
    def max_splats(self) -> int:
        return self.mask.shape[1]

    def take(self, index) -> SplatBatch:
        """The batch restricted to sectors ``index`` (any integer index array or slice)."""
        return SplatBatch(
            *(np.asarray(getattr(self, f))[index] for f in ("center", "sigma", "radius", "mask", "area_scale", "v_range"))
        )

    def row_areas(self, n_s: int, n_r: int) -> np.ndarray:
        """(N, n_r) exact metric area of one cell in each grid row."""
        v0, v1 = self.v_range[:, 0:1], self.v_range[:, 1:2]
        step = (v1 - v0) / n_r
        return self.area_scale[:, None] / n_s * step * (v0 + (np.arange(n_r) + 0.5) * step)

    def sector_areas(self) -> np.ndarray:
        """(N,) metric area of each sector."""
        return self.area_scale * 0.5 * (self.v_range[:, 1] ** 2 - self.v_range[:, 0] ** 2)


def pack(sector, center, sigma, radius, n_sectors: int, area_scale, v_range, max_splats: int | None = None) -> SplatBatch:
    """Pad flat splats (J,) with sector indices into a :class:`SplatBatch` of ``n_sectors`` sectors.

    ``max_splats`` (default: the largest count) must not be exceeded: nothing is dropped.
    """
    sector = np.asarray(sector, dtype=np.int64)
    counts = np.bincount(sector, minlength=n_sectors) if sector.size else np.zeros(n_sectors, np.int64)
    need = int(counts.max()) if counts.size else 0
    width = max(need, 1) if max_splats is None else int(max_splats)
    if width < need:
        raise ValidationError("max_splats", max_splats, f"a sector has {need} splats")
    order = np.argsort(sector, kind="stable")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    slot = np.empty(sector.size, dtype=np.int64)
    slot[order] = np.arange(sector.size) - np.repeat(starts, counts)
    c = np.zeros((n_sectors, width, 2))
    s = np.ones((n_sectors, width, 2))
    r = np.zeros((n_sectors, width))
    m = np.zeros((n_sectors, width), dtype=bool)
    c[sector, slot] = center
    s[sector, slot] = sigma
    r[sector, slot] = radius
    m[sector, slot] = True
    return SplatBatch(c, s, r, m, np.asarray(area_scale, dtype=np.float64), np.asarray(v_range, dtype=np.float64))
