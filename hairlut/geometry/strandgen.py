"""Strands inside clusters: generation (deterministic by seed) and assignment of given strands.

Generation works in the ellipse-normalised plane of eq 1, (ξ, η) = v·(cos φ, sin φ) with
φ = q(t) + u, where area is proportional to metric area (the map to the normal plane is
linear, with Jacobian A·B).  A strand is a root (v₀, u₀) drawn from the profile, followed
along t at that (v, u) (so it turns with the twist q), plus a smooth jitter:

- ``uniform``: uniform over the annulus v ∈ [v_min, v_max];
- ``gaussian``: isotropic Gaussian core of standard deviation ``spread`` (a fraction of
  the ellipse), truncated to the annulus (exact inverse CDF of the radial law);
- ``clumped``: ``clumps`` centres uniform over the annulus, each strand joining one at a
  Gaussian offset of standard deviation ``spread``, redrawn until inside.

Jitter: each of ξ, η gets jitter · √2 · Σₘ cₘ sin(π m t + βₘ), m = 1 … ``jitter_waves``,
cₘ ~ N(0, 1/waves), βₘ uniform (so its RMS over t is about ``jitter``); points pushed
outside the annulus are moved back radially onto it.  Each cluster draws from its own
child of ``numpy.random.SeedSequence(seed)``: the same seed gives identical strands.

Assignment rule (:func:`assign_strands`): a strand goes to the cluster whose trajectory
is nearest on average — the mean, over the strand's points, of the distance to the
trajectory (sampled at the frame table, densified 4×); −1 if that mean exceeds
``max_distance``.
"""

from __future__ import annotations

import numpy as np

from ..errors import ValidationError
from ..validate import check_real
from .strands import Strands
from .sweep import ClusterGeometry

PROFILES = ("uniform", "gaussian", "clumped")


def _positive(name: str, value, allow_zero: bool = False) -> float:
    return check_real(value, name, 0, lo_open=not allow_zero)


def _annulus_uniform(rng, n, v_min, v_max):
    return np.sqrt(rng.uniform(v_min**2, v_max**2, n)), rng.uniform(0.0, 2 * np.pi, n)


def _roots(rng, n, profile, v_min, v_max, spread, clumps):
    """(v, θ) of n roots in the normalised plane, θ the polar angle."""
    if profile == "uniform":
        return _annulus_uniform(rng, n, v_min, v_max)
    if profile == "gaussian":
        a, b = -(v_min**2) / (2 * spread**2), -(v_max**2) / (2 * spread**2)
        uu = rng.uniform(size=n)
        log_s = a + np.log(uu + (1 - uu) * np.exp(b - a))  # log survival, uniform in S between e^b and e^a
        return np.clip(spread * np.sqrt(-2.0 * log_s), v_min, v_max), rng.uniform(0.0, 2 * np.pi, n)
    cv, ct = _annulus_uniform(rng, clumps, v_min, v_max)
    centre = np.stack([cv * np.cos(ct), cv * np.sin(ct)], axis=1)[rng.integers(0, clumps, n)]
    pts = centre + rng.normal(0.0, spread, (n, 2))
    for _ in range(64):
        rad = np.hypot(pts[:, 0], pts[:, 1])
        bad = (rad < v_min) | (rad > v_max)
        if not bad.any():
            break
        pts[bad] = centre[bad] + rng.normal(0.0, spread, (int(bad.sum()), 2))
    return np.clip(np.hypot(pts[:, 0], pts[:, 1]), v_min, v_max), np.arctan2(pts[:, 1], pts[:, 0])


