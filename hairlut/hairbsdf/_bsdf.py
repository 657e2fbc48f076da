"""The hair BSDF of Chiang et al. 2016 in JAX (float64), as pbrt-v4's ``HairBxDF`` evaluates and samples it.

Sources (cited by title; "§" and "eq." refer to them):

- [Chiang] M. J.-Y. Chiang, B. Bitterli, C. Tappan, B. Burley, "A Practical and Controllable Hair and Fur
  Model for Production Path Tracing", Computer Graphics Forum 35(2), Eurographics 2016.  The near-field
  model f = Σ_p M_p A_p N_p (§4), the logistic azimuthal distribution (§4.2), the residual lobe p_max that
  sums every order p ≥ 3 (§4.3), the roughness maps β_m → v and β_n → s (§5, eqs. 7 and 8) and the
  colour → absorption inversion (§5, eq. 9).
- [d'Eon] E. d'Eon, G. Francois, M. Hill, J. Letteri, J.-M. Aubry, "An Energy-Conserving Hair Reflectance
  Model", Computer Graphics Forum 30(4), EGSR 2011.  The longitudinal scattering function M_p (§3, the
  spherical-Gaussian convolution with the modified Bessel function I₀), normalised on the sphere:
  ∫ M_p(θ_i, θ_o) cos θ_i dθ_i = 1 for every θ_o and v.
- [pbrt] M. Pharr, W. Jakob, G. Humphreys, "Physically Based Rendering: From Theory to Implementation",
  4th edition, §9.9 "Scattering from Hair" (and M. Pharr, "The Implementation of a Hair Scattering
  Model", 2016): the hair frame, the cuticle tilt applied to θ_o per lobe, the melanin absorption
  coefficients, and the sampling routine (choose p by A_p, sample M_p exactly, sample N_p exactly).

The frame is pbrt's: directions are unit vectors with x along the fibre (from root to tip), so
sin θ = w_x and φ = atan2(w_z, w_y); h ∈ [−1, 1] is the offset across the fibre where the ray meets it
(γ_o = asin h).  For each lobe p (0 = R, 1 = TT, 2 = TRT, 3 = the residual p ≥ 3)::

    f(ωo, ωi) |cos_z ωi| = Σ_p M_p(θ_i; θ_o^(p), v_p) · A_p(θ_o, h) · N_p(φ_i − φ_o; θ_o, h)

where |cos_z ωi| = |w_i,z| is the cosine of pbrt's curve shading frame, so :func:`lobes` returns the
terms M_p A_p N_p (the integrand of the rendering equation, with dω = cos θ dθ dφ) and :func:`f` divides
their sum by |w_i,z|, as pbrt does.  Every M_p and N_p integrates to 1 over the sphere, so the directional
albedo at a fixed h is Σ_p A_p(θ_o, h) exactly, and 1 when σ_a = 0 (the white furnace).

- **M_p** (d'Eon): M = e^(−b) I₀(a) / (2 v sinh(1/v)), a = cos θ_i cos θ_o / v, b = sin θ_i sin θ_o / v.
  Evaluated in log space for every v, with the *exact* exponentially scaled Bessel function
  (``i0e(a) = e^(−a) I₀(a)``) instead of pbrt's 10-term series and asymptotic log I₀: log M =
  log i0e(a) − (1 − cos(θ_i + θ_o))/v − log v − log(1 − e^(−2/v)), with 1 − cos(θ_i + θ_o) written as
  ((sin θ_i + sin θ_o)² + (cos θ_i − cos θ_o)²)/2, a sum of squares that loses no digits near the lobe's
  peak.  (pbrt's 10-term series for I₀ is 0.3 % low at a = 10 and 2 % at a = 12, where its asymptotic log I₀
  takes over 0.6 % off; with them ∫ M_p cos θ_i dθ_i is 1 only within 1.1 % for β_m ≥ 0.05, measured by a
  4000-node quadrature, which would break a 1e-4 furnace.)
- **Cuticle tilt** α (degrees, pbrt's default 2°): M_0 is evaluated at θ_o − 2α, M_1 at θ_o + α, M_2 at
  θ_o + 4α (|cos| taken, as pbrt), the residual unrotated: the lobes' centres in θ_i sit at −θ_o + 2α (R),
  −θ_o − α (TT), −θ_o − 4α (TRT).
- **Roughness** [Chiang eqs. 7, 8]: v_0 = (0.726 β_m + 0.812 β_m² + 3.7 β_m²⁰)², v_1 = v_0/4,
  v_2 = v_3 = 4 v_0; s = √(π/8) (0.265 β_n + 1.194 β_n² + 5.372 β_n²²).
- **N_p** [Chiang §4.2]: the logistic distribution of scale s, trimmed to [−π, π] and normalised by
  tanh(π/(2s)), centred on Φ_p = 2p γ_t − 2γ_o + pπ (γ_t = asin(h/η′), η′ = √(η² − sin²θ_o)/cos θ_o, the
  Bravais index); the residual's N is 1/(2π).
- **A_p** [Chiang §4.3]: f = F(cos θ_o cos γ_o) (unpolarised dielectric Fresnel, η = 1.55 by default),
  T = exp(−σ_a · 2 cos γ_t / cos θ_t); A_0 = f, A_1 = (1 − f)² T, A_2 = A_1 T f and the residual
  A_3 = A_2 f T / (1 − f T), written (1 − f)·[(1 − f)/(1 − f T)]·T³ f² so that it has its limit 0, not
  0/0, at grazing incidence (f = 1) without absorption.
- **Absorption** σ_a (per unit radius): given directly; from melanin (pbrt's coefficients, eumelanin
  (0.419, 0.697, 1.37), pheomelanin (0.187, 0.4, 1.05)); or from a colour C ∈ (0, 1] by [Chiang eq. 9],
  σ_a = (ln C / (5.969 − 0.215 β_n + 2.532 β_n² − 10.73 β_n³ + 5.574 β_n⁴ + 0.245 β_n⁵))².

Not reciprocal in general (pbrt §9.9.6 says why: A_p and N_p use θ_o only, and the tilt rotates θ_o
only); what holds is stated where the tests check it (tests/test_hairbsdf_physics.py).  No NaN at the
poles (sin θ = ±1), at grazing offsets (h = ±1) or at σ_a = 0: every square root, arcsine and quotient is
guarded.

The public functions validate and convert (float64 NumPy out); the ``*_kernel`` functions are the jitted
float64 kernels (call them under ``jax.enable_x64``); the lower-case primitives are pure ``jax.numpy``
functions that the quadratures of :mod:`._quadrature`, :mod:`._energy` and :mod:`._montecarlo` compose.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import i0e

from ..errors import ValidationError

#: The number of explicit lobes (R, TT, TRT); index P_MAX is the residual lobe of every p ≥ P_MAX.
P_MAX = 3
LOBES = ("R", "TT", "TRT", "residual")
#: pbrt-v4's defaults: the fibre's refractive index and the cuticle tilt in degrees.
ETA = 1.55
ALPHA = 2.0
#: Absorption coefficients (per unit radius, RGB) per unit concentration of the two melanins (pbrt).
EUMELANIN_SIGMA_A = (0.419, 0.697, 1.37)
PHEOMELANIN_SIGMA_A = (0.187, 0.4, 1.05)
#: [Chiang eq. 9]'s polynomial in β_n, lowest order first.
COLOUR_POLYNOMIAL = (5.969, -0.215, 2.532, -10.73, 5.574, 0.245)
_SQRT_PI_OVER_8 = math.sqrt(math.pi / 8.0)
_TWO_PI = 2.0 * math.pi


def _xp(*args):
    for a in args:
        if type(a).__module__.split(".")[0] in ("jax", "jaxlib"):
            return jnp
    return np


# ----------------------------------------------------------------------------- parameter maps (NumPy or JAX)


def longitudinal_variance(beta_m):
    """v_p for p = 0 … 3, shape (..., 4) [Chiang eq. 7]: v_0 = (0.726 β + 0.812 β² + 3.7 β²⁰)², v_1 = v_0/4,
    v_2 = v_3 = 4 v_0."""
    xp = _xp(beta_m)
    b = beta_m
    v0 = (0.726 * b + 0.812 * b * b + 3.7 * b**20) ** 2
    return xp.stack([v0, 0.25 * v0, 4.0 * v0, 4.0 * v0], axis=-1)


def azimuthal_scale(beta_n):
    """The logistic scale s = √(π/8) (0.265 β_n + 1.194 β_n² + 5.372 β_n²²) [Chiang eq. 8]."""
    b = beta_n
    return _SQRT_PI_OVER_8 * (0.265 * b + 1.194 * b * b + 5.372 * b**22)


def colour_denominator(beta_n):
    """[Chiang eq. 9]'s denominator D(β_n) = 5.969 − 0.215 β_n + 2.532 β_n² − 10.73 β_n³ + 5.574 β_n⁴ +
    0.245 β_n⁵ (3.375 at β_n = 1, positive on [0, 1])."""
    d = 0.0
    for c in reversed(COLOUR_POLYNOMIAL):
        d = d * beta_n + c
    return d


def colour_to_sigma_a(colour, beta_n):
    """σ_a = (ln C / D(β_n))² [Chiang eq. 9], unchecked (C in (0, 1], works on NumPy and JAX arrays)."""
    xp = _xp(colour, beta_n)
    return (xp.log(colour) / colour_denominator(beta_n)) ** 2


def sigma_a_to_colour(sigma_a, beta_n):
    """The inverse of :func:`colour_to_sigma_a`: C = exp(−√σ_a · D(β_n)), unchecked."""
    xp = _xp(sigma_a, beta_n)
    return xp.exp(-xp.sqrt(sigma_a) * colour_denominator(beta_n))


# ----------------------------------------------------------------------------- JAX primitives


def _sqrt1m(x):
    """√(1 − x²) = √((1 − x)(1 + x)), clamped to 0 outside [−1, 1]."""
    return jnp.sqrt(jnp.maximum((1.0 - x) * (1.0 + x), 0.0))


def wrap_angle(x):
    """x wrapped to [−π, π] (by the nearest multiple of 2π)."""
    return x - _TWO_PI * jnp.round(x / _TWO_PI)


def longitudinal(sin_i, cos_i, sin_o, cos_o, v):
    """d'Eon's M_p(θ_i, θ_o; v) in log space with the exact log I₀ (module docstring); cos_i, cos_o ≥ 0, v > 0.

    Normalised: ∫_{−π/2}^{π/2} M cos θ_i dθ_i = 1."""
    a = cos_i * cos_o / v
    t = 0.5 * ((sin_i + sin_o) ** 2 + (cos_i - cos_o) ** 2)  # 1 − cos(θ_i + θ_o) ≥ 0, no cancellation
    log_m = jnp.log(i0e(a)) - t / v - jnp.log(v) - jnp.log(-jnp.expm1(-2.0 / v))
    return jnp.exp(log_m)


def fresnel(cos_i, eta):
    """Unpolarised Fresnel reflectance of a dielectric of index η > 1 seen from outside, cos_i ∈ [0, 1]."""
    sin2_t = (1.0 - cos_i) * (1.0 + cos_i) / (eta * eta)
    cos_t = jnp.sqrt(jnp.maximum(1.0 - sin2_t, 0.0))
    r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    return 0.5 * (r_par * r_par + r_perp * r_perp)


def bravais_inverse(sin_o, cos_o, eta):
    """k = 1/η′ = cos θ_o / √(η² − sin²θ_o): sin γ_t = k h (0 at the poles, where η′ is infinite)."""
    return cos_o / jnp.sqrt(eta * eta - sin_o * sin_o)


def path_length(sin_o, h, eta):
    """The attenuation length 2 cos γ_t / cos θ_t of one pass through the fibre (radius 1)."""
    cos_o = _sqrt1m(sin_o)
    sin_gt = bravais_inverse(sin_o, cos_o, eta) * h
    cos_t = _sqrt1m(sin_o / eta)
    return 2.0 * _sqrt1m(sin_gt) / cos_t


def attenuation(f, transmittance):
    """A_p for p = 0 … 3 (..., 4) from the Fresnel factor f and the one-pass transmittance T [Chiang §4.3]."""
    a0 = f
    a1 = (1.0 - f) ** 2 * transmittance
    a2 = a1 * transmittance * f
    den = 1.0 - f * transmittance
    ok = den > 0.0
    ratio = jnp.where(ok, (1.0 - f) / jnp.where(ok, den, 1.0), 1.0)
    a3 = (1.0 - f) * jnp.minimum(ratio, 1.0) * transmittance**3 * f * f
    return jnp.stack(jnp.broadcast_arrays(a0, a1, a2, a3), axis=-1)


def phi_centre(p, gamma_o, gamma_t):
    """Φ_p = 2p γ_t − 2γ_o + pπ, the exit azimuth of lobe p."""
    return 2.0 * p * gamma_t - 2.0 * gamma_o + p * math.pi


def trimmed_logistic(x, s):
    """The logistic density of scale s trimmed to [−π, π] and renormalised (by tanh(π/(2s)))."""
    e = jnp.exp(-jnp.abs(x) / s)
    return e / (s * (1.0 + e) ** 2) / jnp.tanh(0.5 * math.pi / s)


def logistic_cdf(x, s):
    """The logistic distribution function 1/(1 + e^(−x/s))."""
    return jax.nn.sigmoid(x / s)


def tilt(sin_o, cos_o, alpha):
    """(sin θ_o^(p), |cos θ_o^(p)|) for p = 0 … 3, each (..., 4): θ_o − 2α, θ_o + α, θ_o + 4α, θ_o (α in radians)."""
    rot = jnp.stack(jnp.broadcast_arrays(-2.0 * alpha, alpha, 4.0 * alpha, 0.0 * alpha), axis=-1)
    s, c = jnp.sin(rot), jnp.cos(rot)
    sin_p = sin_o[..., None] * c + cos_o[..., None] * s
    cos_p = jnp.abs(cos_o[..., None] * c - sin_o[..., None] * s)
    return sin_p, cos_p


def _fibre(sin_o, cos_o, h, eta):
    """(γ_o, cos γ_o, γ_t, cos γ_t, cos θ_t) of the refracted path at offset h."""
    h = jnp.clip(h, -1.0, 1.0)
    sin_gt = bravais_inverse(sin_o, cos_o, eta) * h
    return jnp.arcsin(h), _sqrt1m(h), jnp.arcsin(sin_gt), _sqrt1m(sin_gt), _sqrt1m(sin_o / eta)


def _angles(w):
    """(sin θ, cos θ, φ) of unit vectors w (..., 3) in the hair frame (x along the fibre)."""
    return jnp.clip(w[..., 0], -1.0, 1.0), jnp.hypot(w[..., 1], w[..., 2]), jnp.arctan2(w[..., 2], w[..., 1])


def _terms(sin_o, cos_o, h, sigma_a, beta_m, beta_n, alpha, eta):
    """Everything that depends on ωo and h: (A (..., C, 4), sinθ_o^(p), cosθ_o^(p) (..., 4), v (..., 4), s,
    γ_o, γ_t)."""
    gamma_o, cos_go, gamma_t, cos_gt, cos_t = _fibre(sin_o, cos_o, h, eta)
    transmittance = jnp.exp(-sigma_a * (2.0 * cos_gt / cos_t)[..., None])
    f = fresnel(cos_o * cos_go, eta)[..., None]
    a = attenuation(f, transmittance)
    sin_p, cos_p = tilt(sin_o, cos_o, alpha)
    return a, sin_p, cos_p, longitudinal_variance(beta_m), azimuthal_scale(beta_n), gamma_o, gamma_t


def _mn(sin_i, cos_i, dphi, sin_p, cos_p, v, s, gamma_o, gamma_t):
    """M_p (..., 4) and N_p (..., 4) at the incident direction."""
    m = longitudinal(sin_i[..., None], cos_i[..., None], sin_p, cos_p, v)
    n = [trimmed_logistic(wrap_angle(dphi - phi_centre(p, gamma_o, gamma_t)), s) for p in range(P_MAX)]
    n.append(jnp.full_like(dphi, 1.0 / _TWO_PI))
    return m, jnp.stack(jnp.broadcast_arrays(*n), axis=-1)


def lobes_angles(sin_o, cos_o, phi_o, sin_i, cos_i, phi_i, h, sigma_a, beta_m, beta_n, alpha, eta):
    """M_p A_p N_p for p = 0 … 3, shape (..., C, 4), from angles (sigma_a (..., C); α in radians)."""
    a, sin_p, cos_p, v, s, gamma_o, gamma_t = _terms(sin_o, cos_o, h, sigma_a, beta_m, beta_n, alpha, eta)
    m, n = _mn(sin_i, cos_i, phi_i - phi_o, sin_p, cos_p, v, s, gamma_o, gamma_t)
    return (m * n)[..., None, :] * a


def _ap_pdf(a):
    """pbrt's discrete lobe pdf: A_p averaged over the channels, normalised (..., 4)."""
    mean = jnp.mean(a, axis=-2)
    return mean / jnp.sum(mean, axis=-1, keepdims=True)


