"""Slow NumPy references for the light-space shadow methods (tests and benchmarks compare against them)."""

from __future__ import annotations

import numpy as np

from ._volume import voxelize


def trilinear_np(field: np.ndarray, g: np.ndarray) -> np.ndarray:
    """``field`` at continuous cell coordinates g (n, 3), cell centres at integers; zero outside."""
    base = np.floor(g).astype(np.int64)
    frac, shape, out = g - base, np.array(field.shape), np.zeros(len(g))
    for c in range(8):
        o = np.array([(c >> 2) & 1, (c >> 1) & 1, c & 1])
        idx = base + o
        w = np.prod(np.where(o == 1, frac, 1 - frac), 1) * np.all((idx >= 0) & (idx < shape), 1)
        idx = np.clip(idx, 0, shape - 1)
        out += w * field[idx[:, 0], idx[:, 1], idx[:, 2]]
    return out


def ray_march(points, light, kappa: float, strands=None, resolution: int = 32, *, volume=None, step: float = 0.5):
    """T = exp(−κ ∫ ρ dl) from each point toward the light, marched in ``step`` cells through a
    world-aligned density (``voxelize``: strand length per unit volume) over the part of the ray
    inside the grid: a point outside the grid whose ray crosses the hair is shadowed too."""
    vol = volume if volume is not None else voxelize(strands, resolution)
    rho = vol.density / vol.size**2  # voxelize stores length / s; per unit volume is length / s³
    g = vol.to_grid(np.asarray(points, np.float64))
    light = np.asarray(light, np.float64) / np.linalg.norm(light)
    t_in, t_out = _box_span(g, light, np.array(vol.shape, np.float64))
    tau = np.zeros(len(g))
    hit = t_out > t_in
    for k in range(int(np.ceil((t_out - t_in)[hit].max(initial=0.0) / step)) + 1):
        t = t_in + (k + 0.5) * step
        live = hit & (t < t_out)
        if not live.any():
            break
        tau[live] += trilinear_np(rho, g[live] + t[live, None] * light)
    return np.exp(-kappa * tau * step * vol.size)


def _box_span(g: np.ndarray, d: np.ndarray, shape: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ray parameters [t_in, t_out] (t ≥ 0) where g + t d lies in the open box (−1, shape), the
    region where :func:`trilinear_np` can be non-zero (slab method); t_out ≤ t_in where it misses."""
    t_in, t_out = np.zeros(len(g)), np.full(len(g), np.inf)
    for a in range(3):
        if d[a] == 0.0:
            outside = (g[:, a] <= -1) | (g[:, a] >= shape[a])
            t_out = np.where(outside, -np.inf, t_out)
            continue
        t1, t2 = (-1.0 - g[:, a]) / d[a], (shape[a] - g[:, a]) / d[a]
        t_in, t_out = np.maximum(t_in, np.minimum(t1, t2)), np.minimum(t_out, np.maximum(t1, t2))
    return t_in, t_out
