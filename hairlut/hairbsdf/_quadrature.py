"""The quadrature of the hair tables: Gauss–Legendre panels and the azimuthal crossings they are graded about.

Every integral of :mod:`._energy` and :mod:`._coverage` is a sum of m-point Gauss–Legendre rules on the panels
between sorted breaks (:func:`_panels`), each value's error estimate the difference from the rule with m/2 nodes
on the same panels.

The h integrals of the BSDF tables (the fibre of Chiang et al. 2016, "A Practical and Controllable Hair and Fur
Model for Production Path Tracing", :mod:`._bsdf`) are taken in γ = asin h (dh = cos γ dγ removes the
square-root end points).  The share c_p(h) of lobe p's azimuthal distribution N_p (Chiang's trimmed logistic,
[Chiang §4.2], after d'Eon et al. 2011) that falls in the back half of azimuth (|φ_i − φ_o| < π/2, Zinke et
al. 2008's split) is a closed form of the logistic's distribution function (:func:`back_fraction`).  At low
roughness c_p jumps from 0 to 1 over a width s/|dΦ_p/dγ| where Φ_p(γ) crosses ±π/2 (mod 2π): those crossings
are found by bisection (:func:`_crossings`, on the monotone pieces of Φ_p, split at the TRT caustic where
dΦ_2/dγ = 0) and the panels are graded geometrically about each (:func:`_h_breaks`), so the quadrature
converges exponentially at every roughness (the widths use the second derivative too, so a crossing at a
caustic is resolved).
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from . import _bsdf as B

_BISECTION = 64
_HALF_PI = 0.5 * math.pi


# ----------------------------------------------------------------------------- quadrature helpers


@functools.cache
def _gauss(m: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes and weights on [−1, 1] (float64)."""
    x, w = np.polynomial.legendre.leggauss(m)
    return x, w


def _panels(breaks, m: int):
    """Nodes and weights of m-point Gauss–Legendre on each panel between consecutive sorted ``breaks`` (..., B):
    (..., (B−1)·m) each; zero-width panels carry zero weight."""
    x, w = _gauss(m)
    lo, hi = breaks[..., :-1], breaks[..., 1:]
    half, mid = 0.5 * (hi - lo), 0.5 * (hi + lo)
    nodes = mid[..., None] + half[..., None] * x
    weights = half[..., None] * w
    shape = (*breaks.shape[:-1], (breaks.shape[-1] - 1) * m)
    return nodes.reshape(shape), weights.reshape(shape)


def _graded(levels: int, ratio: float) -> np.ndarray:
    """Offsets 0, ±1, ±ratio, …, ±ratio^(levels−1) (in units of a feature's width)."""
    g = ratio ** np.arange(levels, dtype=np.float64)
    return np.concatenate([[0.0], g, -g])


# ----------------------------------------------------------------------------- the azimuthal crossings


def _psi(p, k, g):
    """ψ_p(γ) = Φ_p − pπ = 2p asin(k sin γ) − 2γ (k = 1/η′); odd in γ."""
    return 2.0 * p * jnp.arcsin(k * jnp.sin(g)) - 2.0 * g


def _dpsi(p, k, g):
    return 2.0 * p * k * jnp.cos(g) / jnp.sqrt(1.0 - (k * jnp.sin(g)) ** 2) - 2.0


def _d2psi(p, k, g):
    return 2.0 * p * k * jnp.sin(g) * (k * k - 1.0) / (1.0 - (k * jnp.sin(g)) ** 2) ** 1.5


def _caustic(p: int, k):
    """The γ ≥ 0 where dψ_p/dγ = 0 (sin²γ = (p²k² − 1)/((p² − 1)k²), when p k > 1), else 0."""
    if p < 2:
        return jnp.zeros_like(k)
    ok = p * k > 1.0
    ks = jnp.where(ok, k, 1.0)
    s2 = jnp.clip((p * p * ks * ks - 1.0) / ((p * p - 1.0) * ks * ks), 0.0, 1.0)
    return jnp.where(ok, jnp.arcsin(jnp.sqrt(s2)), 0.0)