def _pdf_angles(sin_i, cos_i, dphi, terms):
    a, sin_p, cos_p, v, s, gamma_o, gamma_t = terms
    m, n = _mn(sin_i, cos_i, dphi, sin_p, cos_p, v, s, gamma_o, gamma_t)
    return jnp.sum(m * n * _ap_pdf(a), axis=-1)


# ----------------------------------------------------------------------------- jitted kernels


@jax.jit
def lobes_kernel(wo, wi, h, sigma_a, beta_m, beta_n, alpha, eta):
    """M_p A_p N_p (..., C, 4) for unit wo, wi (..., 3), h, β_m, β_n (...), σ_a (..., C), α (radians), η."""
    sin_o, cos_o, phi_o = _angles(wo)
    sin_i, cos_i, phi_i = _angles(wi)
    return lobes_angles(sin_o, cos_o, phi_o, sin_i, cos_i, phi_i, h, sigma_a, beta_m, beta_n, alpha, eta)


@jax.jit
def pdf_kernel(wo, wi, h, sigma_a, beta_m, beta_n, alpha, eta):
    """pbrt's sampling density (per unit solid angle) of wi given wo: Σ_p M_p Ã_p N_p (Ã_p: :func:`_ap_pdf`)."""
    sin_o, cos_o, phi_o = _angles(wo)
    sin_i, cos_i, phi_i = _angles(wi)
    terms = _terms(sin_o, cos_o, h, sigma_a, beta_m, beta_n, alpha, eta)
    return _pdf_angles(sin_i, cos_i, phi_i - phi_o, terms)


