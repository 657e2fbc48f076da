"""A slow, plain NumPy/``math`` float64 transcription of the hair BSDF of :mod:`._bsdf` (tests only).

One scalar at a time, straight from the equations (see :mod:`._bsdf` for the papers), with a few
deliberately different spellings so that the two check each other:

- angles: θ = atan2(sin θ, cos θ) and the exponent of d'Eon's M_p from 1 − cos(θ_i + θ_o) =
  2 sin²((θ_i + θ_o)/2) (the kernel uses a sum of squares of sines and cosines);
- M_p in the textbook form e^(−b) I₀(a) / (2 v sinh(1/v)) with ``scipy.special.i0`` where v ≥ 0.1 and in
  log space with ``scipy.special.i0e`` below (the kernel is in log space throughout);
- the azimuth wrapped with ``math.remainder``; the trimmed logistic normalised by the difference of its
  distribution function at ±π (the kernel uses tanh(π/(2s)));
- the residual lobe as pbrt writes it, A_2 f T / (1 − f T), with its limit 0 where f T = 1;
- Fresnel with Snell's law through the angles.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

from ._bsdf import COLOUR_POLYNOMIAL, P_MAX


def variance(beta_m: float) -> list[float]:
    """[Chiang eq. 7]: v_0 … v_3."""
    v0 = (0.726 * beta_m + 0.812 * beta_m**2 + 3.7 * beta_m**20) ** 2
    return [v0, 0.25 * v0, 4.0 * v0, 4.0 * v0]


def scale(beta_n: float) -> float:
    """[Chiang eq. 8]: the logistic scale s."""
    return math.sqrt(math.pi / 8.0) * (0.265 * beta_n + 1.194 * beta_n**2 + 5.372 * beta_n**22)


def sigma_a_from_colour(c: float, beta_n: float) -> float:
    """[Chiang eq. 9]."""
    d = sum(k * beta_n**i for i, k in enumerate(COLOUR_POLYNOMIAL))
    return (math.log(c) / d) ** 2


def mp(cos_i: float, cos_o: float, sin_i: float, sin_o: float, v: float) -> float:
    """d'Eon's longitudinal function."""
    a = cos_i * cos_o / v
    if v >= 0.1:
        b = sin_i * sin_o / v
        return math.exp(-b) * float(special.i0(a)) / (2.0 * v * math.sinh(1.0 / v))
    th_i, th_o = math.atan2(sin_i, cos_i), math.atan2(sin_o, cos_o)
    one_minus_cos = 2.0 * math.sin(0.5 * (th_i + th_o)) ** 2
    log_m = (
        math.log(float(special.i0e(a))) - one_minus_cos / v - math.log(2.0 * v) - math.log1p(-math.exp(-2.0 / v)) + math.log(2.0)
    )
    return math.exp(log_m)


def fresnel(cos_i: float, eta: float) -> float:
    """Unpolarised dielectric reflectance through Snell's law."""
    th_i = math.acos(min(max(cos_i, -1.0), 1.0))
    th_t = math.asin(math.sin(th_i) / eta)
    ci, ct = math.cos(th_i), math.cos(th_t)
    rs = (ci - eta * ct) / (ci + eta * ct)
    rp = (eta * ci - ct) / (eta * ci + ct)
    return 0.5 * (rs * rs + rp * rp)


def ap(cos_o: float, eta: float, h: float, t: float) -> list[float]:
    """A_0 … A_3 (pbrt's Ap)."""
    f = fresnel(cos_o * math.sqrt(max(0.0, 1.0 - h * h)), eta)
    a = [f, (1.0 - f) ** 2 * t]
    a.append(a[1] * t * f)
    den = 1.0 - t * f
    a.append(a[2] * f * t / den if den > 0.0 else 0.0)
    return a


def logistic(x: float, s: float) -> float:
    x = abs(x)
    return math.exp(-x / s) / (s * (1.0 + math.exp(-x / s)) ** 2)


def logistic_cdf(x: float, s: float) -> float:
    return 1.0 / (1.0 + math.exp(-x / s)) if x > -700 * s else 0.0


def np_(phi: float, p: int, s: float, gamma_o: float, gamma_t: float) -> float:
    """N_p: the trimmed logistic about Φ_p = 2p γ_t − 2γ_o + pπ."""
    dphi = math.remainder(phi - (2 * p * gamma_t - 2 * gamma_o + p * math.pi), 2.0 * math.pi)
    return logistic(dphi, s) / (logistic_cdf(math.pi, s) - logistic_cdf(-math.pi, s))


