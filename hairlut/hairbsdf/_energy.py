"""The BSDF tables' integrals, one sin θ_o row at a time: mean energy and dual scattering, and the white furnace.

Computed from the BSDF of :mod:`._bsdf` (Chiang et al. 2016, "A Practical and Controllable Hair and Fur Model for
Production Path Tracing") and the dual-scattering definitions of Zinke, Yuksel, Weber and Keyser 2008, "Dual
Scattering Approximation for Fast Multiple Scattering in Hair", on the axes of :mod:`._axes`:

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

**How** (every value comes with an error estimate, |Q_m − Q_{m/2}|, the difference between the rule with
``nodes`` = m Gauss–Legendre nodes per panel and the rule with m/2 on the same panels; the value is Q_m):

- The BSDF factorises: M_p depends on θ_i (and θ_o), N_p on φ_i − φ_o and h, A_p on h.  Each M_p
  integrates to 1 over θ_i and each N_p to 1 over φ (both exactly, [d'Eon], [Chiang §4.2]; the white
  furnace test checks it by 2-D quadrature, :func:`furnace_kernel`), so E_p = ½ ∫ A_p dh and a_f,p = ½ ∫ A_p
  (1 − c_p) dh, a_b,p = ½ ∫ A_p c_p dh, with c_p(h) the part of N_p in the back half, a closed form of the
  logistic's distribution function (:func:`._quadrature.back_fraction`).  The h integrals are taken in
  γ = asin h on panels graded about the crossings of ±π/2 (:mod:`._quadrature`).
- The moments α_p, β_p are θ_i quadratures of M_p cos θ_i on panels graded about each lobe's centre
  (−θ_o shifted by the tilt) in units of its width √v_p.

Measured on the 2-core development machine, shared (load average 5–8), default axes and resolutions:

- mean energy and dual scattering, 64 × 64 × 16, ``nodes`` = 12: 1.5–2.0 s wall (1.5 s CPU) for all 64 rows
  (12- and 6-node rules, one program per row); against 24 nodes: mean energy R, TT, TRT ≤ 3.6e-10 (residual
  1.0e-7), A_f, A_b ≤ 2.3e-7, ᾱ, β̄ ≤ 4.6e-8; the stored estimates ≤ 5.6e-5.  ``nodes`` = 8: error ≤ 4.3e-6.
- the white furnace (:func:`._integrals.furnace`, 16 nodes): max |1 − E| = 9.7e-15 over 21 sin θ_o × 9 h × 6 × 6
  (β_m, β_n) ∈ [0.05, 1]², the rule's estimates ≤ 8.2e-8.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from . import _bsdf as B
from ._quadrature import _HALF_PI, _graded, _h_breaks, _panels, back_fraction

# ----------------------------------------------------------------------------- the BSDF tables, one row


def _segments(parts):
    """The arrays ``parts`` joined along their last axis, and the (start, stop) of each in the whole."""
    bounds, at = [], 0
    for x in parts:
        bounds.append((at, at + x.shape[-1]))
        at += x.shape[-1]
    return jnp.concatenate(parts, axis=-1), bounds


def _theta_moments(sin_o, cos_o, rough, alpha, rules: tuple[int, ...], levels: int):
    """[(α_p, β_p²) (R, 4) for each rule of ``rules`` (nodes per panel)]: the mean and variance of
    θ_h = (θ_i + θ_o)/2 under M_p(θ_i) cos θ_i dθ_i, every rule on the same panels (graded about each lobe's centre
    in units of its width √v_p), M_p evaluated once on every rule's nodes."""
    v = B.longitudinal_variance(rough)  # (R, 4)
    sin_p, cos_p = B.tilt(sin_o, cos_o, alpha)  # (4,)
    centre = -jnp.arctan2(sin_p, cos_p)
    offsets = jnp.asarray(_graded(levels, 2.0))
    pts = centre[None, :, None] + jnp.sqrt(v)[..., None] * offsets
    ends = jnp.broadcast_to(jnp.asarray([-_HALF_PI, _HALF_PI]), (*v.shape, 2))
    breaks = jnp.sort(jnp.clip(jnp.concatenate([pts, ends], axis=-1), -_HALF_PI, _HALF_PI), axis=-1)
    nodes = [_panels(breaks, m) for m in rules]
    th, bounds = _segments([x for x, _ in nodes])  # (R, 4, N)
    w, _ = _segments([x for _, x in nodes])
    mp = B.longitudinal(jnp.sin(th), jnp.cos(th), sin_p[:, None], cos_p[:, None], v[..., None])
    wt = w * mp * jnp.cos(th)
    theta_o = jnp.arctan2(sin_o, cos_o)
    out = []
    for i0, i1 in bounds:
        wr, tr = wt[..., i0:i1], th[..., i0:i1]
        z = jnp.sum(wr, axis=-1)
        mean = jnp.sum(wr * tr, axis=-1) / z
        var = jnp.sum(wr * (tr - mean[..., None]) ** 2, axis=-1) / z
        out.append((0.5 * (mean + theta_o), 0.25 * var))
    return out