@jax.jit
def sample_kernel(wo, u, h, sigma_a, beta_m, beta_n, alpha, eta):
    """Importance sampling as pbrt's ``HairBxDF::Sample_f``, with four uniforms u (..., 4) in [0, 1):
    u₀ picks the lobe p with probability Ã_p, (u₁, u₂) sample M_p exactly (d'Eon's spherical-Gaussian
    construction about the tilted cone), u₃ samples N_p exactly (the trimmed logistic's inverse CDF about
    Φ_p; uniform for the residual).  Returns (wi (..., 3), pdf (...), lobes M_p A_p N_p at wi (..., C, 4))."""
    sin_o, cos_o, phi_o = _angles(wo)
    terms = _terms(sin_o, cos_o, h, sigma_a, beta_m, beta_n, alpha, eta)
    a, sin_p, cos_p, v, s, gamma_o, gamma_t = terms
    cdf = jnp.cumsum(_ap_pdf(a), axis=-1)
    p = jnp.sum(u[..., 0:1] >= cdf[..., :P_MAX], axis=-1)
    pick = jax.nn.one_hot(p, P_MAX + 1, dtype=v.dtype)
    vp, sp, cp = jnp.sum(v * pick, -1), jnp.sum(sin_p * pick, -1), jnp.sum(cos_p * pick, -1)
    u1, u2, u3 = u[..., 1], u[..., 2], u[..., 3]
    # cos of the angle from the cone's axis: 1 + v ln(u₁ + (1 − u₁) e^(−2/v)), summed in log space.
    log_arg = jnp.logaddexp(jnp.log(u1), jnp.log1p(-u1) - 2.0 / vp)
    cos_c = jnp.clip(1.0 + vp * log_arg, -1.0, 1.0)
    sin_i = jnp.clip(-cos_c * sp + _sqrt1m(cos_c) * jnp.cos(_TWO_PI * u2) * cp, -1.0, 1.0)
    cos_i = _sqrt1m(sin_i)
    lo = logistic_cdf(-math.pi, s)
    q = u3 * jnp.tanh(0.5 * math.pi / s) + lo
    x = jnp.clip(s * (jnp.log(q) - jnp.log1p(-q)), -math.pi, math.pi)
    centre = phi_centre(jnp.minimum(p, P_MAX - 1).astype(v.dtype), gamma_o, gamma_t)
    dphi = jnp.where(p < P_MAX, centre + x, _TWO_PI * u3)
    phi_i = phi_o + dphi
    wi = jnp.stack([sin_i, cos_i * jnp.cos(phi_i), cos_i * jnp.sin(phi_i)], axis=-1)
    m, n = _mn(sin_i, cos_i, dphi, sin_p, cos_p, v, s, gamma_o, gamma_t)
    pdf = jnp.sum(m * n * _ap_pdf(a), axis=-1)
    return wi, pdf, (m * n)[..., None, :] * a


