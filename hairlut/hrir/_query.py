"""SATF lookup (satf eq 4): HRIRs for arbitrary (ρ_feature, θv, θl) from an HRIR-DB.

Feature space: features are normalised with the database's statistics,
z = (x − mean) / std, and compared with the Euclidean metric.  The k nearest
records (brute force: one (N, M) distance block per chunk of queries, then
``lax.top_k``: :func:`neighbours`) are blended with inverse-distance weights
w_i ∝ 1 / (d_i + ε), so an exact feature match returns that record.  Angles are
periodic: each record is interpolated bilinearly on the (θv, θl) grid with
wrap-around (α only in θv, since it does not depend on the light: :func:`interpolate`,
which callers with precomputed neighbours use on their own).

Cost per query: O(M·F) for the distances, O(k·4·P) for the gathers; the distances'
memory is bounded by evaluating ``CHUNK`` queries at a time.

**Range.**  The search runs in float32, so a query's normalised features must keep its squared distance
to every record finite there: a record lies at most √(N − 1) standard deviations from the mean
(Samuelson's inequality; the std's floor only shrinks that), so |z| ≤ √(F32max / 2F) − √(N − 1) per
component keeps Σ (z − z_i)² ≤ F32max / 2 (:func:`feature_limit`); a query beyond it is refused, naming
``features`` (finite features of 1e300 gave NaN weights, issue 29 m14).  Angles are reduced mod 2π in
float64 before the float32 cast (1e300 rad became inf, then NaN), as exactly as float64 holds them.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from .._blocks import map_blocks
from ..validate import FLOAT32_MAX

CHUNK = 4096
EPS = 1e-6


def _periodic(theta, n):
    """Grid cell (i0, i1) and fraction for a periodic grid 2πi/n."""
    f = jnp.mod(theta, 2 * jnp.pi) / (2 * jnp.pi) * n
    i0 = jnp.floor(f).astype(jnp.int32)
    frac = f - i0
    i0 = jnp.mod(i0, n)
    return i0, jnp.mod(i0 + 1, n), frac


def neighbours(zq, zdb, k):
    """The k nearest records of normalised queries zq (n, F) among zdb (M, F) and their
    inverse-distance weights w_i ∝ 1 / (d_i + ε), normalised: (idx (n, k), w (n, k))."""
    d2 = jnp.sum((zq[:, None, :] - zdb[None, :, :]) ** 2, axis=-1)  # (n, M)
    neg, idx = jax.lax.top_k(-d2, k)
    w = 1.0 / (jnp.sqrt(jnp.maximum(-neg, 0.0)) + EPS)
    return idx, w / jnp.sum(w, axis=-1, keepdims=True)


def interpolate(idx, w, tv, tl, alpha, refl):
    """The angle half of the lookup for known neighbours: records idx (n, k) blended with weights
    w (n, k), each bilinear on the periodic (θv, θl) grid (α in θv only) → re (n, Lt, P) for
    tl (n, Lt), α (n, P).  One row gather per (neighbour, grid corner), fused into the sum."""
    n_rec, V, L, P = refl.shape
    rows, arows = refl.reshape(n_rec * V * L, P), alpha.reshape(n_rec * V, P)
    v0, v1, fv = _periodic(tv, V)
    l0, l1, fl = _periodic(tl, L)
    gv, gl, fv = fv[:, None, None], fl[..., None], fv[:, None]
    re = a = 0.0
    for j in range(idx.shape[1]):
        a0, a1 = idx[:, j] * V + v0, idx[:, j] * V + v1  # α rows; reflectance rows follow in θl
        r0, r1 = a0[:, None] * L, a1[:, None] * L
        r = (1 - gv) * ((1 - gl) * rows[r0 + l0] + gl * rows[r0 + l1]) + gv * ((1 - gl) * rows[r1 + l0] + gl * rows[r1 + l1])
        re = re + w[:, j, None, None] * r
        a = a + w[:, j, None] * ((1 - fv) * arows[a0] + fv * arows[a1])
    return re, a


@functools.partial(jax.jit, static_argnames=("k",))
def neighbours_kernel(zq, zdb, k):
    """:func:`neighbours` over flat queries, in chunks of CHUNK."""
    return map_blocks(lambda q: neighbours(q, zdb, k), (zq,), CHUNK)


@jax.jit
def _interpolate_kernel(idx, w, tv, tl, alpha, refl):
    re, a = interpolate(idx, w, tv, tl[:, None], alpha, refl)
    return re[:, 0], a


def query_kernel(zq, tv, tl, zdb, alpha, refl, k):
    """The SATF over flat queries (see module doc): the k-NN search (jitted, in chunks of CHUNK),
    then :func:`interpolate` (jitted) over all queries at once → re, α, neighbour index, weights.
    Two kernels: in one, XLA:CPU fuses the search into the gathers and runs ~15× slower."""
    idx, w = neighbours_kernel(zq, zdb, k)
    return (*_interpolate_kernel(idx, w, tv, tl, alpha, refl), idx, w)


def device_arrays(db):
    """The database's normalised features, α and reflectance as float32 device arrays."""
    return (
        jnp.asarray(db.stats.normalize(db.features), jnp.float32),
        jnp.asarray(db.alpha, jnp.float32),
        jnp.asarray(db.reflectance, jnp.float32),
    )