def generate_strands(
    geometry: ClusterGeometry,
    count,
    *,
    radius=0.004,
    profile: str = "uniform",
    spread: float = 0.35,
    clumps: int = 6,
    jitter: float = 0.0,
    jitter_waves: int = 3,
    points: int = 32,
    v_range: tuple[float, float] | None = None,
    seed: int = 0,
) -> tuple[Strands, np.ndarray]:
    """Strands in every cluster of ``geometry``; returns (strands, cluster of each strand).

    ``count``: strands per cluster (int or (C,)); ``radius``: metric strand radius, a
    number or a (low, high) range drawn per strand (stored as thickness = 2·radius);
    ``v_range``: radial range in ellipse fractions (default: core to the outer layer).
    """
    if profile not in PROFILES:
        raise ValidationError("profile", profile, f"known profiles: {', '.join(PROFILES)}")
    n_c = geometry.n_clusters
    counts = np.broadcast_to(np.asarray(count), (n_c,))
    if counts.dtype.kind not in "iu" or (counts < 0).any():
        raise ValidationError("count", count, "strand counts must be integers ≥ 0")
    r_lo, r_hi = (radius, radius) if np.ndim(radius) == 0 else tuple(radius)
    r_lo, r_hi = _positive("radius", r_lo), _positive("radius", r_hi)
    if r_hi < r_lo:
        raise ValidationError("radius", radius, "the range must be (low, high)")
    spread = _positive("spread", spread)
    jitter = _positive("jitter", jitter, allow_zero=True)
    for name, val, least in (("clumps", clumps, 1), ("jitter_waves", jitter_waves, 1), ("points", points, 2)):
        if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or val < least:
            raise ValidationError(name, val, f"must be an integer ≥ {least}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValidationError("seed", seed, "must be an integer ≥ 0")
    specs = geometry.batch.specs
    t = np.linspace(0.0, 1.0, points)
    sec = geometry.sections(t)  # (C, points): every strand is sampled at these t
    twist = sec.twist
    all_c, all_v, all_u, all_r = [], [], [], []
    for c, child in enumerate(np.random.SeedSequence(int(seed)).spawn(n_c)):
        rng = np.random.default_rng(child)
        n = int(counts[c])
        lo, hi = (specs[c].core_radius, specs[c].layer_radii[-1]) if v_range is None else v_range
        if not 0 <= lo < hi <= 1:
            raise ValidationError("v_range", v_range, "need 0 ≤ low < high ≤ 1")
        v0, th0 = _roots(rng, n, profile, lo, hi, spread, clumps)
        u0 = th0 - twist[c, 0]
        base = v0[:, None] * np.exp(1j * (twist[c][None, :] + u0[:, None]))  # (n, points) normalised plane
        m = np.arange(1, jitter_waves + 1)
        coef = rng.normal(0.0, 1.0 / np.sqrt(jitter_waves), (n, 2, jitter_waves))
        phase = rng.uniform(0.0, 2 * np.pi, (n, 2, jitter_waves))
        wave = (
            np.sqrt(2.0)
            * jitter
            * np.sum(coef[..., None] * np.sin(np.pi * m[None, None, :, None] * t + phase[..., None]), axis=2)
        )
        z = base + wave[:, 0] + 1j * wave[:, 1]
        rad = np.abs(z)
        z = np.where(rad > 0, z / np.where(rad > 0, rad, 1.0), 1.0) * np.clip(rad, lo, hi)
        all_c.append(np.full(n, c))
        all_v.append(np.abs(z))
        all_u.append(np.angle(z) - twist[c][None, :])
        all_r.append(rng.uniform(r_lo, r_hi, n))
    cl = np.concatenate(all_c).astype(np.int64)
    vv, uu = np.concatenate(all_v), np.concatenate(all_u)
    pts = sec.take(cl).point(vv, uu)
    thick = np.repeat(2.0 * np.concatenate(all_r), points)
    strands = Strands(pts.reshape(-1, 3), np.full(cl.size, points, dtype=np.int64), thickness=thick)
    return strands, cl


def assign_strands(strands: Strands, geometry: ClusterGeometry, *, max_distance: float | None = None) -> np.ndarray:
    """(S,) cluster of each strand by the nearest-trajectory rule (module docstring); −1 if none."""
    from scipy.spatial import cKDTree  # here, not at import: scipy.spatial costs half a second to load

    if not isinstance(strands, Strands):
        raise ValidationError("strands", type(strands).__name__, "must be a hairlut.geometry.Strands")
    if max_distance is not None:
        max_distance = _positive("max_distance", max_distance)
    if not strands.n_strands:
        return np.zeros(0, dtype=np.int64)
    fx = geometry.frame_table[0]  # (C, F, 3)
    w = np.linspace(0.0, 1.0, 5)[:-1]
    dense = (fx[:, :-1, None, :] * (1 - w)[:, None] + fx[:, 1:, None, :] * w[:, None]).reshape(fx.shape[0], -1, 3)
    dense = np.concatenate([dense, fx[:, -1:]], axis=1)
    pts = strands.points.astype(np.float64)
    first = strands.offsets[:-1]
    mean = np.empty((geometry.n_clusters, strands.n_strands))
    for c in range(geometry.n_clusters):
        d, _ = cKDTree(dense[c]).query(pts)
        mean[c] = np.add.reduceat(d, first) / strands.counts
    best = np.argmin(mean, axis=0)
    if max_distance is not None:
        best = np.where(mean[best, np.arange(best.size)] <= max_distance, best, -1)
    return best.astype(np.int64)