# ----------------------------------------------------------------------------- validation and public API


def _array(value, field: str) -> np.ndarray:
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise ValidationError(field, value, f"not an array of numbers ({exc})") from None
    if arr.dtype == np.bool_ or not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise ValidationError(field, value, f"need real numbers, got dtype {arr.dtype}")
    return arr.astype(np.float64)


def check_values(value, field: str, lo=None, hi=None, *, lo_open=False) -> np.ndarray:
    """``value`` as a float64 array, every element finite and in [lo, hi] ((lo, hi] with ``lo_open``);
    otherwise a ValidationError naming ``field`` and the first bad element."""
    arr = _array(value, field)
    bad = ~np.isfinite(arr)
    if lo is not None:
        bad |= (arr <= lo) if lo_open else (arr < lo)
    if hi is not None:
        bad |= arr > hi
    if bad.any():
        k = tuple(int(i) for i in np.argwhere(bad)[0]) if arr.ndim else ()
        where = f" at index {k}" if k else ""
        if lo is not None and hi is not None:
            rng = f"must be finite and in {'(' if lo_open else '['}{lo:g}, {hi:g}]"
        elif lo is not None:
            rng = f"must be finite and {'>' if lo_open else '≥'} {lo:g}"
        else:
            rng = "must be finite"
        raise ValidationError(field, arr[k] if k else arr.item() if arr.ndim == 0 else value, rng + where)
    return arr


