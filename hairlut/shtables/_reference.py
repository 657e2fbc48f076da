"""Slow, independent reference for R(i, j, t, θ′): direct quadrature on the sphere.

No Legendre expansion and no Gaunt coefficients: ω is parametrised in a frame
around t, ω = cos θ t + sin θ (cos φ e₁ + sin φ e₂); φ uses the uniform rule
(exact for the trigonometric polynomial Y_i Y_j of degree ≤ l_i + l_j), and θ
uses Gauss–Legendre on pieces split at every kink of the kernel (the clamp
θ + θ′ = π/2, the peak θ + θ′ = π and the clamp θ + θ′ = 3π/2), graded toward
the clamps.  NumPy float64 throughout; meant for tests and benchmarks.
"""

from __future__ import annotations

import numpy as np

from .. import kernels as kk
from ..sh import real_sh


def _frame(t):
    t = np.asarray(t, np.float64)
    helper = np.array([1.0, 0.0, 0.0]) if abs(t[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(t, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(t, e1)


def _theta_rule(breaks, n):
    x, w = np.polynomial.legendre.leggauss(n)
    s, ws = 0.5 * (x + 1), 0.5 * w
    nodes, weights = [], []
    for a, b in zip(breaks[:-1], breaks[1:]):
        if b - a <= 0:
            continue
        # grade toward both ends: θ = a + (b−a)·g(s), g(s) = 3s² − 2s³ (g′ vanishes at the ends)
        g, dg = 3 * s**2 - 2 * s**3, 6 * s - 6 * s**2
        nodes.append(a + (b - a) * g)
        weights.append((b - a) * dg * ws)
    return np.concatenate(nodes), np.concatenate(weights)


def reference_r(t, theta_v, p, lmax_i, lmax_j, specular=True, n_theta=200):
    """R(i, j) at one tangent t and one θ′ (ignored for the diffuse kernel): ((lmax_i+1)², (lmax_j+1)²)."""
    e1, e2 = _frame(t)
    if specular:
        kinks = [np.pi / 2 - theta_v, np.pi - theta_v, 3 * np.pi / 2 - theta_v]
        breaks = sorted({0.0, np.pi, *[k for k in kinks if 0 < k < np.pi]})
    else:
        breaks = [0.0, np.pi / 2, np.pi]
    theta, wt = _theta_rule(breaks, n_theta)
    n_phi = lmax_i + lmax_j + 2
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    omega = ct[..., None] * t + st[..., None] * (np.cos(phi)[None, :, None] * e1 + np.sin(phi)[None, :, None] * e2)
    kernel = kk.specular(theta, theta_v, p) if specular else kk.diffuse(theta)
    w = (wt * kernel * np.sin(theta))[:, None] * (2 * np.pi / n_phi)
    y = np.asarray(real_sh(max(lmax_i, lmax_j), omega.reshape(-1, 3), normalize=True))
    yi, yj = y[:, : (lmax_i + 1) ** 2], y[:, : (lmax_j + 1) ** 2]
    return np.einsum("n,ni,nj->ij", np.broadcast_to(w, omega.shape[:2]).ravel(), yi, yj)
