"""Clusters fitted to given strands (e.g. the .tfx grooms), for cutting real sectors.

Recipe (:func:`fit_clusters`), all deterministic by seed:

1. resample every strand at ``n_resample`` points equally spaced in arc length;
2. group the strands by k-means (k-means++ start, Lloyd iterations) on those points;
3. the trajectory of a group is a least-squares cubic B-spline (``n_control`` control
   points) through the mean of its resampled strands, parametrised by relative arc length,
   then lengthened straight along its end tangents until no point of the group's strands lies
   beyond the first or last cross-section's plane (``extend``; the mean alone stops short of
   the longer strands and of roots spread over the scalp: 27.5 % of Sintel's strand length and
   22 % of Ratboy's lay beyond the ends without it);
4. the half-axes: at ``n_fit`` cross-sections the group's strands are cut by the normal
   plane (rotation-minimising frame), A and B start at twice the standard deviations of
   the crossings' frame coordinates x and y, then both are scaled so that a fraction
   ``coverage`` of the crossings lies inside the ellipse (v ≤ 1); A(t), B(t) are
   cubic B-splines with ``n_axis`` control values fitted as upper envelopes of those samples
   (least squares with the samples above the curve lifted until none is), kept
   ≥ ``min_half_axis`` (default 2 % of the group's trajectory length).  No twist (q = 0).

:func:`hairlut.geometry.length_inside` measures the result: with the defaults and no core
(``core_radius`` 0, the ``[groom]`` default) 98.4 % of Sintel's and 98.2 % of Ratboy's strand length
lies inside the fitted clusters (99.8 % with ``coverage`` 1; 62.8 % and 64.6 % with the former fit:
mean trajectory, 12 sections, core 0.25; tests/test_fit.py).  ``coverage`` 0.95 rather than 1: the
outliers' few crossings would widen every section's ellipse, and the layered render of both grooms
came out closer to the strand render with 0.95 (mean α −11.2 % against −13.6 % on Sintel, −18.9 %
against −21.5 % on Ratboy; 128², direct maps, strand render level 0).  The outliers' hair is not lost for that:
the sectors keep a crossing beyond the outer layer at the rim (:mod:`hairlut.geometry.sectors`).

A group whose mean strand has no length (the grooms hold a few near-zero strands) is
dropped and its strands are labelled −1.
"""

from __future__ import annotations

import numpy as np

from ..errors import ValidationError
from ._bspline import BSpline, fit_bspline
from .cluster import ClusterBatch, ClusterSpec
from .cluster_defaults import STRUCTURE_DEFAULTS as _D
from .sectors import _crossings
from .strands import Strands
from .sweep import ClusterGeometry


def resample_strands(strands: Strands, n: int) -> np.ndarray:
    """(S, n, 3) points at n fractions of each strand's arc length (0 and 1 included)."""
    pts = strands.points.astype(np.float64)
    off = strands.offsets
    seg_len = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    owner = np.repeat(np.arange(strands.n_strands), strands.counts)
    seg_len[off[1:-1] - 1] = 0.0  # no segment across strands
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    start = cum[off[:-1]]
    total = cum[off[1:] - 1] - start
    tot = total[owner]
    frac = np.zeros_like(cum)
    np.divide(cum - start[owner], tot, out=frac, where=tot > 0)
    flat = tot <= 0  # a strand without length: its (equal) points spread over [0, 1], so it does not reach the next strand
    frac[flat] = (np.arange(len(cum)) - off[owner])[flat] / np.maximum(strands.counts[owner][flat] - 1, 1)
    key = owner * 2.0 + frac  # strands' keys never overlap
    want = (np.arange(strands.n_strands)[:, None] * 2.0 + np.linspace(0.0, 1.0, n)[None, :]).ravel()
    out = np.empty((want.size, 3))
    for d in range(3):
        out[:, d] = np.interp(want, key, pts[:, d])
    return out.reshape(strands.n_strands, n, 3)


def kmeans(x: np.ndarray, k: int, seed: int, iters: int = 50) -> np.ndarray:
    """Labels of k-means (k-means++ start); deterministic by seed."""
    rng = np.random.default_rng(seed)
    centres = [x[rng.integers(len(x))]]
    d2 = np.sum((x - centres[0]) ** 2, axis=1)
    for _ in range(1, k):
        p = d2 / d2.sum() if d2.sum() > 0 else np.full(len(x), 1.0 / len(x))
        centres.append(x[rng.choice(len(x), p=p)])
        d2 = np.minimum(d2, np.sum((x - centres[-1]) ** 2, axis=1))
    c = np.array(centres)
    labels = np.zeros(len(x), dtype=np.int64)
    x2 = np.sum(x**2, 1)[:, None]
    for it in range(iters):
        dist = x2 - 2 * x @ c.T + np.sum(c**2, 1)[None, :]
        new = np.argmin(dist, axis=1)
        if it > 0 and (new == labels).all():
            break
        labels = new
        c = _group_means(x, labels, c)
    return labels


