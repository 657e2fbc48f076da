"""Slow NumPy float64 references for the real SH basis (tests and benchmarks only).

These use a *different* algorithm from the fast kernel in :mod:`._basis`, so that the two
can check each other:

* :func:`real_sh_reference` goes through angles: θ = atan2(ρ, z), φ = atan2(y, x); the
  *unnormalised* associated Legendre functions P_l^m(cos θ) (no Condon–Shortley phase) by
  the textbook recurrences ::

      P_m^m     = (2m−1)!! sin^m θ
      P_{m+1}^m = (2m+1) cos θ P_m^m
      (l−m) P_l^m = (2l−1) cos θ P_{l−1}^m − (l+m−1) P_{l−2}^m

  the normalisation N_lm = √((2−δ_m0)(2l+1)/(4π) · (l−m)!/(l+m)!) evaluated in log space
  with ``math.lgamma``, and finally cos(mφ) / sin(|m|φ) from ``np.cos`` / ``np.sin``.
  Unnormalised P_l^m stays below ~1e190 for l ≤ 100, hence the cap.

* :func:`real_sh_scipy` converts ``scipy.special.sph_harm_y`` (complex, with the
  Condon–Shortley phase) to the hairlut real basis::

      Y_l,0 = Re Y_l^0,   Y_l,m = √2 (−1)^m Re Y_l^m,   Y_l,−m = √2 (−1)^m Im Y_l^m   (m > 0)

  the (−1)^m removes scipy's Condon–Shortley phase.

Both return NumPy float64 arrays of shape (..., (lmax+1)²) in flat order i = l² + l + m.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ValidationError
from ._basis import check_dirs, check_lmax

REFERENCE_MAX_LMAX = 100


def _angles(lmax, dirs, normalize: bool):
    lmax = check_lmax(lmax)
    if lmax > REFERENCE_MAX_LMAX:
        raise ValidationError("lmax", lmax, f"the reference is valid for lmax ≤ {REFERENCE_MAX_LMAX}")
    d = np.asarray(check_dirs(dirs, normalize=normalize), dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    rho = np.hypot(x, y)
    theta = np.arctan2(rho, z)  # accurate near the poles, unlike arccos(z)
    phi = np.arctan2(y, x)
    return lmax, theta, phi


def log_norm(l: int, m: int) -> float:
    """log N_lm, N_lm = √((2−δ_m0)(2l+1)/(4π) · (l−|m|)!/(l+|m|)!), via lgamma."""
    m = abs(m)
    return 0.5 * (math.log((2.0 if m else 1.0) * (2 * l + 1) / (4.0 * math.pi)) + math.lgamma(l - m + 1) - math.lgamma(l + m + 1))


def legendre_unnormalised(lmax: int, t: np.ndarray, s: np.ndarray) -> dict[tuple[int, int], np.ndarray]:
    """P_l^m(t) for 0 ≤ m ≤ l ≤ lmax, no Condon–Shortley phase, given t = cos θ and s = sin θ ≥ 0."""
    p: dict[tuple[int, int], np.ndarray] = {}
    sectoral = np.ones_like(t)
    for m in range(lmax + 1):
        if m > 0:
            sectoral = sectoral * (2 * m - 1) * s
        p[m, m] = sectoral
        if m + 1 <= lmax:
            p[m + 1, m] = (2 * m + 1) * t * sectoral
        for l in range(m + 2, lmax + 1):
            p[l, m] = ((2 * l - 1) * t * p[l - 1, m] - (l + m - 1) * p[l - 2, m]) / (l - m)
    return p


def real_sh_reference(lmax: int, dirs, *, normalize: bool = False) -> np.ndarray:
    """Real SH by angles + unnormalised Legendre + log-space normalisation (float64, slow)."""
    lmax, theta, phi = _angles(lmax, dirs, normalize)
    t, s = np.cos(theta), np.sin(theta)
    p = legendre_unnormalised(lmax, t, s)
    out = np.empty(theta.shape + ((lmax + 1) ** 2,), dtype=np.float64)
    for l in range(lmax + 1):
        for m in range(-l, l + 1):
            am = abs(m)
            radial = math.exp(log_norm(l, am)) * p[l, am]
            if m > 0:
                out[..., l * l + l + m] = radial * np.cos(am * phi)
            elif m < 0:
                out[..., l * l + l + m] = radial * np.sin(am * phi)
            else:
                out[..., l * l + l] = radial
    return out


def real_sh_scipy(lmax: int, dirs, *, normalize: bool = False) -> np.ndarray:
    """Real SH from ``scipy.special.sph_harm_y`` (complex, Condon–Shortley) → hairlut basis."""
    from scipy.special import sph_harm_y  # scipy ≥ 1.15; imported lazily (tests/benchmarks only)

    lmax, theta, phi = _angles(lmax, dirs, normalize)
    out = np.empty(theta.shape + ((lmax + 1) ** 2,), dtype=np.float64)
    for l in range(lmax + 1):
        out[..., l * l + l] = sph_harm_y(l, 0, theta, phi).real
        for m in range(1, l + 1):
            y = sph_harm_y(l, m, theta, phi)
            sign = -1.0 if m % 2 else 1.0
            out[..., l * l + l + m] = math.sqrt(2.0) * sign * y.real
            out[..., l * l + l - m] = math.sqrt(2.0) * sign * y.imag
    return out


def legendre_p(l: int, t) -> np.ndarray:
    """Legendre polynomial P_l(t) by Bonnet's recurrence (float64), for the addition theorem."""
    t = np.asarray(t, dtype=np.float64)
    p0, p1 = np.ones_like(t), t
    if l == 0:
        return p0
    for n in range(2, l + 1):
        p0, p1 = p1, ((2 * n - 1) * t * p1 - (n - 1) * p0) / n
    return p1
