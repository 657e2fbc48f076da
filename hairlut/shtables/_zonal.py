"""Legendre coefficients of the Kajiya–Kay kernels, which are zonal around t.

For fixed θ′ both kernels depend on ω only through c = cos θ = ω·t, so
(xing eq. 3; Funk–Hecke)

    f(ω·t) = Σ_l k_l Σ_m Y_lm(t) Y_lm(ω),    k_l = 2π ∫₀^π f(θ) P_l(cos θ) sin θ dθ.

Diffuse: f = sin θ = √(1−c²), and k_l = 2π ∫ √(1−c²) P_l(c) dc is exact with
Gauss–Chebyshev quadrature of the second kind.

Specular: with a = π/2 − θ′ and ψ = θ − a, the clamped kernel
max(0, cos(π − θ − θ′))^p is sin(ψ)^p on ψ ∈ [0, π] and zero elsewhere.  The
integral runs over ψ ∈ [max(0, −a), min(π, π − a)], split at the peak ψ = π/2,
with each half graded toward its outer end (s ↦ s^q) so that the algebraic
endpoint behaviour ψ^p of a fractional p costs no accuracy.

As a function of θ′, k_l is analytic on [0, π/2] and on [π/2, π] (for integer
p; C^{p} at θ′ = π/2 otherwise), so it is stored as Chebyshev–Lobatto samples on
each half and evaluated anywhere by its Chebyshev series (Clenshaw).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ..kernels import specular_offset

HIGHEST = jax.lax.Precision.HIGHEST  # stated, not inherited: XLA would use TF32 on NVIDIA GPUs

GRADING = 3  # s ↦ s**GRADING near the outer ends of the specular integral


def legendre_p(lmax: int, c):
    """P_0..P_lmax at c (..., ) → (..., lmax+1), by the three-term recurrence (stable for |c| ≤ 1)."""
    out = [jnp.ones_like(c), c]
    for l in range(1, lmax):
        out.append(((2 * l + 1) * c * out[l] - l * out[l - 1]) / (l + 1))
    return jnp.stack(out[: lmax + 1], axis=-1)


EIGEN_NODES = 128  # above this, Newton on the recurrence: O(n²) instead of the companion matrix's O(n³)


@functools.cache
def gauss_legendre_01(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(n) if n <= EIGEN_NODES else gauss_legendre_newton(n)
    return 0.5 * (x + 1.0), 0.5 * w


def gauss_legendre_newton(n: int, iterations: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes and weights on [−1, 1] by Newton's method on P_n, from Tricomi's
    asymptotic first guess x_k ≈ (1 − (n − 1)/(8n³)) cos(π(4k − 1)/(4n + 2)).

    P_n and P_n' come from the three-term recurrence, vectorised over the positive half of the
    nodes (the rule is symmetric); w_k = 2 / ((1 − x_k²) P_n'(x_k)²), scaled so that Σ w = 2. At n = 8,500 (exponent
    p = 2·10⁶) this takes about a second where the companion matrix's eigenvalues take minutes.
    """
    k = np.arange(1, n // 2 + 1 + n % 2)
    x = (1.0 - (n - 1) / (8.0 * n**3)) * np.cos(np.pi * (4 * k - 1) / (4 * n + 2))
    for _ in range(iterations):
        p_prev, p_n = np.ones_like(x), x.copy()
        for l in range(1, n):
            p_prev, p_n = p_n, ((2 * l + 1) * x * p_n - l * p_prev) / (l + 1)
        dp = n * (x * p_n - p_prev) / (x * x - 1.0)
        step = p_n / dp
        x = x - step
        if np.max(np.abs(step)) < 1e-15:
            break
    p_prev, p_n = np.ones_like(x), x.copy()
    for l in range(1, n):
        p_prev, p_n = p_n, ((2 * l + 1) * x * p_n - l * p_prev) / (l + 1)
    dp = n * (x * p_n - p_prev) / (x * x - 1.0)
    w = 2.0 / ((1.0 - x * x) * dp * dp)
    w *= 2.0 / (2.0 * w.sum() - (w[-1] if n % 2 else 0.0))  # Σ w = 2 exactly, as leggauss also normalises
    if n % 2:  # the middle node x = 0 is its own mirror
        x[-1] = 0.0
        return np.concatenate([-x, x[-2::-1]]), np.concatenate([w, w[-2::-1]])
    return np.concatenate([-x, x[::-1]]), np.concatenate([w, w[::-1]])


def diffuse_nodes(lmax: int) -> int:
    """Gauss–Chebyshev (2nd kind) points that integrate √(1−c²) P_l(c), l ≤ lmax, exactly."""
    return lmax // 2 + 2


def specular_nodes(lmax: int, p: float) -> int:
    """Gauss–Legendre points per half of the specular integral (checked against 4× as many in the tests)."""
    return int(48 + 3 * lmax + 6 * np.ceil(np.sqrt(p)))


def diffuse_coeffs(lmax: int, n: int):
    """k_l of sin θ (:func:`hairlut.kernels.diffuse`) for l = 0..lmax (odd l vanish), as a jnp array.

    k_l = 2π ∫₋₁¹ √(1−c²) P_l(c) dc, and Gauss–Chebyshev quadrature of the
    second kind (weight √(1−c²)) with n points is exact for degree ≤ 2n − 1: the lobe is
    the quadrature's weight function, so it is never evaluated at the nodes.
    """
    k = np.arange(1, n + 1)
    c = jnp.asarray(np.cos(k * np.pi / (n + 1)))
    w = jnp.asarray(np.pi / (n + 1) * np.sin(k * np.pi / (n + 1)) ** 2)
    return 2 * jnp.pi * jnp.einsum("q,ql->l", w, legendre_p(lmax, c), precision=HIGHEST)


def specular_coeffs(lmax: int, n: int, p, theta_v):
    """k_l(θ′) of max(0, cos(π − θ − θ′))^p (:func:`hairlut.kernels.specular_offset` in ψ = θ + θ′ − π/2)
    for θ′ of shape (...,) → (..., lmax+1)."""
    s, w = gauss_legendre_01(n)
    s, w = jnp.asarray(s), jnp.asarray(w)
    a = jnp.pi / 2 - jnp.asarray(theta_v)[..., None]
    lo = jnp.maximum(0.0, -a)
    hi = jnp.minimum(jnp.pi, jnp.pi - a)
    g = s**GRADING
    dg = GRADING * s ** (GRADING - 1) * w
    half = jnp.pi / 2
    psi = jnp.concatenate([lo + (half - lo) * g, hi - (hi - half) * g], axis=-1)
    jac = jnp.concatenate([(half - lo) * dg, (hi - half) * dg], axis=-1)
    theta = jnp.clip(psi + a, 0.0, jnp.pi)
    f = jac * specular_offset(psi, p) * jnp.sin(theta)
    return 2 * jnp.pi * jnp.einsum("...q,...ql->...l", f, legendre_p(lmax, jnp.cos(theta)), precision=HIGHEST)


# ----------------------------------------------------------------------------- Chebyshev in θ′

HALVES = ((0.0, np.pi / 2), (np.pi / 2, np.pi))


def lobatto_nodes(n: int) -> np.ndarray:
    """θ′ at the Chebyshev–Lobatto points of both halves: shape (2, n+1), ascending."""
    x = -np.cos(np.pi * np.arange(n + 1) / n)  # −1 … 1
    return np.stack([lo + (hi - lo) * (x + 1) / 2 for lo, hi in HALVES])


def cheb_coeffs(values: np.ndarray) -> np.ndarray:
    """Chebyshev coefficients from values at ascending Lobatto nodes (axis −2 holds the n+1 nodes)."""
    v = np.asarray(values, dtype=np.float64)[..., ::-1, :]  # nodes cos(πj/n), j = 0..n
    n = v.shape[-2] - 1
    j = np.arange(n + 1)
    cos = np.cos(np.pi * np.outer(j, j) / n)
    wj = np.ones(n + 1)
    wj[[0, n]] = 0.5
    c = (2.0 / n) * np.einsum("kj,...jl->...kl", cos * wj, v)
    c[..., [0, n], :] *= 0.5
    return c


def cheb_eval(coeffs, theta_v):
    """Evaluate per-half Chebyshev series (2, n+1, L) at θ′ (...,) → (..., L).

    T_k(x) comes from the three-term recurrence (one vector per node count, not
    per l); the series is then two small matrix products, one per half.
    """
    theta_v = jnp.asarray(theta_v)
    upper = theta_v > np.pi / 2
    x = jnp.where(upper, theta_v - np.pi / 2, theta_v) * (4 / np.pi) - 1.0
    n = coeffs.shape[1] - 1
    cols = [jnp.ones_like(x), x]
    for _ in range(2, n + 1):
        cols.append(2 * x * cols[-1] - cols[-2])
    basis = jnp.stack(cols[: n + 1], axis=-1)  # (..., n+1)
    hi, lo = jnp.matmul(basis, coeffs[1], precision=HIGHEST), jnp.matmul(basis, coeffs[0], precision=HIGHEST)
    return jnp.where(upper[..., None], hi, lo)
