"""Converged hair tables by deterministic quadrature, each value with its estimated error (issue 28).

Three tables, on Unreal Engine's axes (its ``HairStrandsLUT`` bakes them by uniform Monte Carlo), here
computed from the BSDF of :mod:`._bsdf` (Chiang et al. 2016, "A Practical and Controllable Hair and Fur
Model for Production Path Tracing") and the dual-scattering definitions of Zinke, Yuksel, Weber and Keyser
2008, "Dual Scattering Approximation for Fast Multiple Scattering in Hair":

**Axes** (Unreal's, :data:`DEFAULT_AXES`).  Every axis has ``n`` nodes at the *cell centres* of its range
[lo, hi], x_i = lo + (i + ½)(hi − lo)/n, which is where a GPU's bilinear sampler reads texel i:

- ``sin_theta_o`` ∈ [0, 1]: sin θ_o of the outgoing (view) direction against the fibre.  [0, 1] suffices
  for the energies (they depend on cos θ_o only); the longitudinal shifts ᾱ are not symmetric in θ_o when
  the cuticle tilt α ≠ 0, so a range reaching −1 may be asked for.
- ``roughness`` ∈ (0, 1]: one roughness for both of Chiang's: β_m = β_n = roughness.
- ``absorption``: with ``absorption_kind = "colour"`` (the default) Unreal's perceptual absorption axis
  c ∈ [0, 1]: the linear hair colour is C = c² (Unreal's ``ToLinearAbsorption``) and σ_a follows from C
  through [Chiang eq. 9] with β_n = roughness; with ``"sigma_a"`` the axis is σ_a itself (per unit radius).
- coverage: ``radius_px`` ∈ [0, 0.5] (the strand radius in pixels, Unreal's range) and ``strand_count``
  over [−0.5, 63.5], whose cell centres are the counts 0, 1, …, 63 (Unreal's texel i holds i strands).

**mean_energy** (…, 4) = (R, TT, TRT, residual): the directional albedo of each lobe, averaged uniformly
over the offset h ∈ [−1, 1] (pbrt evaluates the BSDF at one h per ray, so the table holds its average over
the fibre's width, as Unreal's)::

    E_p(θ_o) = ½ ∫_{−1}^{1} ∫_{S²} M_p A_p N_p dω_i dh

Unreal's table holds R, TT and TRT; the residual (all p ≥ 3) is kept so that Σ E_p is the whole albedo
(exactly 1 when σ_a = 0).

**dual_scattering** (…, 6) = (A_f, A_b, alpha_f, alpha_b, beta_f, beta_b): Zinke's average forward and
backward attenuations (eq. 12), the integral of the scattered energy over the front half of azimuth
(|φ_i − φ_o| > π/2, where TT goes) and the back half (|φ_i − φ_o| < π/2, where R and TRT go), h averaged as
above, so A_f + A_b = Σ_p E_p; and the energy-weighted means over the lobes of their longitudinal shift
and variance (Zinke §4: ᾱ_f = Σ_p a_f,p α_p / Σ_p a_f,p, β̄_f² = Σ_p a_f,p β_p² / Σ_p a_f,p, likewise
back).  α_p and β_p are in Zinke's (and Marschner's) convention, for the half angle θ_h = (θ_i + θ_o)/2,
in radians: α_p is the mean of θ_h and β_p² its variance under lobe p's longitudinal distribution
M_p(θ_i) cos θ_i dθ_i (computed by quadrature; for a narrow lobe they tend to the tilt shifts α, −α/2, −2α
and √v_p / 2).  ``beta_f`` and ``beta_b`` are the standard deviations β̄ (their squares the variances).

**coverage** (n_radius, n_count): the expected fraction of a unit pixel covered by N strands of radius r
pixels.  The measure: each strand is an infinite straight band of half-width r whose centre line passes
through a uniformly random point P of the pixel, with a uniformly random orientation θ ∈ [0, π), the
strands independent.  A point x of the pixel is then covered by one strand with probability
q(x) = ∫_pixel K(|P − x|) dP, K(ρ) = 1 (ρ ≤ r) or (2/π) asin(r/ρ) (ρ > r) (the fraction of orientations
whose line passes within r of x), and the expected coverage is 1 − ∫_pixel (1 − q(x))^N dx.  N may be any
real ≥ 0.

**How** (every value comes with an error estimate, |Q_m − Q_{m/2}|, the difference between the rule with
``nodes`` = m Gauss–Legendre nodes per panel and the rule with m/2 on the same panels; the value is Q_m):

- The BSDF factorises: M_p depends on θ_i (and θ_o), N_p on φ_i − φ_o and h, A_p on h.  Each M_p
  integrates to 1 over θ_i and each N_p to 1 over φ (both exactly, [d'Eon], [Chiang §4.2]; the white
  furnace test checks it by 2-D quadrature, :func:`furnace`), so E_p = ½ ∫ A_p dh and a_f,p = ½ ∫ A_p
  (1 − c_p) dh, a_b,p = ½ ∫ A_p c_p dh, with c_p(h) the part of N_p in the back half, a closed form of the
  logistic's distribution function.  The h integrals are taken in γ = asin h (dh = cos γ dγ removes the
  square-root end points).  At low roughness c_p jumps from 0 to 1 over a width s/|dΦ_p/dγ| where
  Φ_p(γ) crosses ±π/2 (mod 2π): those crossings are found by bisection (on the monotone pieces of Φ_p,
  split at the TRT caustic where dΦ_2/dγ = 0) and the panels are graded geometrically about each, so the
  quadrature converges exponentially at every roughness (the widths use the second derivative too, so a
  crossing at a caustic is resolved).
- The moments α_p, β_p are θ_i quadratures of M_p cos θ_i on panels graded about each lobe's centre
  (−θ_o shifted by the tilt) in units of its width √v_p.
- q(x) is an exact radial integral (∫_0^R K(ρ) ρ dρ = R²/2 or (R² asin(r/R) + r √(R² − r²))/π) under a
  quadrature over the direction ω from x, split at the pixel's corners and where the distance to an edge
  equals r; the outer integral runs over a quarter of the pixel (the square's symmetry) split where x is r
  from an edge.

Reproducibility: each *row* (one sin θ_o for the BSDF tables, one radius for coverage) is computed by one
jitted kernel of fixed shapes from the row's own inputs, so a row's numbers are the same bits whichever
rows are computed together (:func:`tables`' ``start``/``stop``).

:func:`montecarlo_unreal` is the baseline: Unreal's estimator (stratified uniform sampling of the sphere
with jitter, 128…64 × 128…32 strata per entry falling with roughness, the sums clamped to [0, 1]) for the
same tables, with a fixed PRNG key.

Measured on the 2-core development machine, shared (load average 5–8), default axes and resolutions:

- mean energy and dual scattering, 64 × 64 × 16, ``nodes`` = 12: 2.9–3.1 s wall (2.2 s CPU) for all 64 rows
  (12- and 6-node rules); against 24 nodes: mean energy R, TT, TRT ≤ 3.6e-10 (residual 1.0e-7), A_f, A_b
  ≤ 2.3e-7, ᾱ, β̄ ≤ 4.6e-8; the stored estimates ≤ 5.6e-5.  ``nodes`` = 8: 3 s less a third, error ≤ 4.3e-6.
- coverage, 64 × 64, ``coverage_nodes`` = 16: ~3 s; against 32 nodes ≤ 6.7e-6 (the corner arcs make its
  convergence algebraic); the stored estimates ≤ 8.5e-5.  All three tables: 7.3 s wall, 4.6 s CPU; the jit
  compiles, once per process, another ~8 s wall.
- the white furnace (:func:`furnace`, 16 nodes): max |1 − E| = 9.7e-15 over 21 sin θ_o × 9 h × 6 × 6
  (β_m, β_n) ∈ [0.05, 1]², the rule's estimates ≤ 8.2e-8.
- the Unreal-style baseline against 24-node quadrature: at Unreal's counts 46.5 s wall (25.7 s CPU), max |error|
  0.94 (mean energy, TT), 0.90 (A_f), 0.83 (A_b), RMS 0.068 (mean energy) and 0.086 (A_f, A_b); at 4× the
  samples (``sample_scale`` = 2) 145 s, max 0.86 / 0.90 / 0.62, RMS 0.051 / 0.060; at 16× (``sample_scale`` = 4,
  16 rows of 64 measured, ~690 s for all) max 0.66 / 0.70 / 0.17, RMS 0.027 / 0.032.  The worst entries sit at
  the smallest roughness (0.0078), in the TT lobe, whose spike uniform sampling misses.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ValidationError
from . import _bsdf as B

TABLES = ("mean_energy", "dual_scattering", "coverage")
MEAN_ENERGY_FIELDS = ("R", "TT", "TRT", "residual")
DUAL_SCATTERING_FIELDS = ("A_f", "A_b", "alpha_f", "alpha_b", "beta_f", "beta_b")
ABSORPTION_KINDS = ("colour", "sigma_a")
#: Unreal's axes (module docstring).
DEFAULT_AXES = {
    "sin_theta_o": (0.0, 1.0),
    "roughness": (0.0, 1.0),
    "absorption": (0.0, 1.0),
    "absorption_kind": "colour",
    "radius_px": (0.0, 0.5),
    "strand_count": (-0.5, 63.5),
}
#: Unreal's resolutions: 64 × 64 × 16 for the BSDF tables, 64 × 64 for coverage.
DEFAULT_RESOLUTION = {"sin_theta_o": 64, "roughness": 64, "absorption": 16, "radius_px": 64, "strand_count": 64}
#: Gauss–Legendre nodes per panel (``nodes``, even: the error estimate uses half of them), the grading levels
#: about each sharp feature (``levels``) and the nodes per panel of the coverage integrals.
DEFAULT_QUADRATURE = {"nodes": 12, "levels": 4, "coverage_nodes": 16}
#: The BSDF's constants (η, the cuticle tilt α in degrees): pbrt-v4's defaults.
DEFAULT_MODEL = {"eta": B.ETA, "alpha": B.ALPHA}
#: Unreal's strata per entry: θ from 128 (smooth) to 64 (rough), φ from 128 to 32 (``HairStrandsLUT.usf``).
UNREAL_THETA = (128, 64)
UNREAL_PHI = (128, 32)
#: Coverage trials per entry of the Monte Carlo baseline (Unreal's coverage sampling is not public; our choice).
UNREAL_COVERAGE_TRIALS = 1024
MAX_NODES = 64
MAX_RESOLUTION = 4096
_BISECTION = 64
_HALF_PI = 0.5 * math.pi
_TWO_PI = 2.0 * math.pi


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


def _psi(p: int, k, g):
    """ψ_p(γ) = Φ_p − pπ = 2p asin(k sin γ) − 2γ (k = 1/η′); odd in γ."""
    return 2.0 * p * jnp.arcsin(k * jnp.sin(g)) - 2.0 * g


def _dpsi(p: int, k, g):
    return 2.0 * p * k * jnp.cos(g) / jnp.sqrt(1.0 - (k * jnp.sin(g)) ** 2) - 2.0


def _d2psi(p: int, k, g):
    return 2.0 * p * k * jnp.sin(g) * (k * k - 1.0) / (1.0 - (k * jnp.sin(g)) ** 2) ** 1.5


def _caustic(p: int, k):
    """The γ ≥ 0 where dψ_p/dγ = 0 (sin²γ = (p²k² − 1)/((p² − 1)k²), when p k > 1), else 0."""
    if p < 2:
        return jnp.zeros_like(k)
    ok = p * k > 1.0
    ks = jnp.where(ok, k, 1.0)
    s2 = jnp.clip((p * p * ks * ks - 1.0) / ((p * p - 1.0) * ks * ks), 0.0, 1.0)
    return jnp.where(ok, jnp.arcsin(jnp.sqrt(s2)), 0.0)


def _crossings(p: int, k):
    """The γ ∈ [−π/2, π/2] where Φ_p crosses ±π/2 (mod 2π), the edges of the back half of azimuth.

    ψ_p stays within [−π, π] for p ≤ 2 (|asin(k sin γ)| ≤ |γ|), so the crossings are those of ψ_p = ±π/2, found by
    bisection on the monotone pieces of [0, π/2] and mirrored (ψ_p is odd).  On [0, π/2], ψ_0 and ψ_1 fall from 0
    (only −π/2 can be crossed); ψ_2 rises to the caustic γ_c, where it is ≥ 0 (only +π/2), then falls (either).
    Returns (γ (S,), valid (S,)): S = 2 for p ≤ 1, 6 for p = 2."""
    gc = _caustic(p, k)
    zero, top = 0.0 * k, 0.0 * k + _HALF_PI
    slots = [(zero, top, -_HALF_PI)] if p < 2 else [(zero, gc, _HALF_PI), (gc, top, _HALF_PI), (gc, top, -_HALF_PI)]
    a = jnp.stack([lo for lo, _, _ in slots])
    b = jnp.stack([hi for _, hi, _ in slots])
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
    return jnp.concatenate([root, -root]), jnp.concatenate([valid, valid])


def back_fraction(phi, s):
    """c = ∫_{|φ′| < π/2} N(φ′) dφ′ for the trimmed logistic N of scale s centred on ``phi``: the share of a
    lobe scattered into the back half of azimuth (a closed form of the logistic distribution function)."""
    d = jnp.abs(B.wrap_angle(phi))
    lc = functools.partial(B.logistic_cdf, s=s)
    num = lc(_HALF_PI - d) - lc(jnp.maximum(-math.pi, -_HALF_PI - d)) + lc(math.pi) - lc(jnp.minimum(math.pi, 1.5 * math.pi - d))
    return jnp.clip(num / jnp.tanh(0.5 * math.pi / s), 0.0, 1.0)


# ----------------------------------------------------------------------------- the BSDF tables, one row


def _h_nodes(p: int, k, s, m: int, levels: int):
    """γ nodes and the h-measure weights ½ cos γ dγ for lobe p (R, N), graded about the crossings."""
    gam, valid = _crossings(p, k)
    slope = jnp.abs(_dpsi(p, k, gam))
    curve = jnp.abs(_d2psi(p, k, gam))
    s_ = s[:, None]
    width = s_ / jnp.maximum(jnp.maximum(slope, jnp.sqrt(0.5 * s_ * curve)), 1e-300)
    width = jnp.minimum(width, math.pi / 8.0)
    offsets = jnp.asarray(_graded(levels, 4.0))
    pts = jnp.where(valid[None, :, None], gam[None, :, None] + width[..., None] * offsets, -_HALF_PI)
    gc = _caustic(p, k)
    fixed = jnp.stack([-_HALF_PI + 0.0 * k, 0.0 * k, _HALF_PI + 0.0 * k, gc, -gc])
    pts = jnp.concatenate([pts.reshape(s.shape[0], -1), jnp.broadcast_to(fixed, (s.shape[0], 5))], axis=1)
    breaks = jnp.sort(jnp.clip(pts, -_HALF_PI, _HALF_PI), axis=-1)
    g, w = _panels(breaks, m)
    return g, 0.5 * w * jnp.cos(g)


def _theta_moments(sin_o, cos_o, rough, alpha, m: int, levels: int):
    """(α_p, β_p²) (R, 4): mean and variance of θ_h = (θ_i + θ_o)/2 under M_p(θ_i) cos θ_i dθ_i."""
    v = B.longitudinal_variance(rough)  # (R, 4)
    sin_p, cos_p = B.tilt(sin_o, cos_o, alpha)  # (4,)
    centre = -jnp.arctan2(sin_p, cos_p)
    offsets = jnp.asarray(_graded(levels, 2.0))
    pts = centre[None, :, None] + jnp.sqrt(v)[..., None] * offsets
    ends = jnp.broadcast_to(jnp.asarray([-_HALF_PI, _HALF_PI]), (*v.shape, 2))
    breaks = jnp.sort(jnp.clip(jnp.concatenate([pts, ends], axis=-1), -_HALF_PI, _HALF_PI), axis=-1)
    th, w = _panels(breaks, m)  # (R, 4, N)
    mp = B.longitudinal(jnp.sin(th), jnp.cos(th), sin_p[:, None], cos_p[:, None], v[..., None])
    wt = w * mp * jnp.cos(th)
    z = jnp.sum(wt, axis=-1)
    mean = jnp.sum(wt * th, axis=-1) / z
    var = jnp.sum(wt * (th - mean[..., None]) ** 2, axis=-1) / z
    theta_o = jnp.arctan2(sin_o, cos_o)
    return 0.5 * (mean + theta_o), 0.25 * var


def _bsdf_row(sin_o, rough, sigma, eta, alpha, m: int, levels: int):
    """One sin θ_o: mean energy (R, K, 4) and dual scattering (R, K, 6) for roughness (R,) and σ_a (R, K)."""
    cos_o = B._sqrt1m(sin_o)
    k = B.bravais_inverse(sin_o, cos_o, eta)
    cos_t = B._sqrt1m(sin_o / eta)
    s = B.azimuthal_scale(rough)
    front, back = [], []
    residual = None
    for p in range(B.P_MAX):
        g, w = _h_nodes(p, k, s, m, levels)  # (R, N)
        sin_gt = k * jnp.sin(g)
        f = B.fresnel(cos_o * jnp.cos(g), eta)[:, None, :]
        c = back_fraction(B.phi_centre(p, g, jnp.arcsin(sin_gt)), s[:, None])[:, None, :]
        if p == 0:
            wa = w[:, None, :] * f  # A_0 = f, whatever σ_a
        t = jnp.exp(-sigma[:, :, None] * (2.0 * B._sqrt1m(sin_gt) / cos_t)[:, None, :])  # (R, K, N)
        if p == 0:  # the residual lobe (uniform in azimuth: half in each half) on the same nodes
            residual = jnp.sum(w[:, None, :] * B.attenuation(f, t)[..., B.P_MAX], axis=-1)
        elif p == 1:
            wa = w[:, None, :] * (1.0 - f) ** 2 * t
        else:
            wa = w[:, None, :] * (1.0 - f) ** 2 * t * t * f
        wb = jnp.sum(wa * c, axis=-1)
        back.append(jnp.broadcast_to(wb, sigma.shape))
        front.append(jnp.broadcast_to(jnp.sum(wa, axis=-1) - wb, sigma.shape))
    front.append(0.5 * residual)
    back.append(0.5 * residual)
    fr, bk = jnp.stack(front, axis=-1), jnp.stack(back, axis=-1)  # (R, K, 4)
    mean_a, var_b = _theta_moments(sin_o, cos_o, rough, alpha, m, levels)  # (R, 4)
    a_f, a_b = jnp.sum(fr, axis=-1), jnp.sum(bk, axis=-1)

    def weighted(wt, total, x):
        ok = total > 0.0
        return jnp.where(ok, jnp.sum(wt * x[:, None, :], axis=-1) / jnp.where(ok, total, 1.0), 0.0)

    dual = jnp.stack(
        [
            a_f,
            a_b,
            weighted(fr, a_f, mean_a),
            weighted(bk, a_b, mean_a),
            jnp.sqrt(weighted(fr, a_f, var_b)),
            jnp.sqrt(weighted(bk, a_b, var_b)),
        ],
        axis=-1,
    )
    return fr + bk, dual


@functools.partial(jax.jit, static_argnames=("m", "levels"))
def bsdf_row_kernel(sin_o, rough, sigma, eta, alpha, *, m, levels):
    """The BSDF tables' row kernel (float64): sin_o (), rough (R,), sigma (R, K), η, α (radians) →
    (mean energy (R, K, 4), dual scattering (R, K, 6))."""
    return _bsdf_row(sin_o, rough, sigma, eta, alpha, m, levels)


@functools.partial(jax.jit, static_argnames=("m", "levels"))
def bsdf_point_kernel(sin_o, rough, sigma, eta, alpha, *, m, levels):
    """The same at P scattered points: sin_o, rough, sigma (P,) → ((P, 4), (P, 6))."""

    def one(so, r, sg):
        e, d = _bsdf_row(so, r[None], sg[None, None], eta, alpha, m, levels)
        return e[0, 0], d[0, 0]

    return jax.lax.map(lambda x: one(*x), (sin_o, rough, sigma))


# ----------------------------------------------------------------------------- coverage, one row


def _coverage_q(x1, x2, r, m: int):
    """q(x) (n,) at points (x1, x2) of the centred pixel [−½, ½]²: ∫_0^{2π} H(R(x, ω)) dω."""
    d = jnp.stack([0.5 - x1, 0.5 - x2, 0.5 + x1, 0.5 + x2], axis=-1)  # distance to the right, top, left, bottom edge
    side = jnp.asarray([0.0, _HALF_PI, math.pi, 1.5 * math.pi])
    corners = jnp.stack(
        [jnp.arctan2(sy - x2, sx - x1) for sx, sy in ((0.5, 0.5), (-0.5, 0.5), (-0.5, -0.5), (0.5, -0.5))], axis=-1
    )
    rs = jnp.maximum(r, 1e-300)
    half_angle = jnp.arccos(jnp.minimum(d / rs, 1.0))
    kinks = jnp.concatenate([side + half_angle, side - half_angle], axis=-1)
    kinks = jnp.where(jnp.concatenate([d < r, d < r], axis=-1), kinks, jnp.tile(corners, 2))
    pts = jnp.mod(jnp.concatenate([corners, kinks], axis=-1), _TWO_PI)
    n = x1.shape[0]
    breaks = jnp.sort(jnp.concatenate([jnp.zeros((n, 1)), pts, jnp.full((n, 1), _TWO_PI)], axis=-1), axis=-1)
    om, w = _panels(breaks, m)  # (n, N)
    c = jnp.cos(om[..., None] - side)  # (n, N, 4)
    dist = jnp.where(c > 0.0, d[:, None, :] / jnp.where(c > 0.0, c, 1.0), jnp.inf)
    big_r = jnp.min(dist, axis=-1)
    rr = jnp.maximum(big_r, rs)
    outer = (
        big_r * big_r * jnp.arcsin(jnp.minimum(r / rr, 1.0)) + r * jnp.sqrt(jnp.maximum(big_r * big_r - r * r, 0.0))
    ) / math.pi
    h = jnp.where(big_r <= r, 0.5 * big_r * big_r, outer)
    return jnp.sum(w * h, axis=-1)


def _coverage_row(r, counts, m: int):
    edges = jnp.sort(jnp.clip(jnp.stack([0.0 * r, 0.5 - r, r - 0.5, 0.5 + 0.0 * r]), 0.0, 0.5))
    x, w = _panels(edges, m)
    x1, x2 = jnp.meshgrid(x, x, indexing="ij")
    wx = (w[:, None] * w[None, :]).reshape(-1)
    q = _coverage_q(x1.reshape(-1), x2.reshape(-1), r, m)
    miss = jnp.power(jnp.clip(1.0 - q, 0.0, 1.0)[None, :], counts[:, None])
    return 1.0 - 4.0 * jnp.sum(wx * miss, axis=-1)


@functools.partial(jax.jit, static_argnames=("m",))
def coverage_row_kernel(r, counts, *, m):
    """Coverage (float64) for one radius r () and strand counts (C,) → (C,)."""
    return _coverage_row(r, counts, m)


# ----------------------------------------------------------------------------- the white furnace


def _furnace_one(sin_o, h, beta_m, beta_n, sigma_a, eta, alpha, m: int):
    """∫_{S²} Σ_p M_p A_p N_p dω_i at one (θ_o, h) by a tensor Gauss–Legendre rule in (θ_i, φ_i − φ_o)."""
    cos_o = B._sqrt1m(sin_o)
    v = B.longitudinal_variance(beta_m)
    s = B.azimuthal_scale(beta_n)
    sin_p, cos_p = B.tilt(sin_o, cos_o, alpha)
    centre = -jnp.arctan2(sin_p, cos_p)
    tpts = (centre[:, None] + jnp.sqrt(v)[:, None] * jnp.asarray(_graded(4, 2.0))).reshape(-1)
    tb = jnp.sort(jnp.clip(jnp.concatenate([tpts, jnp.asarray([-_HALF_PI, _HALF_PI])]), -_HALF_PI, _HALF_PI))
    th, wt = _panels(tb, m)
    gamma_o, _, gamma_t, _, _ = B._fibre(sin_o, cos_o, h, eta)
    phis = jnp.stack([B.phi_centre(p, gamma_o, gamma_t) for p in range(B.P_MAX)])
    ppts = jnp.concatenate([(phis[:, None] + s * jnp.asarray(_graded(5, 4.0))).reshape(-1), phis + math.pi])
    pb = jnp.sort(jnp.concatenate([B.wrap_angle(ppts), jnp.asarray([-math.pi, math.pi])]))
    ph, wp = _panels(pb, m)
    g = B.lobes_angles(
        sin_o, cos_o, 0.0, jnp.sin(th)[:, None], jnp.cos(th)[:, None], ph[None, :], h, sigma_a[None], beta_m, beta_n, alpha, eta
    )  # (Nθ, Nφ, 1, 4)
    return jnp.sum(jnp.sum(g[..., 0, :].sum(-1) * wp[None, :], axis=-1) * wt * jnp.cos(th))


@functools.partial(jax.jit, static_argnames=("m",))
def furnace_kernel(sin_o, h, beta_m, beta_n, sigma_a, eta, alpha, *, m):
    """:func:`_furnace_one` over P configurations (all (P,)) → (P,)."""
    return jax.lax.map(lambda x: _furnace_one(*x, eta, alpha, m), (sin_o, h, beta_m, beta_n, sigma_a))


# ----------------------------------------------------------------------------- the Monte Carlo baseline


def _mc_row(sin_o, rough, sigma, n_theta, n_phi, jitter, hs, eta, alpha, block: int):
    """Unreal's estimator for one sin θ_o: per roughness, n_θ × n_φ jittered strata of the sphere (row-major in
    the strata, jitter and h from shared tables indexed by stratum), summed in blocks."""
    cos_o = B._sqrt1m(sin_o)
    theta_o = jnp.arctan2(sin_o, cos_o)
    sin_p, cos_p = B.tilt(sin_o, cos_o, alpha)
    k_count = sigma.shape[-1]

    def per_rough(args):
        r, sg, nt, npf = args
        total = nt * npf
        nblocks = (total + block - 1) // block
        sa = sg[None, :]
        v, s = B.longitudinal_variance(r), B.azimuthal_scale(r)

        def body(b, acc):
            j = b * block + jnp.arange(block)
            ok = j < total
            jj = jnp.where(ok, j, 0)
            ia, ib = jj % nt, jj // nt
            idx = ia * _MC_PHI_STRIDE + ib
            jt = jitter[idx]
            sin_i = 1.0 - 2.0 * (ia + jt[:, 0]) / nt
            cos_i = B._sqrt1m(sin_i)
            phi_i = _TWO_PI * (ib + jt[:, 1]) / npf
            h = hs[idx]
            gamma_o, cos_go, gamma_t, cos_gt, cos_t = B._fibre(sin_o, cos_o, h, eta)
            m_, n_ = B._mn(sin_i, cos_i, phi_i, sin_p, cos_p, v, s, gamma_o, gamma_t)
            t = jnp.exp(-sa * (2.0 * cos_gt / cos_t)[:, None])  # (block, K)
            a = B.attenuation(B.fresnel(cos_o * cos_go, eta)[:, None], t)  # (block, K, 4)
            mn = jnp.where(ok[:, None], m_ * n_, 0.0)  # (block, 4)
            g = mn[:, None, :] * a * (4.0 * math.pi)  # f / pdf, pdf = 1/(4π)
            is_back = jnp.cos(phi_i) > 0.0
            okb, okf = ok & is_back, ok & ~is_back
            theta_h = 0.5 * (jnp.arcsin(sin_i) + theta_o)
            s_all, s_f, s_b, c_f, c_b, m0, m1, m2 = acc
            return (
                s_all + jnp.sum(g, axis=0),
                s_f + jnp.sum(jnp.where(okf[:, None, None], g, 0.0), axis=0),
                s_b + jnp.sum(jnp.where(okb[:, None, None], g, 0.0), axis=0),
                c_f + jnp.sum(okf),
                c_b + jnp.sum(okb),
                m0 + jnp.sum(mn, axis=0),
                m1 + jnp.sum(mn * theta_h[:, None], axis=0),
                m2 + jnp.sum(mn * theta_h[:, None] ** 2, axis=0),
            )

        z = jnp.zeros((k_count, 4))
        z4 = jnp.zeros(4)
        zero = jnp.zeros((), total.dtype)
        s_all, s_f, s_b, c_f, c_b, m0, m1, m2 = jax.lax.fori_loop(0, nblocks, body, (z, z, z, zero, zero, z4, z4, z4))
        energy = jnp.clip(s_all / total, 0.0, 1.0)
        fr = 0.5 * s_f / jnp.maximum(c_f, 1)
        bk = 0.5 * s_b / jnp.maximum(c_b, 1)
        mean_a = m1 / jnp.where(m0 > 0, m0, 1.0)
        var_b = jnp.maximum(m2 / jnp.where(m0 > 0, m0, 1.0) - mean_a**2, 0.0)
        a_f, a_b = jnp.sum(fr, axis=-1), jnp.sum(bk, axis=-1)

        def weighted(wt, tot, x):
            ok = tot > 0.0
            return jnp.where(ok, jnp.sum(wt * x[None, :], axis=-1) / jnp.where(ok, tot, 1.0), 0.0)

        dual = jnp.stack(
            [
                jnp.clip(a_f, 0.0, 1.0),
                jnp.clip(a_b, 0.0, 1.0),
                weighted(fr, a_f, mean_a),
                weighted(bk, a_b, mean_a),
                jnp.sqrt(weighted(fr, a_f, var_b)),
                jnp.sqrt(weighted(bk, a_b, var_b)),
            ],
            axis=-1,
        )
        return energy, dual

    return jax.lax.map(per_rough, (rough, sigma, n_theta, n_phi))


#: Stride of the φ stratum in the shared jitter tables (the largest φ count the tables allow).
_MC_PHI_STRIDE = 128 * 16


@functools.partial(jax.jit, static_argnames=("block",))
def montecarlo_row_kernel(sin_o, rough, sigma, n_theta, n_phi, jitter, hs, eta, alpha, *, block):
    """Unreal's uniform Monte Carlo for one sin θ_o row → (mean energy (R, K, 4), dual scattering (R, K, 6))."""
    return _mc_row(sin_o, rough, sigma, n_theta, n_phi, jitter, hs, eta, alpha, block)


