"""Reading a scene table online: every sector's α and re rows at its exact θv and θl (the ``scene`` map method).

For sector s with table row r (−1: empty, α = re = 0) and view θv: f = θv V / 2π, views
i₀ = ⌊f⌋ mod V and i₁ = i₀ + 1 mod V, weight w = f − ⌊f⌋ (periodic linear interpolation, as an SATF
row's angle interpolation).  α(p) = (1 − w) α_{i₀}(p) + w α_{i₁}(p), where a view i ≥ V/2 reads the
stored view i − V/2 at pixel P − 1 − p (the mirror symmetry).  The ratio's terms are interpolated
the same way on their own grid of V_r = V / ratio_step views and evaluated at each light's Δ = θl − θv: ρ_l(q) = c₀ + Σ_k a_k cos kΔ + b_k sin kΔ;
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


def fetch_terms(alpha_t, ratio_t, row, theta_v, theta_l, *, shade: bool = True):
    """α (S, P) and the re/α ratio per light and bin, ρ (S, L, Q), of S sectors (module docstring):
    re_l(p) = α(p) ρ_l(⌊p Q / P⌋).  Traceable (no jit of its own): :func:`fetch_kernel` and the
    scene method's frame kernel (``hairlut.synth``) inline it.  Arguments as :func:`fetch_kernel`.

    Every read is a whole contiguous row (P pixels of α; the Q·T terms of one view): the tables are
    viewed as 2-D (N·V/2, P) and (N·V, Q·T) and indexed by row, so XLA gathers slices rather than one
    index tuple per element (several times cheaper on the CPU than the (N, V, Q, T) element gather),
    and a mirror view is its stored row reversed.  Narrow storage is converted after the gather."""
    n, half, P = alpha_t.shape
    Vr, Q, T = ratio_t.shape[1:]
    K = (T - 1) // 2
    live = row >= 0
    r = jnp.where(live, row, 0)

    def grid(V):  # views i0, i1 = i0 + 1 (mod V) and weight w of θv on the grid 2πi/V
        f = jnp.mod(theta_v, 2 * jnp.pi) * (V / (2 * jnp.pi))
        i0f = jnp.floor(f)
        i0 = jnp.mod(i0f.astype(jnp.int32), V)
        return i0, jnp.mod(i0 + 1, V), (f - i0f)[:, None]

    i0, i1, w = grid(2 * half)
    rows_a = alpha_t.reshape(n * half, P)

    def alpha_at(i):
        a = jnp.take(rows_a, r * half + jnp.mod(i, half), axis=0, mode="clip").astype(jnp.float32)
        return jnp.where((i >= half)[:, None], a[:, ::-1], a)

    alpha = jnp.where(live[:, None], (1 - w) * alpha_at(i0) + w * alpha_at(i1), 0.0)
    if not shade:
        return alpha, jnp.zeros((alpha.shape[0], 0, Q), jnp.float32)
    rows_c = ratio_t.reshape(n * Vr, Q * T)
    j0, j1, u = grid(Vr)

    def terms_at(i):
        return jnp.take(rows_c, r * Vr + i, axis=0, mode="clip").astype(jnp.float32)

    c = ((1 - u) * terms_at(j0) + u * terms_at(j1)).reshape(-1, Q, T)
    d = theta_l - theta_v[:, None]  # (S, L)
    k = jnp.arange(1, K + 1, dtype=jnp.float32)
    kd = d[..., None] * k  # (S, L, K)
    basis = jnp.concatenate([jnp.ones_like(d)[..., None], jnp.stack([jnp.cos(kd), jnp.sin(kd)], -1).reshape(
        *d.shape, 2 * K)], -1)  # (S, L, T)
    return alpha, jnp.einsum("sqt,slt->slq", c, basis, precision=HIGHEST)


@partial(jax.jit, static_argnames=("shade",))
def fetch_kernel(alpha_t, ratio_t, row, theta_v, theta_l, *, shade: bool = True):
    """α (S, P) and re (S, L, P) of S sectors from a scene table's ``alpha_t`` (N, V/2, P) and
    ``ratio_t`` (N, V_r, Q, T) (any float dtype; V_r divides V, its own view grid 2πi/V_r), ``row`` (S,) int32,
    ``theta_v`` (S,), ``theta_l`` (S, L)."""
    alpha, ratio = fetch_terms(alpha_t, ratio_t, row, theta_v, theta_l, shade=shade)
    if not shade:
        return alpha, jnp.zeros((alpha.shape[0], 0, alpha.shape[1]), jnp.float32)
    return alpha, alpha[:, None, :] * jnp.repeat(ratio, alpha.shape[1] // ratio.shape[-1], axis=-1)


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
