"""Kajiya–Kay scattering kernels (xing §4; DESIGN.md conventions).

θ = angle(ω, t) and θ′ = angle(t, v), both in [0, π], with ω toward the light
and v toward the viewer.  Diffuse: sin θ.  Specular: max(0, cos(π − θ − θ′))^p,
which peaks on the mirror cone θ + θ′ = π.
"""

from __future__ import annotations

import jax
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


@jax.jit
def _lobes(theta, theta_v, exponents):
    t = theta[:, None]
    v = theta_v[None, :]
    spec = jax.vmap(lambda p: specular(t, v, p))(exponents)
    return diffuse(theta), spec


def sample_lobes(n_theta: int, n_theta_v: int, exponents) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sample both kernels on uniform grids over [0, π] (float64).

    Returns (theta, theta_v, diffuse[θ], specular[p, θ, θ′]).
    """
    for name, n in (("n_theta", n_theta), ("n_theta_v", n_theta_v)):
        if not isinstance(n, (int, np.integer)) or n < 2:
            raise errors.ValidationError(name, n, "need an integer ≥ 2")
    ps = np.array([check_exponent(p, f"exponents[{i}]") for i, p in enumerate(exponents)], dtype=np.float64)
    if ps.size == 0:
        raise errors.ValidationError("exponents", list(exponents), "give at least one exponent")
    with jax.enable_x64(True):
        theta = np.linspace(0.0, np.pi, n_theta)
        theta_v = np.linspace(0.0, np.pi, n_theta_v)
        d, s = _lobes(jnp.asarray(theta), jnp.asarray(theta_v), jnp.asarray(ps))
        return theta, theta_v, np.asarray(d), np.asarray(s)