def check_roughness(value, field: str = "roughness") -> np.ndarray:
    """β in (0, 1] (float64 array)."""
    return check_values(value, field, 0.0, 1.0, lo_open=True)


def check_sigma_a(value, field: str = "sigma_a") -> np.ndarray:
    """σ_a finite and ≥ 0 (float64 array)."""
    return check_values(value, field, 0.0)


def check_colour(value, field: str = "colour") -> np.ndarray:
    """A hair colour in (0, 1] (0 would need σ_a = ∞)."""
    return check_values(value, field, 0.0, 1.0, lo_open=True)


def check_model(alpha, eta) -> tuple[float, float]:
    """(α in radians, η): α in degrees, finite, |α| ≤ 22.5 (so that 4α stays within a right angle); η finite and > 1."""
    a = check_values(alpha, "alpha", -22.5, 22.5)
    e = check_values(eta, "eta", 1.0, lo_open=True)
    if a.ndim or e.ndim:
        raise ValidationError("alpha" if a.ndim else "eta", alpha if a.ndim else eta, "must be a single number")
    return math.radians(float(a)), float(e)


def sigma_a_from_concentration(eumelanin, pheomelanin=0.0) -> np.ndarray:
    """σ_a (..., 3) RGB from melanin concentrations (pbrt's coefficients): ce·(0.419, 0.697, 1.37) +
    cp·(0.187, 0.4, 1.05).  Concentrations must be finite and ≥ 0."""
    ce = check_values(eumelanin, "eumelanin", 0.0)[..., None]
    cp = check_values(pheomelanin, "pheomelanin", 0.0)[..., None]
    return ce * np.asarray(EUMELANIN_SIGMA_A) + cp * np.asarray(PHEOMELANIN_SIGMA_A)


