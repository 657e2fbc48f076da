"""What the planner measures on a scene's own sectors, before anything is baked (satf §3, §5).

:func:`scene_sectors` builds every cluster's sectors (no features) and measures their shape,
strand counts and the in-plane view and light azimuths they produce;
:func:`restricted_space` fits the HRIR database's sampled sector space to them (each range
widened by ``MARGIN``) and :func:`grid_coverage` says how much of a periodic angle grid the
scene reads.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._choices import Choice, sector_grid
from ._clusters import _root_of, scene_clusters

MARGIN = 0.1  # relative widening of each measured sector-space range


@dataclass(frozen=True, eq=False)
class SceneSectors:
    """What the planner measures on a scene's own sectors: per sector ``aspect`` (B/A ≤ 1),
    ``v_range`` (N, 2), ``strands`` crossing it, strand ``radius_rel`` = radius / √area (NaN when empty),
    and the in-plane azimuths ``theta_v`` (N,) and ``theta_l`` (N, L) of the view and lights."""

    s_u: int
    aspect: np.ndarray
    v_range: np.ndarray
    strands: np.ndarray
    radius_rel: np.ndarray
    theta_v: np.ndarray
    theta_l: np.ndarray


#: What :func:`scene_sectors` keeps in the groom cache per sector: the measures and the in-plane axes (the view's and
#: lights' azimuths are computed from the axes on every call).
_KEPT = ("aspect", "v_range", "strands", "radius_rel", "reference", "binormal", "ex", "ey")


def grid_choice(scene, ss: SceneSectors | None = None) -> Choice:
    """:func:`~hairlut.scene.sector_grid` for ``scene`` (its ``[tables.hrir]`` and its sectors ``ss``, measured
    when not given)."""
    ss = scene_sectors(scene) if ss is None else ss
    return sector_grid(scene.config["tables"]["hrir"], ss.radius_rel)


def scene_sectors(scene, cache_root=None) -> SceneSectors:
    """Build every cluster's sectors (no features) and measure them (see :class:`SceneSectors`).  For a ``[groom]``
    scene, what does not depend on the view or the lights is kept in the table cache under ``cache_root`` (else the
    one this process last used for the scene, else ``$HAIRLUT_CACHE``, else ``tables/``), keyed by the clusters'
    specs and strands (``_cache``), with the sector tables themselves (:func:`scene_sector_tables`)."""
    from ..geometry import azimuths
    from ._cache import cached

    pairs = scene_clusters(scene, cache_root)
    if scene.groom_path is None:  # generated strands ([[clusters]]): nothing is kept on disk
        m = _measure(pairs, _build_tables(pairs))
    else:
        key, root = _pairs_key(scene, pairs), _root_of(scene, cache_root)
        m = cached(
            "sectors",
            key,
            lambda: _measure(pairs, _tables(pairs, key, root)),
            lambda m: ({k: m[k] for k in _KEPT}, {"s_u": m["s_u"]}),
            _measured,
            root,
        )
    tv, tl = azimuths(m["reference"], m["binormal"], m["ex"], m["ey"], scene.view, scene.lights)
    return SceneSectors(m["s_u"], m["aspect"], m["v_range"], m["strands"], m["radius_rel"], tv, tl)


def _measured(arrays: dict, meta: dict) -> dict:
    """A sectors entry's arrays, checked (one length, their shapes), with ``s_u``."""
    n = len(arrays["aspect"])
    shapes = {"v_range": (n, 2), "reference": (n, 3), "binormal": (n, 3), "ex": (n, 2), "ey": (n, 2)}
    for k in _KEPT:
        if arrays[k].shape != shapes.get(k, (n,)):
            raise ValueError(f"{k} has shape {arrays[k].shape}")
    return {**{k: arrays[k] for k in _KEPT}, "s_u": int(meta["s_u"])}


def scene_sector_tables(scene, cache_root=None) -> list:
    """Each cluster's :class:`~hairlut.geometry.SectorTable` (:func:`~hairlut.geometry.build_sectors` with every
    strand of the cluster in it, no features), in the scene's order: the sector assignment that the planner, the
    scene-maps bake and ``hairlut.synth.prepare`` share.  A ``[groom]`` scene's are kept in the table cache under
    ``cache_root`` (else the one this process last used for the scene, else ``$HAIRLUT_CACHE``, else ``tables/``),
    keyed by the clusters' specs and strands (``_cache``)."""
    pairs = scene_clusters(scene, cache_root)
    if scene.groom_path is None:  # generated strands: nothing is kept on disk
        return _build_tables(pairs)
    return _tables(pairs, _pairs_key(scene, pairs), _root_of(scene, cache_root))