def _crossings(lobes: tuple[int, ...], k):
    """The γ ∈ [−π/2, π/2] where Φ_p crosses ±π/2 (mod 2π), the edges of the back half of azimuth, for each lobe p of
    ``lobes`` (all p ≤ 1, or all p = 2: the lobes of one call share their bisection).

    ψ_p stays within [−π, π] for p ≤ 2 (|asin(k sin γ)| ≤ |γ|), so the crossings are those of ψ_p = ±π/2, found by
    bisection on the monotone pieces of [0, π/2] and mirrored (ψ_p is odd).  On [0, π/2], ψ_0 and ψ_1 fall from 0
    (only −π/2 can be crossed); ψ_2 rises to the caustic γ_c, where it is ≥ 0 (only +π/2), then falls (either).
    Returns (γ (L, S), valid (L, S)): S = 2 for p ≤ 1, 6 for p = 2."""
    p = jnp.asarray(lobes, jnp.float64)[:, None]
    gc = _caustic(lobes[0], k)
    zero, top = 0.0 * k, 0.0 * k + _HALF_PI
    slots = [(zero, top, -_HALF_PI)] if lobes[0] < 2 else [(zero, gc, _HALF_PI), (gc, top, _HALF_PI), (gc, top, -_HALF_PI)]
    shape = (len(lobes), len(slots))
    a = jnp.broadcast_to(jnp.stack([lo for lo, _, _ in slots]), shape)
    b = jnp.broadcast_to(jnp.stack([hi for _, hi, _ in slots]), shape)
    tau = jnp.asarray([t for _, _, t in slots])
    fa, fb = _psi(p, k, a) - tau, _psi(p, k, b) - tau
    valid = fa * fb < 0.0

    def step(_, state):
        lo, hi, flo = state
        mid = 0.5 * (lo + hi)
        fm = _psi(p, k, mid) - tau
        same = fm * flo > 0.0
        return jnp.where(same, mid, lo), jnp.where(same, hi, mid), jnp.where(same, fm, flo)

    lo, hi, _ = jax.lax.fori_loop(0, _BISECTION, step, (a, b, fa))
    root = 0.5 * (lo + hi)
    return jnp.concatenate([root, -root], axis=-1), jnp.concatenate([valid, valid], axis=-1)


def back_fraction(phi, s):
    """c = ∫_{|φ′| < π/2} N(φ′) dφ′ for the trimmed logistic N of scale s centred on ``phi``: the share of a
    lobe scattered into the back half of azimuth (a closed form of the logistic distribution function)."""
    d = jnp.abs(B.wrap_angle(phi))
    lc = functools.partial(B.logistic_cdf, s=s)
    num = lc(_HALF_PI - d) - lc(jnp.maximum(-math.pi, -_HALF_PI - d)) + lc(math.pi) - lc(jnp.minimum(math.pi, 1.5 * math.pi - d))
    return jnp.clip(num / jnp.tanh(0.5 * math.pi / s), 0.0, 1.0)


# ----------------------------------------------------------------------------- the γ panels of the BSDF tables


def _h_breaks(lobes: tuple[int, ...], k, s, levels: int):
    """The γ panel breaks (L, R, B) of each lobe of ``lobes`` (as :func:`_crossings`) and roughness (scale s (R,)):
    graded geometrically about each crossing in units of its width, plus ±π/2, 0 and ±γ_c."""
    gam, valid = _crossings(lobes, k)  # (L, S)
    p = jnp.asarray(lobes, jnp.float64)[:, None]
    slope = jnp.abs(_dpsi(p, k, gam))[:, None, :]
    curve = jnp.abs(_d2psi(p, k, gam))[:, None, :]
    s_ = s[None, :, None]
    width = s_ / jnp.maximum(jnp.maximum(slope, jnp.sqrt(0.5 * s_ * curve)), 1e-300)
    width = jnp.minimum(width, math.pi / 8.0)  # (L, R, S)
    offsets = jnp.asarray(_graded(levels, 4.0))
    pts = jnp.where(valid[:, None, :, None], gam[:, None, :, None] + width[..., None] * offsets, -_HALF_PI)
    gc = _caustic(lobes[0], k)
    fixed = jnp.broadcast_to(jnp.stack([-_HALF_PI + 0.0 * k, 0.0 * k, _HALF_PI + 0.0 * k, gc, -gc]), (*width.shape[:2], 5))
    pts = jnp.concatenate([pts.reshape(*width.shape[:2], -1), fixed], axis=-1)
    return jnp.sort(jnp.clip(pts, -_HALF_PI, _HALF_PI), axis=-1)
