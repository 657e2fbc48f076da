"""Reading a scene table online: every sector's α and re rows at its exact θv and θl (the ``scene`` map method).

For sector s with table row r (−1: empty, α = re = 0) and view θv: f = θv V / 2π, views
i₀ = ⌊f⌋ mod V and i₁ = i₀ + 1 mod V, weight w = f − ⌊f⌋ (periodic linear interpolation, as an SATF
row's angle interpolation).  α(p) = (1 − w) α_{i₀}(p) + w α_{i₁}(p), where a view i ≥ V/2 reads the
stored view i − V/2 at pixel P − 1 − p (the mirror symmetry).  The ratio's terms are interpolated
the same way and evaluated at each light's Δ = θl − θv: ρ_l(q) = c₀ + Σ_k a_k cos kΔ + b_k sin kΔ;
re_l(p) = α(p) ρ_l(q(p)), q(p) = ⌊p Q / P⌋.  One jitted kernel, float32 arithmetic (the contraction
over the terms at HIGHEST precision), empty sectors masked to exactly 0.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors

HIGHEST = jax.lax.Precision.HIGHEST


@partial(jax.jit, static_argnames=("shade",))
def fetch_kernel(alpha_t, ratio_t, row, theta_v, theta_l, *, shade: bool = True):
    """α (S, P) and re (S, L, P) of S sectors from a scene table's ``alpha_t`` (N, V/2, P) and
    ``ratio_t`` (N, V, Q, T) (any float dtype), ``row`` (S,) int32, ``theta_v`` (S,), ``theta_l`` (S, L)."""
    n, half, P = alpha_t.shape
    V, Q, T = ratio_t.shape[1:]
    K = (T - 1) // 2
    live = row >= 0
    r = jnp.where(live, row, 0)
    f = jnp.mod(theta_v, 2 * jnp.pi) * (V / (2 * jnp.pi))
    i0f = jnp.floor(f)
    w = (f - i0f)[:, None]
    i0 = jnp.mod(i0f.astype(jnp.int32), V)
    i1 = jnp.mod(i0 + 1, V)
    p = jnp.arange(P)

    def alpha_at(i):
        flip = (i >= half)[:, None]
        return alpha_t[r[:, None], jnp.mod(i, half)[:, None], jnp.where(flip, P - 1 - p, p)].astype(jnp.float32)

    alpha = jnp.where(live[:, None], (1 - w) * alpha_at(i0) + w * alpha_at(i1), 0.0)
    if not shade:
        return alpha, jnp.zeros((alpha.shape[0], 0, P), jnp.float32)
    c = (1 - w[..., None]) * ratio_t[r, i0].astype(jnp.float32) + w[..., None] * ratio_t[r, i1].astype(jnp.float32)
    d = theta_l - theta_v[:, None]  # (S, L)
    k = jnp.arange(1, K + 1, dtype=jnp.float32)
    kd = d[..., None] * k  # (S, L, K)
    basis = jnp.concatenate([jnp.ones_like(d)[..., None], jnp.stack([jnp.cos(kd), jnp.sin(kd)], -1).reshape(
        *d.shape, 2 * K)], -1)  # (S, L, T)
    ratio = jnp.einsum("sqt,slt->slq", c, basis, precision=HIGHEST)
    re = alpha[:, None, :] * jnp.repeat(ratio, P // Q, axis=-1)
    return alpha, re


def fetch_rows(maps, row, theta_v, theta_l) -> tuple[np.ndarray, np.ndarray]:
    """α (S, P) and re (S, L, P) (NumPy) of the scene sectors ``row`` indexes, at ``theta_v`` (S,) and
    ``theta_l`` (S, L) (module docstring); ``maps`` a :class:`~hairlut.scenemaps.SceneMaps`."""
    tv, tl = np.asarray(theta_v, np.float64), np.asarray(theta_l, np.float64)
    rw = np.asarray(row)
    if tv.ndim != 1 or tl.ndim != 2 or tl.shape[0] != tv.shape[0] or rw.shape != tv.shape:
        raise errors.ValidationError("theta_l", tl.shape, f"need theta_v (S,), theta_l (S, L), row (S,); got {tv.shape}, "
                                     f"{tl.shape}, {rw.shape}")
    if not (np.isfinite(tv).all() and np.isfinite(tl).all()):
        raise errors.ValidationError("theta_v", "non-finite", "angles must be finite")
    a, r = fetch_kernel(jnp.asarray(maps.alpha), jnp.asarray(maps.ratio), jnp.asarray(rw, jnp.int32),
                        jnp.asarray(np.mod(tv, 2 * np.pi), jnp.float32),
                        jnp.asarray(np.mod(tl, 2 * np.pi) if tl.shape[1] else np.zeros((len(tv), 1)), jnp.float32),
                        shade=tl.shape[1] > 0)
    a, r = np.asarray(a), np.asarray(r)
    if not (np.isfinite(a).all() and np.isfinite(r).all()):
        raise errors.HairlutError("scene_maps fetch: non-finite maps")
    return a, r
