"""Projection features of the HRIR-DB index: each sector's own density projected at a few views.

The paper indexes its records by three density statistics (ρ_st, ρ_s, ρ_t; satf §5.2).  A sector
of a real groom holds a few thin strands at arbitrary positions, which those three numbers do
not pin down.  What a lookup must match is the record's α row (eq 4), and α at view θ is the
line integral of the sector's density, α = 1 − exp(−σ_t ∫ρ ds) (eq 5 in closed form).  So the
``projection`` feature set measures that directly, with the tracer's own march
(``hairlut.march.march``, ``sector_fields``: the same rays as the records' α):

* **Profile.**  D = :data:`DIRECTIONS` views θ_d = π d / D, d = 0 … D − 1 (θ and θ + π give the
  same line integrals, mirrored); along each, ``bins · sub`` rays across the image line
  t ∈ [−R, R] (the tracer's lanes, R the sector's ``extent`` column), each marched in the
  recipe's ``trace.steps`` steps; per ray the opacity 1 − exp(−Σ_k τ_k); per bin the mean of its
  ``sub`` rays (a box filter, so a strand between rays is not missed): the bin opacities p_d,b in
  [0, 1] (:func:`sector_projections`).  The profile (:func:`profile`) is, per direction, p_d,b
  beside w · c_d,b with c_d,b = Σ_{b' ≤ b} p_d,b' / B its running sum and w = :data:`CUMULATIVE`.
  Why the running sum: the L2 distance between two thin peaks at different places is as large as
  if one were missing, so a nearest neighbour by p alone prefers a sparse record and under-covers
  (Sintel, 128 records, k = 4: per-sector coverage rel-L2 0.34, mean α −31 %); the running sum's
  distance grows with the shift instead (a 1-D transport distance) and keeps the mass.  Measured on
  the same database (``hairlut.bench.map_accuracy_study``; texel α rel-L2 / coverage rel-L2 / mean-α
  bias): w = 0: 0.566 / 0.336 / −31 %; 1: 0.552 / 0.312 / −28 %; 3: 0.551 / 0.206 / −20 %;
  6: 0.553 / 0.174 / −14 %; the running sum alone: 0.593 / 0.170 / −13 %.
* **Features.**  The scores of the profiles on the first :data:`COMPONENTS` principal components
  of the database's own profiles (``hairlut.geometry.PCABasis``, fitted at bake time and stored
  with the database; zero rows pad a basis of fewer records).  The scores are normalised by one
  common scale (the root of the profiles' total variance), not per component: the Euclidean
  distance between normalised features is then the L2 distance between the profiles (within the
  components' span) over their RMS spread, so a weak component is not magnified to a strong one's weight.

A scene sector gets the same features from its own density grid and geometry rows
(``hairlut.march.scene_sector_inputs``) through :func:`projection_features`.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..geometry.features import PROJECTION, FeatureStats, PCABasis
from ..march import GEOM, march, sector_fields

#: Views of the projection profile over [0, π).
DIRECTIONS = 8
#: Bins of each profile along the image line.
BINS = 16
#: Rays per bin, box-averaged.
SUB = 4
#: Weight of the running sum beside the bin opacities in the profile (module docstring).
CUMULATIVE = 6.0
#: Principal components kept as features.
COMPONENTS = len(PROJECTION)
#: Sectors mapped at once inside the kernel.
BLOCK = 64


@partial(jax.jit, static_argnames=("directions", "bins", "sub", "n_steps", "block"))
def projection_kernel(rho, geom, *, directions: int, bins: int, sub: int, n_steps: int, block: int = BLOCK):
    """(N, D, B) bin opacities of N sectors (module docstring); ``rho`` (N, n_s, n_r), ``geom`` (N, 11)
    rows of :data:`GEOM`, float32; N a multiple of ``block``.  No contraction: sums only."""
    views = jnp.pi * jnp.arange(directions, dtype=rho.dtype) / directions

    def one(a):
        tau = march(sector_fields(a[0]), a[1], views, bins * sub, n_steps)[0]  # (D, lanes, K)
        return (-jnp.expm1(-jnp.sum(tau, axis=-1))).reshape(directions, bins, sub).mean(-1)

    return jax.lax.map(one, (rho, geom), batch_size=block)


def sector_projections(
    density, geometry, *, n_steps: int, directions: int = DIRECTIONS, bins: int = BINS, sub: int = SUB, block: int = BLOCK
) -> np.ndarray:
    """(N, D·B) projection profiles (float64 copies of the float32 kernel's) of N sectors' density
    grids (N, n_s, n_r) and geometry rows (N, 11); empty sectors (all-zero density) are exactly 0."""
    rho = np.asarray(density)
    g = np.asarray(geometry, np.float64)
    if rho.ndim != 3 or rho.dtype.kind not in "fiu" or not np.all(np.isfinite(rho)) or (rho < 0).any():
        raise errors.ValidationError("density", rho.shape, "need (N, n_s, n_r) finite densities ≥ 0")
    if g.shape != (len(rho), len(GEOM)) or not np.all(np.isfinite(g)):
        raise errors.ValidationError("geometry", g.shape, f"need ({len(rho)}, {len(GEOM)}) finite hrir.GEOM rows")
    for name, v, least in (("n_steps", n_steps, 2), ("directions", directions, 1), ("bins", bins, 1), ("sub", sub, 1)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < least:
            raise errors.ValidationError(name, v, f"need an integer ≥ {least}")
    n = len(rho)
    out = np.zeros((n, directions * bins))
    live = np.flatnonzero(rho.reshape(n, -1).max(axis=1, initial=0.0) > 0)
    if live.size == 0:
        return out
    size = min(block, 1 << (live.size - 1).bit_length())
    total = -(-live.size // size) * size
    rows = np.concatenate([live, np.full(total - live.size, live[0])])  # pad with copies of a live sector
    p = projection_kernel(
        jnp.asarray(rho[rows], jnp.float32),
        jnp.asarray(g[rows], jnp.float32),
        directions=int(directions),
        bins=int(bins),
        sub=int(sub),
        n_steps=int(n_steps),
        block=size,
    )
    p = np.asarray(p, np.float64)[: live.size].reshape(live.size, -1)
    if not np.all(np.isfinite(p)):
        raise errors.HairlutError("sector_projections: the kernel produced non-finite profiles (check the density scale)")
    out[live] = p
    return out


def projection_settings(recipe: dict) -> dict:
    """The profile's settings for a resolved recipe (stored as the database's ``projection`` attribute)."""
    return {
        "directions": DIRECTIONS,
        "bins": BINS,
        "sub": SUB,
        "steps": int(recipe["trace"]["steps"]),
        "cumulative": CUMULATIVE,
        "components": COMPONENTS,
        "profile": 2 * DIRECTIONS * BINS,
    }


def profile(projections, bins: int = BINS) -> np.ndarray:
    """(N, 2·D·B) profiles from (N, D·B) bin opacities: per direction the B opacities, then
    :data:`CUMULATIVE` times their running sum over B (module docstring)."""
    p = np.asarray(projections, np.float64)
    q = p.reshape(len(p), -1, bins)
    return np.concatenate([q, CUMULATIVE * np.cumsum(q, axis=-1) / bins], axis=-1).reshape(len(p), -1)


def fit_projection(projections) -> tuple[PCABasis, np.ndarray, FeatureStats]:
    """The database side: from the records' bin opacities (N, D·B), a :data:`COMPONENTS`-component
    basis of their profiles (zero rows pad it below that many records), their scores (N, COMPONENTS)
    and the common-scale :class:`FeatureStats` (module docstring)."""
    prof = profile(projections)
    n, m = prof.shape
    if n >= 2:
        basis = PCABasis.fit(prof[:, None, :], min(COMPONENTS, n, m))
    else:
        basis = PCABasis((1, m), prof.mean(0), np.zeros((0, m)))
    comps = np.zeros((COMPONENTS, m))
    comps[: basis.n_components] = basis.components
    basis = PCABasis((1, m), basis.mean, comps)
    scores = basis.transform(prof[:, None, :])
    spread = float(np.sqrt(np.sum(np.var(prof, axis=0)))) if n >= 2 else 0.0
    scale = max(spread, 1e-12)
    return basis, scores, FeatureStats(PROJECTION, scores.mean(0) if n >= 2 else scores[0].copy(), np.full(COMPONENTS, scale))


def projection_features(db, density, geometry) -> np.ndarray:
    """(N, COMPONENTS) raw projection features of N sectors (density grids and geometry rows in the
    database's grid, pixel count and extinction) on the database's stored basis; the query side."""
    basis = getattr(db, "projection", None)
    if basis is None:
        raise errors.ValidationError(
            "db.features",
            tuple(db.stats.names),
            'this database is not indexed by projection features (bake it with sectors.features = "projection")',
        )
    prof = profile(sector_projections(density, geometry, n_steps=int(db.recipe["trace"]["steps"])))
    return basis.transform(prof[:, None, :])
