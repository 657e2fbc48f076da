"""How many SH bands an environment light needs: chosen from the radiance error it makes.

The hair's environment radiance without occlusion is xing eq 2 with b = (√4π, 0, …):

    E(t, θ′) = ∫ L(ω) (k_d sin θ + k_s max(0, −cos(θ + θ′))^p) dω,   θ = ∠(ω, t).

Both lobes are zonal about the tangent t, so by Funk–Hecke each light band l contributes
λ_l(θ′) L_l(t), L_l(t) = Σ_m a_lm Y_lm(t), λ_l = 2π ∫₋₁¹ k(x) P_l(x) dx:

    E_B(t, θ′) = Σ_{l<B} σ_l (k_d λ_l^d + k_s λ_l^s(θ′)) L_l(t)

for a light kept to B bands and windowed by σ_l.  The paper's rule, B = ⌈√p⌉ + 1, comes from
the lobe's energy alone; what a scene sees is E.  :func:`radiance_error` measures the RMS of
E_B − E_ref over tangents on a Fibonacci sphere and θ′ ∈ [0, π], relative to the RMS of E_ref,
where E_ref is the same light at :data:`REFERENCE_BANDS` bands with no window, and the share of
(t, θ′) samples where E_B < 0 in some channel (those the renderer clamps).  :func:`choose_bands`
returns the smallest B whose error is within ``environment.tolerance``.

**Windows** against ringing (Gibbs oscillation of a truncated light; Sloan, "Stupid SH tricks"):
``hanning`` σ_l = (1 + cos(π l / B)) / 2 and ``lanczos`` σ_l = sinc(l / B) (σ₀ = 1 both, so the
mean radiance is kept); ``none`` σ_l = 1.  A window trades a little blur of the light for fewer
negative lobes; the same factors on the 3-band voxel transmittance (:func:`window_factors` with
B = 3) damp its ringing.

NumPy, float64; the quadrature of λ_l is a midpoint rule in θ with enough nodes for p ≤ 512.
"""

from __future__ import annotations

import math

import numpy as np

from .. import errors

#: Bands of the reference radiance the error is measured against.
REFERENCE_BANDS = 30
WINDOWS = ("none", "hanning", "lanczos")


def window_factors(bands: int, window: str) -> np.ndarray:
    """σ_l (bands,) of a window over bands l < ``bands`` (module docstring)."""
    if window not in WINDOWS:
        raise errors.ValidationError("environment.window", window, f"one of {', '.join(WINDOWS)}")
    l = np.arange(bands, dtype=np.float64)
    if window == "hanning":
        return 0.5 * (1.0 + np.cos(np.pi * l / bands))
    if window == "lanczos":
        return np.sinc(l / bands)
    return np.ones(bands)


def window_coeffs(coeffs: np.ndarray, window: str) -> np.ndarray:
    """SH coefficients ((B², …)) with each band l scaled by the window's σ_l (B from their count)."""
    c = np.asarray(coeffs, np.float64)
    bands = int(round(math.sqrt(c.shape[0])))
    if bands * bands != c.shape[0]:
        raise errors.ValidationError("coeffs", c.shape, "need (B², …) SH coefficients")
    s = window_factors(bands, window)
    return c * np.repeat(s, 2 * np.arange(bands) + 1).reshape((-1,) + (1,) * (c.ndim - 1))


def _legendre(lmax: int, x: np.ndarray) -> np.ndarray:
    """P_l(x) for l ≤ lmax: (lmax + 1, *x.shape) by the three-term recurrence."""
    out = np.empty((lmax + 1,) + x.shape)
    out[0] = 1.0
    if lmax >= 1:
        out[1] = x
    for l in range(1, lmax):
        out[l + 1] = ((2 * l + 1) * x * out[l] - l * out[l - 1]) / (l + 1)
    return out


def lobe_bands(lmax: int, p: float, theta_v: np.ndarray, nodes: int = 8192) -> tuple[np.ndarray, np.ndarray]:
    """Funk–Hecke eigenvalues λ_l of the diffuse lobe sin θ (lmax + 1,) and of the specular lobe
    max(0, −cos(θ + θ′))^p ((θ′, lmax + 1)), by the midpoint rule in θ ∈ [0, π]."""
    th = (np.arange(nodes) + 0.5) * (np.pi / nodes)
    w = 2 * np.pi * np.sin(th) * (np.pi / nodes)
    P = _legendre(lmax, np.cos(th))  # (l, n)
    dif = P @ (np.sin(th) * w)
    lobe = np.maximum(0.0, -np.cos(th[None, :] + np.asarray(theta_v, np.float64)[:, None])) ** float(p)
    return dif, (lobe * w) @ P.T


def _fibonacci(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = np.pi * (1 + 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


def band_radiance(coeffs: np.ndarray, kd: float, ks: float, p: float, *, tangents: int = 2048, theta_v: int = 33) -> np.ndarray:
    """Per band l, the radiance term (k_d λ_l^d + k_s λ_l^s(θ′)) L_l(t): (l, t, θ′, C) for the
    light's own bands, tangents on a Fibonacci sphere and θ′ uniform in [0, π]."""
    from ..sh import real_sh

    c = np.asarray(coeffs, np.float64)
    bands = int(round(math.sqrt(c.shape[0])))
    t = _fibonacci(tangents)
    y = np.asarray(real_sh(bands - 1, t), np.float64)  # (t, B²)
    dif, spec = lobe_bands(bands - 1, p, np.linspace(0.0, np.pi, theta_v))
    out = np.empty((bands, tangents, theta_v, c.shape[1]))
    for l in range(bands):
        sl = slice(l * l, (l + 1) ** 2)
        L_l = y[:, sl] @ c[sl]  # (t, C)
        out[l] = (kd * dif[l] + ks * spec[:, l])[None, :, None] * L_l[:, None, :]
    return out


def radiance_error(terms: np.ndarray, bands: int, window: str = "none") -> tuple[float, float]:
    """(relative RMS error, clamped share) of the radiance at ``bands`` bands and ``window`` against
    all of ``terms``' bands unwindowed; ``terms`` from :func:`band_radiance`."""
    ref = terms.sum(0)
    e = np.tensordot(window_factors(bands, window), terms[:bands], axes=(0, 0))
    err = float(np.sqrt(np.mean((e - ref) ** 2)) / max(np.sqrt(np.mean(ref**2)), 1e-300))
    return err, float(np.mean(np.any(e < 0, axis=-1)))


def choose_bands(terms: np.ndarray, tolerance: float, window: str = "none", least: int = 3) -> tuple[int, float, float]:
    """The smallest B ≥ ``least`` with :func:`radiance_error` ≤ ``tolerance`` (or all the bands, when
    none is: a window's blur can keep the error above a tight tolerance), its error and clamped share."""
    top = terms.shape[0]
    for b in range(max(1, least), top + 1):
        err, clamped = radiance_error(terms, b, window)
        if err <= tolerance:
            return b, err, clamped
    return (top, *radiance_error(terms, top, window))