@functools.partial(jax.jit, static_argnames=("trials", "strands"))
def montecarlo_coverage_kernel(key, r, counts, *, trials, strands):
    """Random strands (a uniform point of the pixel and a uniform orientation each) over one random point of the
    pixel per trial: the covered share for the first N strands, N = counts (C,) (rounded), over ``trials``."""
    k1, k2, k3 = jax.random.split(key, 3)
    pts = jax.random.uniform(k1, (trials, strands, 2), jnp.float64)
    ang = jax.random.uniform(k2, (trials, strands), jnp.float64) * math.pi
    x = jax.random.uniform(k3, (trials, 1, 2), jnp.float64)
    dist = jnp.abs((x[..., 0] - pts[..., 0]) * jnp.sin(ang) - (x[..., 1] - pts[..., 1]) * jnp.cos(ang))
    hit = jnp.cumsum(dist <= r, axis=-1) > 0  # (trials, strands): covered by the first j+1 strands
    hit = jnp.concatenate([jnp.zeros((trials, 1), bool), hit], axis=-1)
    n = jnp.clip(jnp.round(counts).astype(jnp.int32), 0, strands)
    return jnp.mean(hit[:, n].astype(jnp.float64), axis=0)


# ----------------------------------------------------------------------------- axes and validation


def _range(value, field: str, lo=None, hi=None) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ValidationError(field, value, "need a range (lo, hi) of two numbers") from None
    if not (math.isfinite(a) and math.isfinite(b)) or not a < b:
        raise ValidationError(field, value, "need finite lo < hi")
    if (lo is not None and a < lo) or (hi is not None and b > hi):
        raise ValidationError(field, value, f"must lie within [{lo:g}, {hi:g}]" if hi is not None else f"must be ≥ {lo:g}")
    return a, b