def _bsdf_rules(sin_o, rough, sigma, eta, alpha, rules: tuple[int, ...], levels: int):
    """One sin θ_o, for each rule of ``rules`` (Gauss–Legendre nodes per panel, all on the same panels): [(mean
    energy (R, K, 4), dual scattering (R, K, 6))] for roughness (R,) and σ_a (R, K).

    The panels (the crossings' bisection and the grading) are built once for every rule; every lobe's and every
    rule's γ nodes are joined on one axis (N), where the geometry that does not depend on σ_a (Fresnel factor,
    back fraction, path length) is evaluated once; then a loop over the K absorption columns computes the
    transmittance and the attenuated sums of one column at a time on (R, N), each lobe's and rule's segment summed
    apart.  One (R, N) column at a time keeps the working memory small (no (R, K, N) array) and the loop body is
    traced once."""
    cos_o = B._sqrt1m(sin_o)
    k = B.bravais_inverse(sin_o, cos_o, eta)
    cos_t = B._sqrt1m(sin_o / eta)
    s = B.azimuthal_scale(rough)
    br01, br2 = _h_breaks((0, 1), k, s, levels), _h_breaks((2,), k, s, levels)  # (2, R, B), (1, R, B′)
    breaks = (br01[0], br01[1], br2[0])
    parts, lobe = [], []
    for m in rules:
        for p in range(B.P_MAX):
            g, w = _panels(breaks[p], m)  # (R, n)
            parts.append((g, 0.5 * w * jnp.cos(g)))  # the h measure ½ dh = ½ cos γ dγ
            lobe.append(np.full(g.shape[-1], p, np.float64))
    g, bounds = _segments([x for x, _ in parts])  # (R, N): lobes 0, 1, 2 of each rule in turn
    w, _ = _segments([x for _, x in parts])
    lobe = np.concatenate(lobe)  # (N,), static
    sin_gt = k * jnp.sin(g)
    f = B.fresnel(cos_o * jnp.cos(g), eta)
    c = back_fraction(B.phi_centre(lobe, g, jnp.arcsin(sin_gt)), s[:, None])
    length = 2.0 * B._sqrt1m(sin_gt) / cos_t
    f, w, c, length = jax.lax.optimization_barrier((f, w, c, length))

    def column(sig):
        """σ_a (R,) → (R, n_rules, 4 lobes, 2 halves): the back and front halves' energy of every lobe."""
        t = jnp.exp(-sig[:, None] * length)  # (R, N)
        a1 = (1.0 - f) ** 2 * t
        wa = w * jnp.where(lobe == 0, f, jnp.where(lobe == 1, a1, a1 * t * f))  # A_0 = f, A_1, A_2
        wab = wa * c
        rows = []
        for j in range(len(rules)):
            halves = []
            for p in range(B.P_MAX):
                i0, i1 = bounds[B.P_MAX * j + p]
                wb = jnp.sum(wab[:, i0:i1], axis=-1)
                halves.append(jnp.stack([wb, jnp.sum(wa[:, i0:i1], axis=-1) - wb], axis=-1))
            # the residual lobe (uniform in azimuth: half in each half) on lobe 0's nodes
            i0, i1 = bounds[B.P_MAX * j]
            a3 = B.attenuation(f[:, i0:i1], t[:, i0:i1])[..., B.P_MAX]
            halves.append(jnp.broadcast_to(0.5 * jnp.sum(w[:, i0:i1] * a3, axis=-1)[:, None], (sig.shape[0], 2)))
            rows.append(jnp.stack(halves, axis=1))
        return jnp.stack(rows, axis=1)

    energy = jnp.moveaxis(jax.lax.map(column, sigma.T), 0, 1)  # (R, K, n_rules, 4, 2)
    moments = _theta_moments(sin_o, cos_o, rough, alpha, rules, levels)
    out = []
    for j, (mean_a, var_b) in enumerate(moments):
        bk, fr = energy[:, :, j, :, 0], energy[:, :, j, :, 1]  # (R, K, 4)
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
        out.append((fr + bk, dual))
    return out


def _bsdf_row(sin_o, rough, sigma, eta, alpha, m: int, levels: int):
    """(mean energy, its error, dual scattering, its error): the m-node rule's values and their distance from the
    m/2-node rule's."""
    (e1, d1), (e0, d0) = _bsdf_rules(sin_o, rough, sigma, eta, alpha, (m, m // 2), levels)
    return e1, jnp.abs(e1 - e0), d1, jnp.abs(d1 - d0)


@functools.partial(jax.jit, static_argnames=("m", "levels"))
def bsdf_row_kernel(sin_o, rough, sigma, eta, alpha, *, m, levels):
    """The BSDF tables' row kernel (float64): sin_o (), rough (R,), sigma (R, K), η, α (radians) →
    (mean energy (R, K, 4), its error estimate, dual scattering (R, K, 6), its error estimate), both rules
    (m and m/2 nodes per panel) in one program."""
    return _bsdf_row(sin_o, rough, sigma, eta, alpha, m, levels)


@functools.partial(jax.jit, static_argnames=("m", "levels"))
def bsdf_point_kernel(sin_o, rough, sigma, eta, alpha, *, m, levels):
    """The same at P scattered points: sin_o, rough, sigma (P,) → ((P, 4), (P, 4), (P, 6), (P, 6))."""

    def one(so, r, sg):
        return tuple(x[0, 0] for x in _bsdf_row(so, r[None], sg[None, None], eta, alpha, m, levels))

    return jax.lax.map(lambda x: one(*x), (sin_o, rough, sigma))


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
