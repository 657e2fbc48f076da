"""Where a cluster's strands lie relative to its volume (satf §3.2): the measure of a cluster fit.

A strand segment is placed by its mid-point against the cluster's cross-sections at ``samples``
values of t (the nearest one): ``before_start`` / ``after_end`` when it lies beyond the first or last
section's plane (t outside [0, 1]), ``core`` when v < core_radius, ``outside`` when v > 1 (beyond the
outer shell of eq 1's ellipse), ``inside`` otherwise: where the strand crosses the sectors' planes
(:func:`~hairlut.geometry.build_sectors`), so only that part of the hair reaches the sector densities and
the layered model.  :func:`length_inside` gives the fractions of the strand length in each place.
"""

from __future__ import annotations

import numpy as np

#: The places of :func:`segment_places`, in code order.
PLACES = ("inside", "before_start", "after_end", "core", "outside")


def segment_places(spec, strands, *, samples: int = 801) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(first point index, length, place code into :data:`PLACES`) of every segment of ``strands`` in the
    cluster ``spec`` (a :class:`~hairlut.geometry.ClusterSpec`); the module docstring gives the rule."""
    from .sweep import ClusterGeometry

    sec = ClusterGeometry([spec]).sections(np.linspace(0.0, 1.0, samples)).take(0)
    p = np.asarray(strands.points, np.float64)
    last = np.zeros(len(p), bool)
    last[np.asarray(strands.offsets)[1:] - 1] = True
    first = np.flatnonzero(~last)
    mid = 0.5 * (p[first] + p[first + 1])
    length = np.linalg.norm(p[first + 1] - p[first], axis=1)
    near = np.empty(len(mid), np.int64)
    for a in range(0, len(mid), 4096):  # (chunk, samples) distances at a time
        near[a : a + 4096] = np.argmin(np.linalg.norm(mid[a : a + 4096, None] - sec.origin[None], axis=-1), axis=1)
    rel = mid - sec.origin[near]
    along = np.sum(rel * sec.tangent[near], 1)
    v = np.hypot(np.sum(rel * sec.normal[near], 1) / sec.a[near], np.sum(rel * sec.binormal[near], 1) / sec.b[near])
    place = np.zeros(len(mid), np.int64)
    before, after = (near == 0) & (along < 0), (near == samples - 1) & (along > 0)
    place[v > 1.0] = PLACES.index("outside")
    place[v < spec.core_radius] = PLACES.index("core")
    place[after] = PLACES.index("after_end")
    place[before] = PLACES.index("before_start")
    return first, length, place


def length_inside(batch, strands, labels, *, samples: int = 801) -> dict:
    """Fractions of the strand length of ``strands`` (a :class:`~hairlut.geometry.Strands`) in each place of
    :data:`PLACES`, each strand against its cluster ``labels[s]`` of ``batch`` (a ClusterBatch or a list of
    ClusterSpecs; label −1: the whole strand counts as ``unassigned``).  The fractions sum to 1."""
    from .strands import Strands

    specs = list(getattr(batch, "specs", batch))
    labels = np.asarray(labels)
    tot = {k: 0.0 for k in (*PLACES, "unassigned")}
    off = strands.offsets
    pts = np.asarray(strands.points)
    for c in [*range(len(specs)), -1]:
        idx = np.flatnonzero(labels == c)
        if not idx.size:
            continue
        sub = Strands(np.concatenate([pts[off[i] : off[i + 1]] for i in idx]), strands.counts[idx])
        if c < 0:
            tot["unassigned"] += float(
                np.linalg.norm(np.diff(sub.points.astype(np.float64), axis=0), axis=1)[
                    np.diff(np.repeat(np.arange(idx.size), sub.counts)) == 0
                ].sum()
            )
            continue
        _, length, place = segment_places(specs[c], sub, samples=samples)
        for k, name in enumerate(PLACES):
            tot[name] += float(length[place == k].sum())
    total = sum(tot.values())
    return {k: v / total if total > 0 else 0.0 for k, v in tot.items()}