def check_axes(axes: dict | None) -> dict:
    """:data:`DEFAULT_AXES` updated by ``axes``, each range checked (ValidationError naming ``axes.KEY``)."""
    axes = dict(axes or {})
    unknown = sorted(set(axes) - set(DEFAULT_AXES))
    if unknown:
        raise ValidationError(f"axes.{unknown[0]}", axes[unknown[0]], f"unknown axis; known: {', '.join(DEFAULT_AXES)}")
    out = {**DEFAULT_AXES, **axes}
    kind = out["absorption_kind"]
    if kind not in ABSORPTION_KINDS:
        raise ValidationError("axes.absorption_kind", kind, f"must be one of {', '.join(ABSORPTION_KINDS)}")
    out["sin_theta_o"] = _range(out["sin_theta_o"], "axes.sin_theta_o", -1.0, 1.0)
    out["roughness"] = _range(out["roughness"], "axes.roughness", 0.0, 1.0)
    out["absorption"] = _range(out["absorption"], "axes.absorption", 0.0, 1.0 if kind == "colour" else None)
    out["radius_px"] = _range(out["radius_px"], "axes.radius_px", 0.0, None)
    out["strand_count"] = _range(out["strand_count"], "axes.strand_count", -1.0, None)
    return out


def check_resolution(resolution: dict | None) -> dict:
    """:data:`DEFAULT_RESOLUTION` updated by ``resolution`` (integers in [1, MAX_RESOLUTION])."""
    resolution = dict(resolution or {})
    unknown = sorted(set(resolution) - set(DEFAULT_RESOLUTION))
    if unknown:
        raise ValidationError(f"resolution.{unknown[0]}", resolution[unknown[0]], "unknown axis")
    out = {**DEFAULT_RESOLUTION, **resolution}
    for name, n in out.items():
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_RESOLUTION:
            raise ValidationError(f"resolution.{name}", n, f"must be an integer in [1, {MAX_RESOLUTION}]")
        out[name] = int(n)
    return out