def feature_limit(n_records: int, n_features: int) -> float:
    """The largest |z| (normalised feature) of a query whose float32 distances to ``n_records`` records of
    ``n_features`` features stay finite (module docstring)."""
    return math.sqrt(FLOAT32_MAX / (2 * n_features)) - math.sqrt(max(n_records - 1, 0))


def satf_query(db, features, theta_v, theta_l, k: int = 4):
    """SATF(ρ_feature, θv, θl) → (re (..., P), α (..., P), neighbour index (..., k), weights (..., k)).

    ``features`` (..., F) are raw (un-normalised) feature vectors in the database's
    feature order; θv, θl are in-plane angles (radians, any real value: periodic).
    """
    f = np.asarray(features, np.float64)
    F = db.features.shape[1]
    if f.ndim < 1 or f.shape[-1] != F or not np.all(np.isfinite(f)):
        raise errors.ValidationError("features", f.shape, f"need finite (..., {F}) feature vectors ({', '.join(db.stats.names)})")
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= len(db.features):
        raise errors.ValidationError("k", k, f"need 1 ≤ k ≤ {len(db.features)} (database size)")
    tv = np.asarray(theta_v, np.float64)
    tl = np.asarray(theta_l, np.float64)
    for name, x in (("theta_v", tv), ("theta_l", tl)):
        if not np.all(np.isfinite(x)):
            raise errors.ValidationError(name, theta_v if name == "theta_v" else theta_l, "angles must be finite")
    shape = np.broadcast_shapes(f.shape[:-1], tv.shape, tl.shape)
    flat = np.broadcast_to(f, shape + (F,)).reshape(-1, F)
    with np.errstate(over="ignore"):  # an overflow is inf, refused below
        z = db.stats.normalize(flat)
    limit = feature_limit(len(db.features), F)
    if z.size and not np.abs(z).max() <= limit:
        i, j = np.unravel_index(int(np.argmax(np.nan_to_num(np.abs(z), nan=np.inf))), z.shape)
        lo, hi = db.stats.denormalize(-limit)[j], db.stats.denormalize(limit)[j]
        raise errors.ValidationError(
            "features",
            float(flat[i, j]),
            f"{db.stats.names[j]} lies {abs(z[i, j]):.3g} standard deviations from the "
            f"database's mean; the float32 distances overflow beyond {limit:.3g} "
            f"({db.stats.names[j]} in [{lo:.3g}, {hi:.3g}])",
        )
    zdb, alpha, refl = getattr(db, "device_arrays", None) or device_arrays(db)
    turn = 2 * np.pi  # reduced in float64 first: a huge angle is inf in float32, and inf mod 2π is NaN
    re, a, idx, w = query_kernel(
        jnp.asarray(z, jnp.float32),
        jnp.asarray(np.mod(np.broadcast_to(tv, shape).ravel(), turn), jnp.float32),
        jnp.asarray(np.mod(np.broadcast_to(tl, shape).ravel(), turn), jnp.float32),
        zdb,
        alpha,
        refl,
        int(k),
    )
    P = db.alpha.shape[-1]
    return (
        np.asarray(re).reshape(*shape, P),
        np.asarray(a).reshape(*shape, P),
        np.asarray(idx).reshape(*shape, k),
        np.asarray(w).reshape(*shape, k),
    )
