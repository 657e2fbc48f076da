"""The Kajiya–Kay lobes, the one definition every caller evaluates (xing §4; satf eqs 9–11).

DESIGN.md's convention: θ = angle(ω, t) and θ′ = angle(t, v), both in [0, π], with ω
toward the light and v toward the viewer.

- Diffuse: sin θ.
- Specular: max(0, cos(π − θ − θ′))^p, which peaks on the mirror cone θ + θ′ = π.

Three spellings of the same two lobes, for the three ways callers hold the angles:

- :func:`diffuse`, :func:`specular` take the angles θ, θ′ (the SH tables' quadratures);
- :func:`specular_offset` takes ψ = θ + θ′ − π/2, where the specular lobe is sin(ψ)^p on
  ψ ∈ [0, π] (the zonal Legendre coefficients integrate over ψ, exact near the clamps);
- :func:`diffuse_cos`, :func:`specular_cos` take the cosines c = t·ω, c′ = t·v of unit
  vectors and, where the caller holds the vectors, their sines |t × ω|, |t × v|
  (:func:`sin_between`): sin θ sin θ′ − cos θ cos θ′ = cos(π − θ − θ′) (the online
  shading of eqs 9–11, whose shifted tangent t̃ is the caller's business).

Near |c| = 1 a sine from the cosine, √(1 − c²), is ill-conditioned: a rounding δ of c (the dot
product's, ~1e-16 in float64, ~6e-8 in float32) moves it by √(2δ) (1.5e-8, 3.5e-4), and at the
lobe's edge θ + θ′ = π/2, where the base cos(π − θ − θ′) is that small, a fractional p turns it
into a large relative error (issue 29 m16: t ∥ ω, p = 0.5, 16 %).  The cross product's norm has
no such loss (it is a difference of products of the components, not of two numbers near 1), so
callers with vectors pass it; from a cosine alone the sine is √((1 − c)(1 + c)) (no rounding of
c² on top of c's own).

Every function works on NumPy arrays (computing in NumPy) and on JAX arrays or tracers
(computing in ``jax.numpy``): the module picks the array library from the arguments.
The clamp comes before the power, so a fractional p never meets a negative base.
"""

from __future__ import annotations

import math

import numpy as np

from . import errors


def _xp(*args):
    """jax.numpy when any argument is a JAX array or tracer, else NumPy."""
    for a in args:
        if type(a).__module__.split(".")[0] in ("jax", "jaxlib"):
            import jax.numpy as jnp

            return jnp
    return np


def diffuse(theta):
    """Kajiya–Kay diffuse lobe sin θ (clamped at 0 outside [0, π])."""
    xp = _xp(theta)
    return xp.maximum(xp.sin(theta), 0.0)


def specular(theta, theta_v, p):
    """Kajiya–Kay specular lobe max(0, cos(π − θ − θ′))^p, written max(0, −cos(θ + θ′))^p."""
    xp = _xp(theta, theta_v, p)
    return xp.maximum(-xp.cos(theta + theta_v), 0.0) ** p


def specular_offset(psi, p):
    """The specular lobe in ψ = θ + θ′ − π/2: sin(ψ)^p where sin ψ > 0, else 0.

    Equal to :func:`specular` (cos(π − θ − θ′) = sin ψ), but accurate to the last bit near
    the clamps ψ = 0, π, where −cos(θ + θ′) loses digits."""
    xp = _xp(psi, p)
    s = xp.sin(psi)
    return xp.where(s > 0, xp.abs(s) ** p, 0.0)


def _sin(cos, xp):
    return xp.sqrt(xp.clip((1.0 - cos) * (1.0 + cos), 0.0, 1.0))


def sin_between(a, b):
    """sin of the angle between unit vectors ``a`` (..., 3) and ``b`` (..., 3) (broadcast): |a × b|, accurate where
    they are nearly parallel or opposite (module docstring)."""
    xp = _xp(a, b)
    x = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    y = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    z = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return xp.minimum(xp.sqrt(x * x + y * y + z * z), 1.0)


def diffuse_cos(cos_l, sin_l=None):
    """The diffuse lobe from c = t·ω (unit vectors): sin θ, ``sin_l`` (|t × ω|) when given, else √((1 − c)(1 + c))."""
    return _sin(cos_l, _xp(cos_l)) if sin_l is None else sin_l


def specular_cos(cos_l, cos_v, p, sin_l=None, sin_v=None):
    """The specular lobe from c = t·ω and c′ = t·v (unit vectors):
    max(0, sin θ sin θ′ − cos θ cos θ′)^p = max(0, cos(π − θ − θ′))^p.  The sines ``sin_l`` = |t × ω| and
    ``sin_v`` = |t × v| when given (accurate near |c| = 1, module docstring), else from the cosines."""
    xp = _xp(cos_l, cos_v, p)
    sl = _sin(cos_l, xp) if sin_l is None else sin_l
    sv = _sin(cos_v, xp) if sin_v is None else sin_v
    return xp.maximum(0.0, sl * sv - cos_l * cos_v) ** p


def exponent_reason(p) -> str | None:
    """Why ``p`` is not a specular exponent (finite and > 0), or None: a recipe Field check."""
    if isinstance(p, bool) or not isinstance(p, (int, float, np.integer, np.floating)):
        return "the specular exponent is a number"
    if not math.isfinite(p) or p <= 0:
        return "the specular exponent p must be finite and > 0"
    return None


def check_exponent(p, field: str = "p") -> float:
    """Validate a specular exponent: finite and > 0 (ValidationError naming ``field``)."""
    if reason := exponent_reason(p):
        raise errors.ValidationError(field, p, reason)
    return float(p)