def check_quadrature(quadrature: dict | None) -> dict:
    """:data:`DEFAULT_QUADRATURE` updated by ``quadrature``: ``nodes`` and ``coverage_nodes`` even integers in
    [2, MAX_NODES], ``levels`` an integer in [1, 8]."""
    quadrature = dict(quadrature or {})
    unknown = sorted(set(quadrature) - set(DEFAULT_QUADRATURE))
    if unknown:
        raise ValidationError(f"quadrature.{unknown[0]}", quadrature[unknown[0]], "unknown key")
    out = {**DEFAULT_QUADRATURE, **quadrature}
    for name in ("nodes", "coverage_nodes"):
        n = out[name]
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 2 <= n <= MAX_NODES or n % 2:
            raise ValidationError(f"quadrature.{name}", n, f"must be an even integer in [2, {MAX_NODES}]")
    n = out["levels"]
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 8:
        raise ValidationError("quadrature.levels", n, "must be an integer in [1, 8]")
    return {k: int(v) for k, v in out.items()}


def check_model_dict(model: dict | None) -> tuple[float, float]:
    """(η, α in radians) from ``model`` ({"eta", "alpha" (degrees)}, defaults :data:`DEFAULT_MODEL`)."""
    model = dict(model or {})
    unknown = sorted(set(model) - set(DEFAULT_MODEL))
    if unknown:
        raise ValidationError(f"model.{unknown[0]}", model[unknown[0]], "unknown key; known: eta, alpha")
    out = {**DEFAULT_MODEL, **model}
    try:
        alpha, eta = B.check_model(out["alpha"], out["eta"])
    except ValidationError as exc:
        raise ValidationError(f"model.{exc.field}", exc.value, exc.reason) from None
    return eta, alpha


