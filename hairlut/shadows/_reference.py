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
    world-aligned density (``voxelize``: strand length per unit volume), until the ray leaves it."""
    vol = volume if volume is not None else voxelize(strands, resolution)
    rho = vol.density / vol.size**2  # voxelize stores length / s; per unit volume is length / s³
    g = vol.to_grid(np.asarray(points, np.float64))
    light = np.asarray(light, np.float64) / np.linalg.norm(light)
    tau = np.zeros(len(g))
    for k in range(int(np.linalg.norm(vol.shape) / step) + 2):
        p = g + (k + 0.5) * step * light
        live = np.all((p > -1) & (p < np.array(vol.shape)), 1)
        if not live.any():
            break
        tau[live] += trilinear_np(rho, p[live])
    return np.exp(-kappa * tau * step * vol.size)
