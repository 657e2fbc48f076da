"""The coverage table, one radius row at a time: the expected covered fraction of a pixel, q in closed form.

The third of the hair tables (:data:`._axes.TABLES`), beside the BSDF tables of :mod:`._energy` (Chiang et al.
2016's fibre, Zinke et al. 2008's dual scattering); Unreal Engine's ``HairStrandsLUT`` bakes it by Monte Carlo.
It involves no BSDF: its measure is geometric.

**coverage** (n_radius, n_count): the expected fraction of a unit pixel covered by N strands of radius r
pixels.  The measure: each strand is an infinite straight band of half-width r whose centre line passes
through a uniformly random point P of the pixel, with a uniformly random orientation θ ∈ [0, π), the
strands independent.  A point x of the pixel is then covered by one strand with probability
q(x) = ∫_pixel K(|P − x|) dP, K(ρ) = 1 (ρ ≤ r) or (2/π) asin(r/ρ) (ρ > r) (the fraction of orientations
whose line passes within r of x), and the expected coverage is 1 − ∫_pixel (1 − q(x))^N dx.  N may be any
real ≥ 0.

**How** (the value is the rule with ``coverage_nodes`` = m Gauss–Legendre nodes per panel, its error estimate
|Q_m − Q_{m/2}|, the difference from the rule with m/2 on the same panels):

- q(x) is in closed form (no quadrature): in polar coordinates about x the radial integral is exact
  (∫_0^R K(ρ) ρ dρ = R²/2 or (R² asin(r/R) + r √(R² − r²))/π), and the angular one, taken edge by edge in the
  offset t along the edge (dω = d dt/ρ²), has an elementary primitive (:func:`_edge_term`).  So q is exact to
  rounding, and the only quadrature is the outer one, 1 − ∫ (1 − q)^N dx, whose points (and q there) serve
  every N of a row at once: Gauss–Legendre panels over a quarter of the pixel (the square's symmetry), split
  where x is r from an edge; the circles of radius r about the corners are not split (q is twice
  differentiable across them), so that rule converges algebraically, about 40× per doubling of the nodes.
  Its estimate |Q_m − Q_{m/2}| is per entry; where that difference changes sign along N it can fall below the
  entry's true error (measured: by up to 10×, on 6 of 4096 entries, whose error is ≤ 1.0e-9, against the
  table's largest estimate 4.6e-6).

Measured on the 2-core development machine, shared (load average 5–8), default axes and resolutions:

- coverage, 64 × 64, ``coverage_nodes`` = 16: 0.09–0.13 s wall; against 64 nodes ≤ 1.1e-7 (the corner arcs
  make its convergence algebraic); the stored estimates ≤ 4.6e-6, below the true error on 6 of the 4096 entries
  (those ≤ 1.0e-9).  The single-strand coverage (N = 1) is within 8e-9 of its closed form.
  Compiling :func:`coverage_row_kernel` takes ~0.5 s wall once per process.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp

from ._quadrature import _HALF_PI, _panels

# ----------------------------------------------------------------------------- coverage, one row


def _edge_term(s, d, r):
    """d · J(s) for offsets s ≥ 0 along one pixel edge at distance d > 0 from x: π times that edge piece's share
    of q(x) (module docstring, *coverage*).

    The rays from x that leave the pixel through an edge at distance d meet it at offset t from the foot of
    the perpendicular, at distance ρ = √(d² + t²), and dω = d dt / ρ², so their share of q is
    (d/π) ∫ F(ρ) dt with F = π H(ρ)/ρ² = asin(min(1, r/ρ)) + r √(max(ρ² − r², 0)) / ρ².  F = π/2 while ρ ≤ r;
    beyond, integrating asin(r/ρ) by parts leaves r(2t² + d² − r²)/(ρ² w), w = √(t² + d² − r²), which is
    2r/w − r(d² + r²)/(ρ² w), each with an elementary primitive (ln(t + w) and an inverse hyperbolic tangent
    that, written as a logarithm, is ln((rt + dw)/(cρ)), c = √|d² − r²|).  With the constant chosen so that J
    is continuous at ρ = r (d < r) and J(0) = 0 (d ≥ r):

        J(s) = (π/2) s                                                         (s² + d² ≤ r²)
        J(s) = s asin(r/ρ) + 2r ln(s + w) − ((d² + r²)/d) ln((rs + dw)/ρ) + ((d − r)²/d) ln c   (otherwise)

    The ln c terms of the two logarithms are collected into the last one, whose weight (d − r)² vanishes where
    c does (an edge at distance r), so the form stays accurate there; multiplied through by d it has no
    division by d either.  F = π/2 − O((ρ − r)^{3/2}) at ρ = r, so q is twice differentiable across the circles
    of radius r about the corners."""
    w2 = s * s + d * d - r * r
    near = w2 <= 0.0
    w = jnp.sqrt(jnp.where(near, 1.0, w2))
    ss = jnp.where(near, 1.0, s)
    rho = jnp.sqrt(ss * ss + d * d)
    c = jnp.sqrt(jnp.maximum(jnp.abs((d - r) * (d + r)), 1e-300))
    far = (
        d * ss * jnp.arcsin(jnp.minimum(r / rho, 1.0))
        + 2.0 * r * d * jnp.log(ss + w)
        - (d * d + r * r) * jnp.log((r * ss + d * w) / rho)
        + (d - r) ** 2 * jnp.log(c)
    )
    return jnp.where(near, _HALF_PI * d * s, far)


def _coverage_q(x1, x2, r):
    """q(x) at points (x1, x2) (n,) of the centred pixel [−½, ½]², in closed form: the sum over the four edges of
    (d/π)(J(t_b) − J(t_a)) (:func:`_edge_term`; J is odd, the edge runs over offsets [t_a, t_b]), the eight ends
    evaluated as one (8, n) array."""
    d = jnp.stack([0.5 - x1, 0.5 - x2, 0.5 + x1, 0.5 + x2])  # right, top, left, bottom
    u = jnp.stack([x2, x1, x2, x1])  # the offset of x's foot point along each edge
    t = jnp.concatenate([0.5 - u, -0.5 - u])  # (8, n): each edge's two ends
    sign = jnp.asarray([1.0] * 4 + [-1.0] * 4)[:, None]
    return jnp.sum(sign * jnp.sign(t) * _edge_term(jnp.abs(t), jnp.concatenate([d, d]), r), axis=0) / math.pi


def _coverage_rules(r, counts, rules: tuple[int, ...]):
    """[1 − ∫ (1 − q)^N dx for N = counts (C,), for each rule of ``rules``]: m-point Gauss–Legendre panels over a
    quarter of the pixel (the square's symmetry), split where x is r from an edge (where q is not smooth); q is
    evaluated once on every rule's points."""
    edges = jnp.sort(jnp.clip(jnp.stack([0.0 * r, 0.5 - r, r - 0.5, 0.5 + 0.0 * r]), 0.0, 0.5))
    pts, wts, bounds, at = [], [], [], 0
    for m in rules:
        x, w = _panels(edges, m)
        x1, x2 = jnp.meshgrid(x, x, indexing="ij")
        pts.append((x1.reshape(-1), x2.reshape(-1)))
        wts.append((w[:, None] * w[None, :]).reshape(-1))
        bounds.append((at, at + wts[-1].shape[0]))
        at += wts[-1].shape[0]
    q = _coverage_q(jnp.concatenate([a for a, _ in pts]), jnp.concatenate([b for _, b in pts]), r)
    log_miss = jnp.log1p(-jnp.clip(q, 0.0, 1.0))
    out = []
    for wx, (i0, i1) in zip(wts, bounds):
        miss = jnp.where(counts[:, None] > 0.0, jnp.exp(counts[:, None] * log_miss[None, i0:i1]), 1.0)
        out.append(1.0 - 4.0 * jnp.sum(wx * miss, axis=-1))
    return out


@functools.partial(jax.jit, static_argnames=("m",))
def coverage_row_kernel(r, counts, *, m):
    """Coverage (float64) for one radius r () and strand counts (C,) → (values (C,), error estimates (C,)): the
    m-node rule and its distance from the m/2-node rule on the same panels (q itself is exact)."""
    hi, lo = _coverage_rules(r, counts, (m, m // 2))
    return hi, jnp.abs(hi - lo)