def axis_nodes(axes: dict | None = None, resolution: dict | None = None) -> dict[str, np.ndarray]:
    """The cell-centre nodes of every axis (float64): lo + (i + ½)(hi − lo)/n."""
    axes, resolution = check_axes(axes), check_resolution(resolution)
    out = {}
    for name, n in resolution.items():
        lo, hi = axes[name]
        out[name] = lo + (np.arange(n, dtype=np.float64) + 0.5) * ((hi - lo) / n)
    return out


def absorption_sigma(absorption, roughness, kind: str) -> np.ndarray:
    """σ_a (R, K) for the absorption nodes (K,) at each roughness (R,): the colour axis maps c → C = c² →
    [Chiang eq. 9] with β_n = roughness; the σ_a axis is used as is."""
    a = np.asarray(absorption, np.float64)[None, :]
    r = np.asarray(roughness, np.float64)[:, None]
    if kind == "sigma_a":
        return np.broadcast_to(a, (r.shape[0], a.shape[1])).copy()
    return B.colour_to_sigma_a(a * a, r)


def peak_bytes(resolution=None, quadrature=None, *, block: int = 4096) -> dict[str, int]:
    """An upper estimate of the working memory (bytes) of one row kernel, before anything is allocated:
    ``bsdf_row`` (both BSDF tables), ``coverage_row`` and ``montecarlo_row`` (``block`` samples at a time).
    Each counts its largest float64 temporaries live at once (a factor 8 over one (R, K, N) array: XLA fuses
    most of them); the tables themselves (rows × … × 8 bytes, twice with the errors) are the caller's."""
    res, q = check_resolution(resolution), check_quadrature(quadrature)
    r, k, m, lv = res["roughness"], res["absorption"], q["nodes"], q["levels"]
    n_h = (6 * (2 * lv + 1) + 4) * m  # the TRT node set, the largest
    n_th = 4 * (2 * lv + 2) * m
    bsdf = 8 * 8 * (r * k * n_h + r * n_th)
    mc = q["coverage_nodes"]
    n_x, n_om = (3 * mc) ** 2, 13 * mc
    cov = 8 * (4 * n_x * n_om * 4 + res["strand_count"] * n_x)
    return {"bsdf_row": int(bsdf), "coverage_row": int(cov), "montecarlo_row": int(8 * 8 * block * k * 4)}


