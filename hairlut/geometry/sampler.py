"""Random generalized sectors for building the HRIR database (satf §5), and real ones from grooms.

§5 "initialize[s] control parameters of a generalized sector using random values"; the
:class:`~hairlut.geometry.SectorSpace` (:mod:`.sector_space`: fields, defaults, rules) makes
those parameters explicit.  A sampled sector is a (v, u)
patch of an ellipse with major half-axis A = 1 (features are scale-free: ρ is an area
fraction, centroids are parametric), minor half-axis B = ``aspect``, radial range
[v0, v0 + radial_extent] ∩ [0, 1], phase extent Δu = 2π/s_u, whose s = 0 edge sits at
polar angle ``phase``.  The strand radius is ``radius`` · √(sector area), so the
coverage n·π·radius² does not depend on the sector's size.  ``strands`` strands cross
the sector or a margin of 3σ around it (as in a real cross-section, where neighbours'
Gaussians reach in), at (s, r) drawn by profile:

- ``uniform``: uniform over the window's metric area;
- ``gaussian``: one blob at a uniform centre in [0, 1]², standard deviation ``spread``
  (sector units, both axes), truncated to the window (exact inverse CDF per axis);
- ``clumped``: ``clumps`` blob centres, each strand in one, standard deviation
  ``spread``/2, truncated likewise.

Ranges are sampled uniformly, or log-uniformly where they span decades (radius, spread,
and strand count + 1).  Everything is drawn from ``numpy.random.default_rng(seed)`` in a
fixed order: the same seed gives identical sectors.  :func:`groom_sectors` cuts the
sectors of a real groom (clusters fitted by :func:`hairlut.geometry.fit.fit_clusters`),
so the space's coverage of real features can be checked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr, ndtri

from ..errors import ValidationError
from ..validate import check_int
from .cluster_defaults import STRUCTURE_DEFAULTS as _D
from .fit import fit_clusters
from .sector_space import SectorSpace
from .sectors import SectorTable, build_sectors
from .splats import SIGMA_PER_RADIUS, SplatBatch, pack, param_sigma
from .strands import Strands
from .sweep import ClusterGeometry

SECTOR_PROFILES = ("uniform", "gaussian", "clumped")


@dataclass(frozen=True, eq=False)
class SampledSectors:
    """Random sectors: their splats (for ``sector_density``) and the parameters drawn.

    ``params`` holds one entry per sector for each :class:`SectorSpace` field (``strands``,
    ``radius_rel``, the strand radius relative to √area, ``spread``, ``clumps``, ``aspect``, ``v_inner``,
    ``radial_extent``, ``s_u``), plus ``phase`` (polar angle of the s = 0 edge), ``profile``
    (index into ``SECTOR_PROFILES``) and ``v_range`` (N, 2).
    """

    splats: SplatBatch
    params: dict[str, np.ndarray]


def _log_uniform(rng, lo, hi, n):
    return np.exp(rng.uniform(np.log(lo), np.log(hi), n))


def _truncnorm(u, mu, sd, lo, hi):
    """Normal(mu, sd) truncated to [lo, hi], by inverse CDF of the uniforms ``u``."""
    a, b = ndtr((lo - mu) / sd), ndtr((hi - mu) / sd)
    q = a + u * (b - a)
    return np.clip(mu + sd * ndtri(np.clip(q, 1e-300, 1 - 1e-16)), lo, hi)


def sample_sectors(n: int, space: SectorSpace = SectorSpace(), *, seed: int = 0) -> SampledSectors:
    """``n`` random sectors from ``space`` (module docstring), deterministic by ``seed``."""
    n = check_int(n, "n", 1)
    _check_space(space)
    rng = np.random.default_rng(check_int(seed, "seed", 0))
    p = _draw_params(rng, space, n)
    w = _window(p, space)
    return _place(p, w, space, _draw_strands(rng, w, space, n))


def sample_each(seeds, space: SectorSpace = SectorSpace()) -> SampledSectors:
    """One sector per seed, bitwise the concatenation of ``sample_sectors(1, space, seed=s)`` for each.

    Every sector draws from its own generator exactly as ``sample_sectors`` would (same calls, same
    arguments, same order); only the arithmetic between the draws runs once over all sectors, so a
    block of sectors costs the host two short loops of draws instead of one full sampling per sector."""
    _check_space(space)
    seeds = [check_int(s, "seed", 0) for s in seeds]
    if not seeds:
        raise ValidationError("seeds", seeds, "give at least one seed")
    rngs = [np.random.default_rng(s) for s in seeds]
    drawn = [_draw_params(rng, space, 1) for rng in rngs]
    p = {k: np.concatenate([d[k] for d in drawn]) for k in drawn[0]}
    w = _window(p, space)
    ends = np.cumsum(p["strands"])
    cut = {k: np.split(v, ends[:-1]) for k, v in w["per_strand"].items()}
    raw = [_draw_strands(rng, {"per_strand": {k: v[i] for k, v in cut.items()}}, space, 1) for i, rng in enumerate(rngs)]
    return _place(p, w, space, {k: np.concatenate([r[k] for r in raw]) for k in raw[0]})


def _check_space(space) -> None:
    if not isinstance(space, SectorSpace):
        raise ValidationError("space", type(space).__name__, "must be a SectorSpace")


def _draw_params(rng, space: SectorSpace, n: int) -> dict:
    """The per-sector parameters, drawn in the fixed order."""
    p = {
        "strands": np.floor(_log_uniform(rng, space.strands[0] + 1, space.strands[1] + 1 + 1e-9, n)).astype(np.int64) - 1,
        "radius_rel": _log_uniform(rng, *space.radius_rel, n),
        "spread": _log_uniform(rng, *space.spread, n),
        "clumps": rng.integers(space.clumps[0], space.clumps[1] + 1, n),
        "aspect": rng.uniform(*space.aspect, n),
        "v_inner": rng.uniform(*space.v_inner, n),
        "radial_extent": rng.uniform(*space.radial_extent, n),
        "s_u": rng.integers(space.s_u[0], space.s_u[1] + 1, n),
        "phase": rng.uniform(0.0, 2 * np.pi, n),
        "profile": rng.choice(3, n, p=np.asarray(space.profile_weights) / sum(space.profile_weights)),
    }
    p["strands"] = np.clip(p["strands"], space.strands[0], space.strands[1])
    return p


def _window(p: dict, space: SectorSpace) -> dict:
    """Each sector's shape and the window its strands may cross: the sector plus a margin of 3σ (at its
    centre) on every side; ``per_strand`` holds the bounds the strand draws take, one row per strand."""
    v0 = p["v_inner"]
    v1 = np.minimum(v0 + p["radial_extent"], 1.0)
    du = 2 * np.pi / p["s_u"]
    area = p["aspect"] * du * 0.5 * (v1**2 - v0**2)
    r_metric = p["radius_rel"] * np.sqrt(area)
    su_c, sv_c = param_sigma(SIGMA_PER_RADIUS * r_metric, 0.5 * (v0 + v1), p["phase"] + 0.5 * du, 1.0, p["aspect"])
    margin = 3.0 * np.stack([su_c / du, sv_c / (v1 - v0)], axis=1)
    lo_r = np.maximum(-margin[:, 1], -v0 / (v1 - v0))  # not inside v < 0
    hi_r = np.minimum(1.0 + margin[:, 1], (1.0 - v0) / (v1 - v0))  # nor outside the ellipse
    lo_s, hi_s = -margin[:, 0], 1.0 + margin[:, 0]
    owner = np.repeat(np.arange(len(v0)), p["strands"])
    va, vb = v0 + lo_r * (v1 - v0), v0 + hi_r * (v1 - v0)
    return {
        "v0": v0,
        "v1": v1,
        "du": du,
        "r_metric": r_metric,
        "lo_r": lo_r,
        "hi_r": hi_r,
        "lo_s": lo_s,
        "hi_s": hi_s,
        "owner": owner,
        "per_strand": {
            "lo_s": lo_s[owner],
            "hi_s": hi_s[owner],
            "va2": va[owner] ** 2,
            "vb2": vb[owner] ** 2,
            "clumps": p["clumps"][owner],
        },
    }


def _draw_strands(rng, w: dict, space: SectorSpace, n: int) -> dict:
    """The strand draws of ``n`` sectors (raw: the arithmetic on them is :func:`_place`'s), in the fixed order."""
    b = w["per_strand"]
    m = len(b["lo_s"])
    return {
        "s_pos": rng.uniform(b["lo_s"], b["hi_s"]),  # uniform in metric area over the window: s uniform, v² uniform
        "v2": rng.uniform(b["va2"], b["vb2"]),
        "centre": rng.uniform(size=(n, space.clumps[1], 2)),  # blob centres; a sector uses its first `clumps`
        "pick": rng.integers(0, b["clumps"]),
        "q_s": rng.uniform(size=m),
        "q_r": rng.uniform(size=m),
    }  # the truncated normals' uniforms


def _place(p: dict, w: dict, space: SectorSpace, raw: dict) -> SampledSectors:
    """Strand positions and splats from the draws (module docstring: profiles, truncated normals)."""
    v0, v1, du, owner = w["v0"], w["v1"], w["du"], w["owner"]
    n = len(v0)
    prof = p["profile"][owner]
    s_pos = raw["s_pos"]
    r_pos = (np.sqrt(raw["v2"]) - v0[owner]) / (v1 - v0)[owner]
    pick = np.where(prof == 2, raw["pick"], 0)
    mu = raw["centre"][owner, pick]
    sd = np.where(prof == 2, 0.5, 1.0) * p["spread"][owner]
    blob_s = _truncnorm(raw["q_s"], mu[:, 0], sd, w["lo_s"][owner], w["hi_s"][owner])
    blob_r = _truncnorm(raw["q_r"], mu[:, 1], sd, w["lo_r"][owner], w["hi_r"][owner])
    s_pos = np.where(prof == 0, s_pos, blob_s)
    r_pos = np.where(prof == 0, r_pos, blob_r)
    v = v0[owner] + r_pos * (v1 - v0)[owner]
    phi = p["phase"][owner] + s_pos * du[owner]
    r_metric = w["r_metric"]
    sig_u, sig_v = param_sigma(SIGMA_PER_RADIUS * r_metric[owner], v, phi, 1.0, p["aspect"][owner])
    sigma = np.stack([sig_u / du[owner], sig_v / (v1 - v0)[owner]], axis=1)
    splats = pack(
        owner,
        np.stack([s_pos, r_pos], axis=1),
        sigma,
        r_metric[owner],
        n,
        p["aspect"] * du,
        np.stack([v0, v1], axis=1),
        max_splats=max(space.strands[1], 1),
    )
    p["v_range"] = np.stack([v0, v1], axis=1)
    return SampledSectors(splats, p)


def groom_sectors(
    strands: Strands,
    n_clusters: int,
    *,
    radius: float,
    layer_radii=_D["layer_radii"],
    core_radius: float = _D["core_radius"],
    s_t: int = _D["s_t"],
    s_v: int = _D["s_v"],
    s_u: int = _D["s_u"],
    seed: int = 0,
) -> tuple[SectorTable, ClusterGeometry, np.ndarray]:
    """Sectors cut from a real groom: fit ``n_clusters`` clusters, assign each strand to its
    group's cluster, build the sectors.  Returns (sectors, geometry, cluster per strand)."""
    batch, labels = fit_clusters(
        strands, n_clusters, layer_radii=layer_radii, core_radius=core_radius, s_t=s_t, s_v=s_v, s_u=s_u, seed=seed
    )
    geometry = ClusterGeometry(batch)
    return build_sectors(geometry, strands, labels, radius=radius), geometry, labels