def sigma_a_from_colour(colour, beta_n) -> np.ndarray:
    """σ_a from a hair colour C ∈ (0, 1] (any shape, per channel) and the azimuthal roughness β_n ∈ (0, 1]
    [Chiang eq. 9]: the absorption whose multiple-scattering albedo is C."""
    c = check_colour(colour)
    b = check_roughness(beta_n, "beta_n")
    return colour_to_sigma_a(c, b)


def colour_from_sigma_a(sigma_a, beta_n) -> np.ndarray:
    """The inverse of :func:`sigma_a_from_colour`: C = exp(−√σ_a · D(β_n))."""
    return sigma_a_to_colour(check_sigma_a(sigma_a), check_roughness(beta_n, "beta_n"))


def _inputs(wo, wi, h, sigma_a, beta_m, beta_n, alpha, eta, *, wi_field="wi"):
    from ..validate import directions

    wo = directions(wo, "wo")
    wi = directions(wi, wi_field) if wi is not None else None
    h = check_values(h, "h", -1.0, 1.0)
    sa = check_sigma_a(sigma_a)
    sa = sa.reshape(1) if sa.ndim == 0 else sa
    bm = check_roughness(beta_m, "beta_m")
    bn = check_roughness(beta_n, "beta_n")
    a, e = check_model(alpha, eta)
    return wo, wi, h, sa, bm, bn, a, e