def _rows(start, stop, total: int, field: str) -> tuple[int, int]:
    start = 0 if start is None else start
    stop = total if stop is None else stop
    for name, v in (("start", start), ("stop", stop)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise ValidationError(f"{field}.{name}", v, "must be an integer")
    if not 0 <= start <= stop <= total:
        raise ValidationError(field, (start, stop), f"need 0 ≤ start ≤ stop ≤ {total}")
    return int(start), int(stop)


# ----------------------------------------------------------------------------- public functions


def _f64(a):
    if isinstance(a, float) or (isinstance(a, np.ndarray) and np.issubdtype(a.dtype, np.floating)):
        return jnp.asarray(a, jnp.float64)
    return jnp.asarray(a) if isinstance(a, np.ndarray) else a


def _x64(fn, *args, **kwargs):
    with jax.enable_x64(True):
        out = fn(*(_f64(a) for a in args), **kwargs)
        return jax.tree_util.tree_map(np.asarray, out)


def _bsdf_points(sin_theta_o, roughness, absorption, absorption_kind, model, quadrature):
    if absorption_kind not in ABSORPTION_KINDS:
        raise ValidationError("absorption_kind", absorption_kind, f"must be one of {', '.join(ABSORPTION_KINDS)}")
    so = B.check_values(sin_theta_o, "sin_theta_o", -1.0, 1.0)
    r = B.check_roughness(roughness)
    ab = B.check_colour(absorption, "absorption") if absorption_kind == "colour" else B.check_sigma_a(absorption, "absorption")
    so, r, ab = np.broadcast_arrays(so, r, ab)
    sigma = B.colour_to_sigma_a(ab * ab, r) if absorption_kind == "colour" else ab
    eta, alpha = check_model_dict(model)
    q = check_quadrature(quadrature)
    flat = [np.ascontiguousarray(x.reshape(-1)) for x in (so, r, sigma)]
    hi = _x64(bsdf_point_kernel, *flat, eta, alpha, m=q["nodes"], levels=q["levels"])
    lo = _x64(bsdf_point_kernel, *flat, eta, alpha, m=q["nodes"] // 2, levels=q["levels"])
    shape = so.shape
    return [(a.reshape(*shape, -1), np.abs(a - b).reshape(*shape, -1)) for a, b in zip(hi, lo)]


def mean_energy(sin_theta_o, roughness, absorption, *, absorption_kind="colour", model=None, quadrature=None):
    """(values (..., 4), errors (..., 4)): the mean energies (R, TT, TRT, residual) at broadcast points.

    ``absorption`` is a perceptual colour c ∈ (0, 1] (C = c², σ_a by [Chiang eq. 9] with β_n = roughness) or,
    with ``absorption_kind="sigma_a"``, σ_a ≥ 0; ``model`` = {"eta", "alpha"}; ``quadrature`` as in
    :func:`tables`.  See the module docstring for the definitions."""
    return _bsdf_points(sin_theta_o, roughness, absorption, absorption_kind, model, quadrature)[0]


def dual_scattering(sin_theta_o, roughness, absorption, *, absorption_kind="colour", model=None, quadrature=None):
    """(values (..., 6), errors (..., 6)): A_f, A_b, ᾱ_f, ᾱ_b, β̄_f, β̄_b (:data:`DUAL_SCATTERING_FIELDS`) at
    broadcast points (arguments as :func:`mean_energy`)."""
    return _bsdf_points(sin_theta_o, roughness, absorption, absorption_kind, model, quadrature)[1]


def coverage(strand_count, radius_px, *, quadrature=None):
    """(values, errors) of the expected covered fraction of a pixel (module docstring's measure) for broadcast
    strand counts N ≥ 0 and radii r ≥ 0 (pixels)."""
    n = B.check_values(strand_count, "strand_count", 0.0)
    r = B.check_values(radius_px, "radius_px", 0.0)
    q = check_quadrature(quadrature)
    n, r = np.broadcast_arrays(n, r)
    vals, errs = np.zeros(n.shape), np.zeros(n.shape)
    for rv in np.unique(r):
        sel = r == rv
        hi = _x64(coverage_row_kernel, np.float64(rv), np.ascontiguousarray(n[sel]), m=q["coverage_nodes"])
        lo = _x64(coverage_row_kernel, np.float64(rv), np.ascontiguousarray(n[sel]), m=q["coverage_nodes"] // 2)
        vals[sel], errs[sel] = hi, np.abs(hi - lo)
    return vals, errs


def furnace(sin_theta_o, h, beta_m, beta_n, sigma_a=0.0, *, model=None, nodes=8):
    """(values, errors): ∫_{S²} Σ_p M_p A_p N_p dω_i at broadcast (sin θ_o, h, β_m, β_n, σ_a), by a tensor
    Gauss–Legendre rule in (θ_i, φ_i) graded about every lobe (not using the factorisation); exactly
    Σ_p A_p(θ_o, h), which is 1 when σ_a = 0 (the white furnace)."""
    so = B.check_values(sin_theta_o, "sin_theta_o", -1.0, 1.0)
    hh = B.check_values(h, "h", -1.0, 1.0)
    bm, bn = B.check_roughness(beta_m, "beta_m"), B.check_roughness(beta_n, "beta_n")
    sa = B.check_sigma_a(sigma_a)
    eta, alpha = check_model_dict(model)
    q = check_quadrature({"nodes": nodes})
    arrs = np.broadcast_arrays(so, hh, bm, bn, sa)
    flat = [np.ascontiguousarray(x.reshape(-1)) for x in arrs]
    hi = _x64(furnace_kernel, *flat, eta, alpha, m=q["nodes"])
    lo = _x64(furnace_kernel, *flat, eta, alpha, m=q["nodes"] // 2)
    return hi.reshape(arrs[0].shape), np.abs(hi - lo).reshape(arrs[0].shape)


def tables(axes=None, resolution=None, *, quadrature=None, model=None, which=TABLES, start=None, stop=None):
    """Compute the tables ``which`` (a subset of :data:`TABLES`) for rows [start, stop) of their first axis.

    Returns {name: (values, errors)}, float64: ``mean_energy`` (S, n_roughness, n_absorption, 4) and
    ``dual_scattering`` (S, n_roughness, n_absorption, 6), S rows of ``sin_theta_o``; ``coverage``
    (S, n_strand_count), S rows of ``radius_px``.  ``start``/``stop`` index the first axis of each table
    asked for (so ask for the BSDF tables and coverage separately when their row counts differ); a row's
    numbers do not depend on the range.  ``axes``, ``resolution``, ``quadrature`` and ``model`` update
    :data:`DEFAULT_AXES`, :data:`DEFAULT_RESOLUTION`, :data:`DEFAULT_QUADRATURE` and :data:`DEFAULT_MODEL`
    (ValidationError naming the key otherwise)."""
    which = (which,) if isinstance(which, str) else tuple(which)
    bad = [w for w in which if w not in TABLES]
    if bad:
        raise ValidationError("which", bad[0], f"must be among {', '.join(TABLES)}")
    ax = check_axes(axes)
    nodes = axis_nodes(ax, resolution)
    q = check_quadrature(quadrature)
    eta, alpha = check_model_dict(model)
    out = {}
    if "mean_energy" in which or "dual_scattering" in which:
        i0, i1 = _rows(start, stop, nodes["sin_theta_o"].size, "rows")
        sigma = absorption_sigma(nodes["absorption"], nodes["roughness"], ax["absorption_kind"])
        res = [[], [], [], []]
        for i in range(i0, i1):
            so = np.float64(nodes["sin_theta_o"][i])
            e1, d1 = _x64(bsdf_row_kernel, so, nodes["roughness"], sigma, eta, alpha, m=q["nodes"], levels=q["levels"])
            e0, d0 = _x64(bsdf_row_kernel, so, nodes["roughness"], sigma, eta, alpha, m=q["nodes"] // 2, levels=q["levels"])
            for lst, x in zip(res, (e1, np.abs(e1 - e0), d1, np.abs(d1 - d0))):
                lst.append(x)
        shape_e = (0, nodes["roughness"].size, nodes["absorption"].size)
        stacked = [np.stack(x) if x else np.zeros((*shape_e, n)) for x, n in zip(res, (4, 4, 6, 6))]
        if "mean_energy" in which:
            out["mean_energy"] = (stacked[0], stacked[1])
        if "dual_scattering" in which:
            out["dual_scattering"] = (stacked[2], stacked[3])
    if "coverage" in which:
        i0, i1 = _rows(start, stop, nodes["radius_px"].size, "rows")
        counts = nodes["strand_count"]
        vals, errs = [], []
        for i in range(i0, i1):
            r = np.float64(nodes["radius_px"][i])
            hi = _x64(coverage_row_kernel, r, counts, m=q["coverage_nodes"])
            lo = _x64(coverage_row_kernel, r, counts, m=q["coverage_nodes"] // 2)
            vals.append(hi)
            errs.append(np.abs(hi - lo))
        empty = np.zeros((0, counts.size))
        out["coverage"] = (np.stack(vals) if vals else empty, np.stack(errs) if errs else empty)
    return out


def unreal_counts(roughness, sample_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Unreal's strata per entry (n_θ, n_φ), each ``max(1, round(sample_scale · lerp(hi, lo, roughness)))``.

    ``sample_scale`` multiplies each axis (Unreal's ``SampleCountScale``), so the sample count grows as its
    square: 2 gives 4× the samples, 4 gives 16×."""
    r = np.asarray(roughness, np.float64)
    nt = np.maximum(1, np.rint(sample_scale * (UNREAL_THETA[0] + (UNREAL_THETA[1] - UNREAL_THETA[0]) * r))).astype(np.int64)
    npf = np.maximum(1, np.rint(sample_scale * (UNREAL_PHI[0] + (UNREAL_PHI[1] - UNREAL_PHI[0]) * r))).astype(np.int64)
    return nt, npf


def montecarlo_unreal(
    axes=None,
    resolution=None,
    *,
    sample_scale: float = 1.0,
    coverage_trials: int = UNREAL_COVERAGE_TRIALS,
    seed: int = 0,
    model=None,
    which=TABLES,
    start=None,
    stop=None,
    block: int = 4096,
) -> dict[str, np.ndarray]:
    """The Unreal-style baseline for the same tables (values only, no error), deterministic for a ``seed``.

    BSDF tables: for each entry, n_θ × n_φ strata of the sphere (:func:`unreal_counts`), one direction per
    stratum jittered (sin θ_i = 1 − 2u, φ_i = 2πu′, pdf 1/(4π)) and one offset h uniform in [−1, 1]; the jitter
    and h of stratum (a, b) are shared by every entry (Unreal shares its R2 jitter likewise).  mean energy =
    the mean of f·cos/pdf per lobe; A_f, A_b = ½ × the mean over the front (back) samples, as Unreal's
    ``HemisphereFactor``; all clamped to [0, 1] (Unreal's ``saturate``).  ᾱ, β̄ combine the per-lobe front/back
    energies with the lobes' sample moments of θ_h (Unreal does not tabulate them).  Coverage: per entry
    ``coverage_trials`` trials of one uniform point of the pixel and N random strands (measure of the module
    docstring).  Returns {name: values} shaped as :func:`tables`."""
    which = (which,) if isinstance(which, str) else tuple(which)
    bad = [w for w in which if w not in TABLES]
    if bad:
        raise ValidationError("which", bad[0], f"must be among {', '.join(TABLES)}")
    scale = B.check_values(sample_scale, "sample_scale", 0.0, 16.0, lo_open=True)
    for name, v in (("coverage_trials", coverage_trials), ("seed", seed), ("block", block)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < (0 if name == "seed" else 1):
            raise ValidationError(name, v, "must be a non-negative integer" if name == "seed" else "must be a positive integer")
    ax = check_axes(axes)
    nodes = axis_nodes(ax, resolution)
    eta, alpha = check_model_dict(model)
    key = jax.random.PRNGKey(int(seed))
    out = {}
    if "mean_energy" in which or "dual_scattering" in which:
        i0, i1 = _rows(start, stop, nodes["sin_theta_o"].size, "rows")
        sigma = absorption_sigma(nodes["absorption"], nodes["roughness"], ax["absorption_kind"])
        nt, npf = unreal_counts(nodes["roughness"], float(scale))
        if int(npf.max()) > _MC_PHI_STRIDE or int(nt.max()) > _MC_PHI_STRIDE:
            raise ValidationError("sample_scale", float(scale), f"at most {_MC_PHI_STRIDE} strata per axis")
        with jax.enable_x64(True):
            kj, kh = jax.random.split(key)
            size = int(nt.max()) * _MC_PHI_STRIDE
            jitter = np.asarray(jax.random.uniform(kj, (size, 2), jnp.float64))
            hs = np.asarray(jax.random.uniform(kh, (size,), jnp.float64, -1.0, 1.0))
        energy, dual = [], []
        for i in range(i0, i1):
            so = np.float64(nodes["sin_theta_o"][i])
            e, d = _x64(montecarlo_row_kernel, so, nodes["roughness"], sigma, nt, npf, jitter, hs, eta, alpha, block=block)
            energy.append(e)
            dual.append(d)
        shape = (0, nodes["roughness"].size, nodes["absorption"].size)
        if "mean_energy" in which:
            out["mean_energy"] = np.stack(energy) if energy else np.zeros((*shape, 4))
        if "dual_scattering" in which:
            out["dual_scattering"] = np.stack(dual) if dual else np.zeros((*shape, 6))
    if "coverage" in which:
        i0, i1 = _rows(start, stop, nodes["radius_px"].size, "rows")
        counts = nodes["strand_count"]
        strands = max(1, int(np.ceil(counts.max())))
        rows = []
        for i in range(i0, i1):
            with jax.enable_x64(True):
                k = jax.random.fold_in(jax.random.fold_in(key, 1), i)
                rows.append(
                    np.asarray(
                        montecarlo_coverage_kernel(
                            k,
                            jnp.float64(nodes["radius_px"][i]),
                            jnp.asarray(counts),
                            trials=int(coverage_trials),
                            strands=strands,
                        )
                    )
                )
        out["coverage"] = np.stack(rows) if rows else np.zeros((0, counts.size))
    return out
