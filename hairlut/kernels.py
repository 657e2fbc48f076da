"""Kajiya–Kay scattering kernels (xing §4; DESIGN.md conventions).

θ = angle(ω, t) and θ′ = angle(t, v), both in [0, π], with ω toward the light
and v toward the viewer.  Diffuse: sin θ.  Specular: max(0, cos(π − θ − θ′))^p,
which peaks on the mirror cone θ + θ′ = π.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from . import errors


def diffuse(theta):
    """Kajiya–Kay diffuse kernel sin θ (clamped at 0 outside [0, π])."""
    return jnp.maximum(jnp.sin(theta), 0.0)


def specular(theta, theta_v, p):
    """Kajiya–Kay specular kernel max(0, cos(π − θ − θ′))^p.

    Written as max(0, −cos(θ + θ′))^p so that the clamp comes before the power:
    a negative base never reaches ``pow`` (no NaN for fractional p).
    """
    base = jnp.maximum(-jnp.cos(theta + theta_v), 0.0)
    return base**p


def check_exponent(p, field: str = "p") -> float:
    """Validate a specular exponent: finite and > 0."""
    try:
        value = float(p)
    except (TypeError, ValueError):
        raise errors.ValidationError(field, p, "the specular exponent is a number") from None
    if not np.isfinite(value) or value <= 0:
        raise errors.ValidationError(field, p, "the specular exponent must be finite and > 0")
    return value
