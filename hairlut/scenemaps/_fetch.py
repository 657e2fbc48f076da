"""Reading a scene table online: every sector's α and re rows at its exact θv and θl (the ``scene`` map method).

For sector s with table row r (−1: empty, α = re = 0) and view θv: f = θv V / 2π, views
i₀ = ⌊f⌋ mod V and i₁ = i₀ + 1 mod V, weight w = f − ⌊f⌋ (periodic linear interpolation, as an SATF
row's angle interpolation).  α(p) = (1 − w) α_{i₀}(p) + w α_{i₁}(p), where a view i ≥ V/2 reads the
stored view i − V/2 at pixel P − 1 − p (the mirror symmetry).  The ratio's terms are interpolated
the same way on their own grid of V_r = V / ratio_step views and evaluated at each light's Δ = θl − θv: ρ_l(q) = c₀ + Σ_k a_k cos kΔ + b_k sin kΔ;
re_l(p) = α(p) ρ_l(q(p)), q(p) = ⌊p Q / P⌋.  One jitted kernel, float32 arithmetic (the contraction
over the terms at HIGHEST precision), empty sectors masked to exactly 0.

A view's maps (the ``scene`` map method, ``hairlut.synth``) run the same fetch as two kernels,
:func:`index_kernel` (each sector's rows and weights) then :func:`terms_kernel` (the gathers), so that
the row indices are materialised before the row copies that use them.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors

HIGHEST = jax.lax.Precision.HIGHEST


def fetch_index(row, theta_v, *, half: int, views: int):
    """Where S sectors read a scene table at their θv (module docstring): the α rows ``ia0``, ``ia1``
    (S,) int32 of the 2-D view (N·V/2, P) of the table for views i₀ and i₁ = i₀ + 1 (mod V = 2·``half``),
    whether each is a mirror view (its row reversed), ``mirror0``, ``mirror1`` (S,) bool, and the weight
    ``w`` (S,); the ratio-term rows ``ic0``, ``ic1`` (S,) of the (N·V_r, Q·T) view (V_r = ``views``) and
    their weight ``u`` (S,); ``live`` (S,) bool (``row`` ≥ 0).  Traceable."""
    live = row >= 0
    r = jnp.where(live, row, 0)

    def grid(V):  # views i0, i1 = i0 + 1 (mod V) and weight w of θv on the grid 2πi/V
        f = jnp.mod(theta_v, 2 * jnp.pi) * (V / (2 * jnp.pi))  # in [0, V]: one subtraction wraps it
        i0f = jnp.floor(f)
        i0 = i0f.astype(jnp.int32)
        i0 = jnp.where(i0 >= V, i0 - V, i0)
        return i0, jnp.where(i0 == V - 1, 0, i0 + 1), f - i0f

    def stored(i):  # view i's row: the mirrored half reads view i − V/2
        return r * half + jnp.where(i >= half, i - half, i)

    i0, i1, w = grid(2 * half)
    j0, j1, u = grid(views)
    return {
        "ia0": stored(i0),
        "ia1": stored(i1),
        "mirror0": i0 >= half,
        "mirror1": i1 >= half,
        "w": w,
        "ic0": r * views + j0,
        "ic1": r * views + j1,
        "u": u,
        "live": live,
    }


def fetch_gathered(alpha_t, ratio_t, index, theta_v, theta_l, *, shade: bool = True):
    """α (S, P) and ρ (S, L, Q) (:func:`fetch_terms`) from the rows :func:`fetch_index` chose.  Traceable.

    Every read is a whole contiguous row (P pixels of α; the Q·T terms of one view): the tables are
    viewed as 2-D (N·V/2, P) and (N·V_r, Q·T) and indexed by row, so XLA gathers slices rather than one
    index tuple per element (several times cheaper on the CPU than the (N, V, Q, T) element gather),
    and a mirror view is its stored row reversed.  Narrow storage is converted after the gather."""
    n, half, P = alpha_t.shape
    Vr, Q, T = ratio_t.shape[1:]
    K = (T - 1) // 2
    ix = index
    rows_a = alpha_t.reshape(n * half, P)

    def alpha_at(ia, mirror):
        a = jnp.take(rows_a, ia, axis=0, mode="clip").astype(jnp.float32)
        return jnp.where(mirror[:, None], a[:, ::-1], a)

    w = ix["w"][:, None]
    alpha = jnp.where(
        ix["live"][:, None], (1 - w) * alpha_at(ix["ia0"], ix["mirror0"]) + w * alpha_at(ix["ia1"], ix["mirror1"]), 0.0
    )
    if not shade:
        return alpha, jnp.zeros((alpha.shape[0], 0, Q), jnp.float32)
    rows_c = ratio_t.reshape(n * Vr, Q * T)

    def terms_at(ic):
        return jnp.take(rows_c, ic, axis=0, mode="clip").astype(jnp.float32)

    u = ix["u"][:, None]
    c = ((1 - u) * terms_at(ix["ic0"]) + u * terms_at(ix["ic1"])).reshape(-1, Q, T)
    d = theta_l - theta_v[:, None]  # (S, L)
    k = jnp.arange(1, K + 1, dtype=jnp.float32)
    kd = d[..., None] * k  # (S, L, K)
    basis = jnp.concatenate(
        [jnp.ones_like(d)[..., None], jnp.stack([jnp.cos(kd), jnp.sin(kd)], -1).reshape(*d.shape, 2 * K)], -1
    )  # (S, L, T)
    return alpha, jnp.einsum("sqt,slt->slq", c, basis, precision=HIGHEST)


def fetch_terms(alpha_t, ratio_t, row, theta_v, theta_l, *, shade: bool = True):
    """α (S, P) and the re/α ratio per light and bin, ρ (S, L, Q), of S sectors (module docstring):
    re_l(p) = α(p) ρ_l(⌊p Q / P⌋).  Traceable (no jit of its own): :func:`fetch_kernel` inlines it.
    Arguments as :func:`fetch_kernel`; :func:`fetch_index` then :func:`fetch_gathered`."""
    index = fetch_index(row, theta_v, half=alpha_t.shape[1], views=ratio_t.shape[1])
    return fetch_gathered(alpha_t, ratio_t, index, theta_v, theta_l, shade=shade)


@partial(jax.jit, static_argnames=("half", "views"))
def index_kernel(row, theta_v, *, half: int, views: int):
    """:func:`fetch_index` as a kernel of its own, for a view's fetch: its few (S,) index arrays are then
    materialised before :func:`terms_kernel` gathers with them.  Fused into one kernel, XLA:CPU recomputes a
    row's index arithmetic for each of the P elements it copies (measured 2.5 of the paper-scale view's
    ~12 ms fetch, 2-core CPU)."""
    return fetch_index(row, theta_v, half=half, views=views)


@jax.jit
def terms_kernel(alpha_t, ratio_t, index, theta_v, theta_l):
    """α (S, P) and ρ (S, L, Q) (:func:`fetch_terms`) from :func:`index_kernel`'s ``index``; tables as
    :func:`fetch_kernel`."""
    return fetch_gathered(alpha_t, ratio_t, index, theta_v, theta_l)


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
        raise errors.ValidationError(
            "theta_l", tl.shape, f"need theta_v (S,), theta_l (S, L), row (S,); got {tv.shape}, {tl.shape}, {rw.shape}"
        )
    if not (np.isfinite(tv).all() and np.isfinite(tl).all()):
        raise errors.ValidationError("theta_v", "non-finite", "angles must be finite")
    a, r = fetch_kernel(
        jnp.asarray(maps.alpha),
        jnp.asarray(maps.ratio),
        jnp.asarray(rw, jnp.int32),
        jnp.asarray(np.mod(tv, 2 * np.pi), jnp.float32),
        jnp.asarray(np.mod(tl, 2 * np.pi) if tl.shape[1] else np.zeros((len(tv), 1)), jnp.float32),
        shade=tl.shape[1] > 0,
    )
    a, r = np.asarray(a), np.asarray(r)
    if not (np.isfinite(a).all() and np.isfinite(r).all()):
        raise errors.HairlutError("scene_maps fetch: non-finite maps")
    return a, r