def _group_means(x: np.ndarray, labels: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``c`` with row j replaced by the mean of the rows of ``x`` labelled j (rows of empty groups kept): one
    stable sort, then each group's rows, a contiguous slice in their order in ``x``, averaged as
    ``x[labels == j].mean(0)`` averages them (the same bits), instead of one pass over ``x`` per group."""
    out = c.copy()
    xs = x[np.argsort(labels, kind="stable")]
    cuts = np.searchsorted(np.sort(labels), np.arange(len(c) + 1))
    for j in np.flatnonzero(np.diff(cuts)):
        out[j] = xs[cuts[j] : cuts[j + 1]].mean(axis=0)
    return out


def _groups(key: np.ndarray, n: int) -> list[np.ndarray]:
    """The indices of ``key`` (ints; negative ones belong to no group) equal to 0, 1, …, n − 1, each in increasing
    order: one stable sort instead of a pass over ``key`` per group."""
    order = np.argsort(key, kind="stable")
    cuts = np.searchsorted(key[order], np.arange(n + 1))
    return [order[cuts[j] : cuts[j + 1]] for j in range(n)]


def _envelope(t, values, n_control: int, floor: float, iters: int = 30) -> np.ndarray:
    """Control values of a least-squares cubic B-spline through ``values`` at ``t`` raised until it is ≥ every
    sample (targets lifted by the shortfall, up to ``iters`` rounds; then scaled by the last ratio), ≥ ``floor``."""
    target = values.copy()
    for _ in range(iters):
        sp = fit_bspline(t, target, n_control, 3)
        short = values - sp(t)[:, 0]
        if (short <= 1e-9 * values.max()).all():
            break
        target = target + np.maximum(short, 0.0)
    ctrl = np.maximum(sp.control[:, 0], floor)  # raising a control value only raises the curve (B-spline bases ≥ 0)
    fitted = BSpline.make(ctrl, sp.knots, 3)(t)[:, 0]
    return ctrl * max(1.0, float(np.max(values / np.maximum(fitted, 1e-300))))


def _extend(mean: np.ndarray, points: np.ndarray, n_control: int, rounds: int = 3, margin: float = 0.01):
    """A trajectory through ``mean`` (M, 3) lengthened at both ends, straight along its end tangents, until no
    point of ``points`` (P, 3) (the group's strands) lies beyond the first or last cross-section's plane.

    Each round fits the spline, finds the points whose nearest of 257 trajectory samples (a k-d tree over the
    samples) is an end one and that lie past its plane, and prepends/appends one point at the largest overhang (plus ``margin`` of the length).
    Returns (the spline, the largest distance of a point from its nearest sample)."""
    from scipy.spatial import cKDTree  # here, not at import: scipy.spatial costs half a second to load

    poly = mean
    ts = np.linspace(0.0, 1.0, 257)
    for _ in range(rounds + 1):
        seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
        t = np.concatenate([[0.0], np.cumsum(seg)]) / max(seg.sum(), 1e-300)
        traj = fit_bspline(t, poly, n_control, 3, field="trajectory")
        pos, tan = traj(ts), traj(ts, deriv=1)
        tan = tan / np.maximum(np.linalg.norm(tan, axis=1, keepdims=True), 1e-300)
        dist, near = cKDTree(pos).query(points)  # the nearest sample of each point (exact distances, as a brute force)
        along0 = (points - pos[0]) @ tan[0]
        along1 = (points - pos[-1]) @ tan[-1]
        over0 = np.max(-along0[near == 0], initial=0.0)
        over1 = np.max(along1[near == len(ts) - 1], initial=0.0)
        length = max(seg.sum(), 1e-300)
        if max(over0, over1) <= 1e-6 * length:
            break
        ext = []
        if over0 > 1e-6 * length:
            ext.append(pos[0] - tan[0] * (over0 + margin * length))
        ext.extend(poly)
        if over1 > 1e-6 * length:
            ext.append(pos[-1] + tan[-1] * (over1 + margin * length))
        poly = np.array(ext)
    return traj, float(dist.max(initial=0.0))


def fit_clusters(
    strands: Strands,
    n_clusters: int,
    *,
    layer_radii=_D["layer_radii"],
    core_radius: float = _D["core_radius"],
    s_t: int = _D["s_t"],
    s_v: int = _D["s_v"],
    s_u: int = _D["s_u"],
    n_control: int = 6,
    n_axis: int = 6,
    n_fit: int = 24,
    n_resample: int = 16,
    coverage: float = 0.95,
    extend: bool = True,
    min_half_axis: float | None = None,
    seed: int = 0,
) -> tuple[ClusterBatch, np.ndarray]:
    """Clusters following groups of nearby strands (module docstring); returns (batch, label per strand).

    Groups left empty by k-means, or whose mean strand has no length, are dropped (their
    strands get label −1); labels index the returned batch.  ``extend``: lengthen each trajectory
    past the group's strands' ends (off: through the mean strand only, as before).
    """
    if isinstance(n_clusters, bool) or not isinstance(n_clusters, (int, np.integer)) or not 1 <= n_clusters <= strands.n_strands:
        raise ValidationError("n_clusters", n_clusters, f"need 1 ≤ n_clusters ≤ {strands.n_strands} strands")
    if not 0 < coverage <= 1:
        raise ValidationError("coverage", coverage, "a fraction in (0, 1]")
    res = resample_strands(strands, n_resample)
    raw = kmeans(res.reshape(len(res), -1), int(n_clusters), seed)
    # a group whose mean strand has (almost) no length cannot carry a trajectory: dropped
    size = np.linalg.norm(np.ptp(res.reshape(-1, 3), axis=0))
    means = _group_means(res.reshape(len(res), -1), raw, np.zeros((int(n_clusters), n_resample * 3))).reshape(-1, n_resample, 3)
    for j in np.unique(raw):
        if np.linalg.norm(np.diff(means[j], axis=0), axis=1).sum() <= 1e-6 * size:
            raw[raw == j] = -1
    used = np.unique(raw[raw >= 0])
    labels = np.where(raw >= 0, np.searchsorted(used, raw), -1)
    if not used.size:
        raise ValidationError("strands", strands.n_strands, "no group of strands has a usable length")
    common = dict(layer_radii=layer_radii, core_radius=core_radius, s_t=s_t, s_v=s_v, s_u=s_u)
    pts = strands.points.astype(np.float64)
    point_groups = _groups(np.repeat(labels, strands.counts), used.size)  # each group's points, in the strands' order
    trajs, probes = [], []
    for j in range(used.size):
        mean = means[used[j]]
        if extend:
            traj, reach = _extend(mean, pts[point_groups[j]], n_control)
        else:
            seg = np.linalg.norm(np.diff(mean, axis=0), axis=1)
            t = np.concatenate([[0.0], np.cumsum(seg)]) / max(seg.sum(), 1e-300)
            traj = fit_bspline(t, mean, n_control, 3, field="trajectory")
            reach = np.linalg.norm(res[labels == j] - mean[None], axis=2).max()
        trajs.append(traj)
        probes.append(
            ClusterSpec(
                traj, 2.0 * reach + 1e-6, 2.0 * reach + 1e-6, layer_radii=(1.0,), core_radius=0.0, s_t=s_t, s_v=1, s_u=s_u
            )
        )
    probe = ClusterGeometry(probes)
    t_fit = np.linspace(0.0, 1.0, n_fit)
    x = _crossings(probe, strands, labels, np.zeros(strands.n_points), probe.sections(t_fit))
    sections = _groups(x["cluster"] * n_fit + x["t_index"], used.size * n_fit)  # each (cluster, section)'s crossings
    specs = []
    for j in range(used.size):
        floor = min_half_axis if min_half_axis is not None else 0.02 * probe.lengths[j]
        a_s, b_s = np.full(n_fit, np.nan), np.full(n_fit, np.nan)
        for i in range(n_fit):
            sel = sections[j * n_fit + i]
            if not sel.size:
                continue
            xa, ya = x["x"][sel], x["y"][sel]
            a0 = max(2.0 * xa.std(), floor)
            b0 = max(2.0 * ya.std(), floor)
            scale = np.quantile(np.hypot(xa / a0, ya / b0), coverage)
            a_s[i], b_s[i] = max(a0 * scale, floor), max(b0 * scale, floor)
        ok = np.isfinite(a_s)
        if ok.sum() >= n_axis:
            fa = _envelope(t_fit[ok], a_s[ok], n_axis, floor)
            fb = _envelope(t_fit[ok], b_s[ok], n_axis, floor)
        else:
            fa = np.full(n_axis, np.nanmax(a_s) if ok.any() else floor)
            fb = np.full(n_axis, np.nanmax(b_s) if ok.any() else floor)
        specs.append(ClusterSpec(trajs[j], fa, fb, **common))
    return ClusterBatch.stack(specs), labels.astype(np.int64)