def lobes_one(wo, wi, h, sigma_a, beta_m, beta_n, alpha_deg, eta, unattenuated=False) -> list[float]:
    """M_p A_p N_p, p = 0 … 3, for one direction pair, one channel (M_p N_p with ``unattenuated``)."""
    sin_o = max(-1.0, min(1.0, wo[0]))
    cos_o = math.hypot(wo[1], wo[2])
    phi_o = math.atan2(wo[2], wo[1])
    sin_i = max(-1.0, min(1.0, wi[0]))
    cos_i = math.hypot(wi[1], wi[2])
    phi_i = math.atan2(wi[2], wi[1])
    th_o = math.atan2(sin_o, cos_o)
    sin_t = sin_o / eta
    cos_t = math.sqrt(1.0 - sin_t * sin_t)
    eta_p = math.sqrt(eta * eta - sin_o * sin_o)
    sin_gt = h * cos_o / eta_p  # h / η′ with η′ = √(η² − sin²θ_o) / cos θ_o
    cos_gt = math.sqrt(max(0.0, 1.0 - sin_gt * sin_gt))
    gamma_o, gamma_t = math.asin(max(-1.0, min(1.0, h))), math.asin(sin_gt)
    t = math.exp(-sigma_a * 2.0 * cos_gt / cos_t)
    a = ap(cos_o, eta, h, t)
    v = variance(beta_m)
    s = scale(beta_n)
    alpha = math.radians(alpha_deg)
    out = []
    for p, shift in enumerate((-2.0 * alpha, alpha, 4.0 * alpha, 0.0)):
        th = th_o + shift
        m = mp(cos_i, abs(math.cos(th)), sin_i, math.sin(th), v[p])
        n = np_(phi_i - phi_o, p, s, gamma_o, gamma_t) if p < P_MAX else 1.0 / (2.0 * math.pi)
        out.append(m * n if unattenuated else m * a[p] * n)
    return out


def lobes(wo, wi, h, sigma_a, beta_m, beta_n, alpha=2.0, eta=1.55, unattenuated=False) -> np.ndarray:
    """:func:`lobes_one` over broadcast arrays: (..., C, 4) like :func:`hairlut.hairbsdf._bsdf.lobes` (M_p N_p
    alone with ``unattenuated``: the scale against which a rounding of A_p is measured)."""
    wo, wi = np.asarray(wo, float), np.asarray(wi, float)
    wo = wo / np.linalg.norm(wo, axis=-1, keepdims=True)
    wi = wi / np.linalg.norm(wi, axis=-1, keepdims=True)
    sa = np.atleast_1d(np.asarray(sigma_a, float))
    shape = np.broadcast_shapes(wo.shape[:-1], wi.shape[:-1], np.shape(h), np.shape(beta_m), np.shape(beta_n), sa.shape[:-1])
    wo = np.broadcast_to(wo, (*shape, 3))
    wi = np.broadcast_to(wi, (*shape, 3))
    h, bm, bn = (np.broadcast_to(np.asarray(x, float), shape) for x in (h, beta_m, beta_n))
    sa = np.broadcast_to(sa, (*shape, sa.shape[-1]))
    out = np.zeros((*shape, sa.shape[-1], 4))
    for idx in np.ndindex(*shape):
        for c in range(sa.shape[-1]):
            out[idx + (c,)] = lobes_one(
                wo[idx], wi[idx], float(h[idx]), float(sa[idx + (c,)]), float(bm[idx]), float(bn[idx]), alpha, eta, unattenuated
            )
    return out


def albedo(sin_o: float, h: float, sigma_a: float, eta: float = 1.55) -> float:
    """Σ_p A_p(θ_o, h): the exact directional albedo at offset h (every M_p and N_p integrates to 1)."""
    cos_o = math.sqrt(max(0.0, 1.0 - sin_o * sin_o))
    cos_t = math.sqrt(1.0 - (sin_o / eta) ** 2)
    sin_gt = h * cos_o / math.sqrt(eta * eta - sin_o * sin_o)
    t = math.exp(-sigma_a * 2.0 * math.sqrt(1.0 - sin_gt**2) / cos_t)
    return sum(ap(cos_o, eta, h, t))
