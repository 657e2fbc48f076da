"""In-plane angles of generalized sectors (satf §6.2.1): each sector's normal-plane frame and
the azimuths of the view and the lights in it.

Shared by the planner (which measures the angles a scene's sectors produce before anything
is baked) and the online module (Params(b) of every sector, each view).  Angles in a
sector's plane are azimuths in [0, 2π) from the sector's local +x axis (the outward ellipse
normal at its parametric centre; +y the tangent of increasing phase: the HRIR tracer's frame).

The HRIR database samples these angles on one periodic grid, :func:`angle_grid` (θ_i = 2πi/n),
and :func:`grid_cell` says between which two of its nodes an angle falls (interpolation wraps).
"""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi


def _unit2(x):
    return x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-300)


def sector_axes(geometry, table):
    """Each sector's normal-plane frame: 3-D ``reference`` and ``binormal`` (N, 3) of its cross-section
    and its in-plane +x (the outward ellipse normal at its parametric centre) and +y (N, 2).

    ``geometry``: a :class:`~hairlut.geometry.ClusterGeometry`; ``table``: its
    :class:`~hairlut.geometry.SectorTable`."""
    sec = geometry.sections(np.linspace(0.0, 1.0, table.shape[1]))
    ab, phi = table.half_axes, table.twist + table.u_range.mean(axis=1)
    ex = _unit2(np.stack([ab[:, 1] * np.cos(phi), ab[:, 0] * np.sin(phi)], axis=1))
    ey = np.stack([-ex[:, 1], ex[:, 0]], axis=1)  # +90°: increasing phase
    return sec.normal[table.cluster, table.t_index], sec.binormal[table.cluster, table.t_index], ex, ey


def azimuths(reference, binormal, ex, ey, view, lights):
    """θv (N,) and θl (N, Lt): the directions projected into each sector's normal plane, as azimuths from +x."""

    def azimuth(d):
        d2 = np.stack([reference @ d, binormal @ d], axis=-1)
        return np.mod(np.arctan2(np.sum(d2 * ey, -1), np.sum(d2 * ex, -1)), TWO_PI)

    tl = np.stack([azimuth(l) for l in np.atleast_2d(np.asarray(lights, np.float64))], axis=1)
    return azimuth(np.asarray(view, np.float64)), tl


def angle_grid(n: int) -> np.ndarray:
    """The periodic in-plane angle grid θ_i = 2πi/n, i = 0 … n−1 (the HRIR database's view and light axes)."""
    return TWO_PI * np.arange(n) / n


def grid_cell(theta, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Periodic linear interpolation on :func:`angle_grid` (n): the node i0 at or below each angle (any real
    value) and the fraction toward node (i0 + 1) mod n."""
    f = np.mod(np.asarray(theta, np.float64), TWO_PI) / TWO_PI * n
    i0 = np.floor(f)
    return i0.astype(np.int64) % n, f - i0