#: The groom cache's key of the last few scenes' clusters, by ``_clusters._key`` (what decides them): the planner
#: and ``synth.prepare`` in one process ask for the same scene's sectors, and the key hashes every strand.
_KEYS: dict = {}


def _pairs_key(scene, pairs) -> str:
    from ._cache import pairs_key
    from ._clusters import _MEMO_SIZE, _key

    memo = _key(scene)
    if memo not in _KEYS:
        while len(_KEYS) >= _MEMO_SIZE:
            _KEYS.pop(next(iter(_KEYS)))
        _KEYS[memo] = pairs_key(pairs)
    return _KEYS[memo]


def _tables(pairs, key: str, root) -> list:
    from ._cache import cached, tables_arrays, tables_from_arrays

    return cached("tables", key, lambda: _build_tables(pairs), tables_arrays, tables_from_arrays, root)


def _build_tables(pairs) -> list:
    from ..geometry import ClusterGeometry, build_sectors

    return [build_sectors(ClusterGeometry(spec), strands, np.zeros(strands.n_strands, np.int64)) for spec, strands in pairs]


def _measure(pairs, tables) -> dict:
    """Every cluster's sectors (no features), measured: the arrays of :data:`_KEPT` and ``s_u``."""
    from ..geometry import ClusterGeometry, sector_axes

    cols = {k: [] for k in _KEPT}
    s_u = None
    for (spec, _), table in zip(pairs, tables):
        geom = ClusterGeometry(spec)
        s_u = table.shape[3]
        A, B = table.half_axes[:, 0], table.half_axes[:, 1]
        v0, v1 = table.v_range[:, 0], table.v_range[:, 1]
        du = table.u_range[:, 1] - table.u_range[:, 0]
        n = np.bincount(table.crossing_sector, minlength=table.n_sectors)
        rsum = np.bincount(table.crossing_sector, weights=table.crossing_radius, minlength=table.n_sectors)
        area = A * B * du * 0.5 * (v1**2 - v0**2)
        with np.errstate(invalid="ignore", divide="ignore"):
            cols["radius_rel"].append(np.where(n > 0, rsum / np.maximum(n, 1) / np.sqrt(area), np.nan))
        cols["aspect"].append(np.minimum(A, B) / np.maximum(A, B))
        cols["v_range"].append(table.v_range)
        cols["strands"].append(n)
        for k, axis in zip(("reference", "binormal", "ex", "ey"), sector_axes(geom, table)):
            cols[k].append(axis)
    return {**{k: np.concatenate(cols[k]) for k in cols}, "s_u": s_u}


def grid_coverage(theta: np.ndarray, n: int) -> float:
    """Fraction of the periodic grid 2πi/n (:func:`~hairlut.geometry.angle_grid`) whose nodes
    bilinear interpolation reads at ``theta``."""
    from ..geometry import grid_cell

    cell, _ = grid_cell(np.ravel(theta), n)
    return float(np.unique(np.concatenate([cell, (cell + 1) % n])).size / n)


def _widen(lo: float, hi: float, floor: float, ceil: float) -> list[float]:
    pad = MARGIN * max(hi - lo, abs(hi), 1e-3)
    return [float(max(floor, lo - pad)), float(min(ceil, hi + pad))]


def restricted_space(ss: SceneSectors, base: dict) -> dict:
    """The base sector space fitted to the scene's sectors (module docstring); spread, clumps and
    profile weights are not measured and stay as given."""
    out = dict(base)
    v0, th = ss.v_range[:, 0], ss.v_range[:, 1] - ss.v_range[:, 0]
    r = ss.radius_rel[np.isfinite(ss.radius_rel)]
    out["s_u"] = [int(ss.s_u), int(ss.s_u)]
    out["aspect"] = _widen(ss.aspect.min(), ss.aspect.max(), 1e-3, 1.0)
    out["v_inner"] = _widen(v0.min(), v0.max(), 0.0, 0.9)
    out["radial_extent"] = _widen(th.min(), th.max(), 1e-3, 1.0)
    hi = int(ss.strands.max())
    out["strands"] = [int(ss.strands.min()), hi + max(1, math.ceil(MARGIN * hi))]
    if r.size:
        out["radius_rel"] = [float(r.min() / (1 + MARGIN)), float(r.max() * (1 + MARGIN))]
    return out
