"""Sector frames for planar ray tracing: centre, orientation, extent, extinction and smoothing width.

From the parameters of a sampled sector (``hairlut.geometry.sampler``: ``phase``,
``s_u``, ``v_range``, ``aspect``, and the strand ``radius`` relative to √area) this builds
the per-sector rows of :data:`hairlut.hrir._tracer.GEOM` in float64 (see the tracer's
docstring for the frame and pixel conventions).
"""

from __future__ import annotations

import numpy as np

from ..errors import ValidationError
from ..geometry.splats import SIGMA_PER_RADIUS
from ._march import GEOM

#: Smoothing width over the strand Gaussian's σ (satf §5.1: "a ratio of 1.5").
SMOOTH_RATIO = 1.5


def _edge_points(phase, du, v0, v1, aspect, n: int = 129):
    """(N, 4n, 2) points on the four edges of each sector (ellipse coordinates)."""
    t = np.linspace(0.0, 1.0, n)
    phi_arc = phase[:, None] + du[:, None] * t[None, :]
    v_rad = v0[:, None] + (v1 - v0)[:, None] * t[None, :]
    pts = []
    for v in (v0[:, None] * np.ones_like(t), v1[:, None] * np.ones_like(t)):
        pts.append(np.stack([v * np.cos(phi_arc), aspect[:, None] * v * np.sin(phi_arc)], -1))
    for phi in (phase, phase + du):
        pts.append(np.stack([v_rad * np.cos(phi)[:, None], aspect[:, None] * v_rad * np.sin(phi)[:, None]], -1))
    return np.concatenate(pts, axis=1)


def sector_geometry(params: dict, *, kappa: float, n_pix: int, smooth_ratio: float = SMOOTH_RATIO) -> np.ndarray:
    """(N, len(GEOM)) float64 geometry rows of sampled sectors.

    ``kappa``: extinction per unit density in units of 1/strand-radius (σ_t = κ / r).
    """
    phase = np.asarray(params["phase"], np.float64)
    du = 2 * np.pi / np.asarray(params["s_u"], np.float64)
    vr = np.asarray(params["v_range"], np.float64)
    v0, v1 = vr[:, 0], vr[:, 1]
    aspect = np.asarray(params["aspect"], np.float64)
    if not ((aspect > 0).all() and (v1 > v0).all() and (v0 >= 0).all() and (du > 0).all() and (du <= 2 * np.pi).all()):
        raise ValidationError("sectors", "geometry", "need aspect > 0, 0 ≤ v0 < v1 and 0 < Δu ≤ 2π")
    vm, pm = 0.5 * (v0 + v1), phase + 0.5 * du
    cx, cy = vm * np.cos(pm), aspect * vm * np.sin(pm)
    beta = np.arctan2(np.sin(pm), aspect * np.cos(pm))  # outward normal (B cos φ, A sin φ), A = 1
    pts = _edge_points(phase, du, v0, v1, aspect)
    extent = np.sqrt(((pts - np.stack([cx, cy], -1)[:, None, :]) ** 2).sum(-1)).max(axis=1)
    area = aspect * du * 0.5 * (v1**2 - v0**2)
    r_strand = np.asarray(params["radius_rel"], np.float64) * np.sqrt(area)
    sigma_t = kappa / r_strand
    sigma_px = smooth_ratio * SIGMA_PER_RADIUS * r_strand / (2 * extent / n_pix)
    cols = {
        "phase": phase,
        "du": du,
        "v0": v0,
        "v1": v1,
        "aspect": aspect,
        "cx": cx,
        "cy": cy,
        "beta": beta,
        "extent": extent,
        "sigma_t": sigma_t,
        "sigma_px": sigma_px,
    }
    return np.stack([cols[k] for k in GEOM], axis=1)


def disc_params(n: int = 1, *, radius_rel: float = 0.05, aspect: float = 1.0) -> dict:
    """Parameters of ``n`` full discs (v ∈ [0, 1], Δu = 2π, phase 0): the analytic test case."""
    return {
        "phase": np.zeros(n),
        "s_u": np.ones(n, np.int64),
        "v_range": np.tile([[0.0, 1.0]], (n, 1)),
        "aspect": np.full(n, aspect),
        "radius_rel": np.full(n, radius_rel),
    }