def _run(kernel, *args):
    with jax.enable_x64(True):
        out = kernel(*(jnp.asarray(x, jnp.float64) for x in args))
        return jax.tree_util.tree_map(np.asarray, out)


def lobes(wo, wi, h, sigma_a, beta_m, beta_n, *, alpha=ALPHA, eta=ETA) -> np.ndarray:
    """The terms M_p A_p N_p (..., C, 4), p = R, TT, TRT, residual: the BSDF times pbrt's |cos_z ωi|.

    ``wo``, ``wi`` (..., 3) are directions in the hair frame (normalised here), ``h`` ∈ [−1, 1], ``sigma_a``
    (..., C) (a scalar is one channel), ``beta_m``, ``beta_n`` ∈ (0, 1], ``alpha`` in degrees, ``eta`` > 1;
    everything broadcasts.  Bad values raise ValidationError naming the argument."""
    wo, wi, h, sa, bm, bn, a, e = _inputs(wo, wi, h, sigma_a, beta_m, beta_n, alpha, eta)
    return _run(lobes_kernel, wo, wi, h, sa, bm, bn, a, e)


def f(wo, wi, h, sigma_a, beta_m, beta_n, *, alpha=ALPHA, eta=ETA) -> np.ndarray:
    """pbrt's f(ωo, ωi) (..., C): Σ_p M_p A_p N_p / |w_i,z| (not divided where w_i,z = 0, as pbrt)."""
    wo_, wi_, *_ = _inputs(wo, wi, h, sigma_a, beta_m, beta_n, alpha, eta)
    total = lobes(wo_, wi_, h, sigma_a, beta_m, beta_n, alpha=alpha, eta=eta).sum(axis=-1)
    z = np.abs(wi_[..., 2])[..., None]
    return np.where(z > 0, total / np.where(z > 0, z, 1.0), total)


def pdf(wo, wi, h, sigma_a, beta_m, beta_n, *, alpha=ALPHA, eta=ETA) -> np.ndarray:
    """The density (per unit solid angle) with which :func:`sample` returns ``wi`` (...)."""
    wo, wi, h, sa, bm, bn, a, e = _inputs(wo, wi, h, sigma_a, beta_m, beta_n, alpha, eta)
    return _run(pdf_kernel, wo, wi, h, sa, bm, bn, a, e)


def sample(wo, u, h, sigma_a, beta_m, beta_n, *, alpha=ALPHA, eta=ETA):
    """Sample ωi given ωo from four uniforms ``u`` (..., 4) in [0, 1) (:func:`sample_kernel`).

    Returns (wi (..., 3), pdf (...), lobes (..., C, 4)); the estimator of the albedo is
    lobes.sum(-1) / pdf, which is 1 exactly for every sample when σ_a = 0."""
    wo, _, h, sa, bm, bn, a, e = _inputs(wo, None, h, sigma_a, beta_m, beta_n, alpha, eta)
    u = check_values(u, "u", 0.0, 1.0)
    if u.ndim < 1 or u.shape[-1] != 4:
        raise ValidationError("u", u.shape, "need uniforms of shape (..., 4)")
    u = np.minimum(u, np.nextafter(1.0, 0.0))
    return _run(sample_kernel, wo, u, h, sa, bm, bn, a, e)
