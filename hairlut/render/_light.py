"""Optical depth toward a light through the strands' tubes: the strand render's shadows (``_strand_march``).

τ_l(x) = ∫₀^∞ σ_t ρ(x + s·l) ds, the exact line integral of every segment's density from x toward the light
direction l (``_strands``: one erfc pair per crossing), and the transmittance T_l(x) = exp(−τ_l(x)).

**At any points** (:func:`point_depths`, what the strand render uses since its shadow term must converge with the
image, not with a grid).  A light's :class:`LightIndex` bins the segments' tubes (cut at ``Z_CUT`` r) on the plane
across the light into square tiles of ``LIGHT_TILE`` median radii, each tile's segments sorted by how far toward
the light their tube reaches.  A point's shadow ray tests only the segments of its tile that reach beyond it
(``_hits.keep_near``) and integrates the near ones exactly from the point on (:func:`shadow_kernel`, one node).
Memory: the index's (tile, segment) entries, about (box side / tile + 1)² per segment whatever the hair's
bounds, and a batch of points at a time; work: one shadow ray per point.

**On a grid** (:func:`shadow_grid`, :func:`grid_depths`): the nodes of a light-aligned grid over the hair's
bounds, each column of nodes one ray toward the light whose crossings are found once and integrated from every
node on, interpolated trilinearly between nodes.  At a node both paths compute the same integral (to float32
rounding, tests); the grid's work and memory grow as the bounds' volume / cell³ (Ratboy at a cell of 2 median
radii: about 10⁹ nodes, 8 GB), the points' as the image's samples, so the strand render takes the grid only
while it is small (``_strand_march.GRID_NODES``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import erfc

from .. import budget
from ._hits import HOST_PAIRS, RAYS, Queue, batch_rows, compact, keep_near, near_pairs, tile_groups
from ._strands import Z_CUT, Segments, support, tail_diff
from ._tiles import bin_boxes, bin_sorted

#: The light index's tile side, in median strand radii.
LIGHT_TILE = 2.0
#: Grid columns per tile side (:func:`shadow_grids`) and the multiple its depth (nodes along the light) is rounded to.
TILE = 8
DEPTH_STEP = 16


def frame_of(direction) -> np.ndarray:
    """Rows (right, up, back): an orthonormal frame whose third axis is the unit ``direction``."""
    back = np.asarray(direction, np.float64) / np.linalg.norm(direction)
    helper = np.array([0.0, 1.0, 0.0]) if abs(back[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(helper, back)
    right /= np.linalg.norm(right)
    return np.stack([right, np.cross(back, right), back])


@partial(jax.jit, static_argnames=("depth",))
def shadow_kernel(o, d, cand, cell, p0, t, length, radius, sigma_t, *, depth: int):
    """Optical depth toward the light ``d`` (3,) from the nodes o + k·cell·d (k < ``depth``) of N columns (origins
    ``o`` (N, 3)) through their near segments ``cand`` (N, K) (−1: none): (N, depth).  The column's crossing
    geometry is found once; each node integrates the part of the support beyond it (one erfc per node)."""
    valid = cand >= 0
    ix = jnp.where(valid, cand, 0)
    seg = [a[ix] for a in (p0, t, length, radius, sigma_t)]
    sa, sb, mu, scale, slanted, peak, _ = support(o[:, None], d, *seg, -1e20)  # (N, K)
    sk = jnp.arange(depth, dtype=jnp.float32) * cell
    a = jnp.maximum(sa[..., None], sk)  # (N, K, depth)
    zb = (sb - mu) / scale
    za = (a - mu[..., None]) / scale[..., None]
    part = scale[..., None] * tail_diff(za, zb[..., None], erfc(jnp.abs(za)), erfc(jnp.abs(zb))[..., None])
    integral = jnp.where(a < sb[..., None], jnp.where(slanted[..., None], part, sb[..., None] - a), 0.0)
    tau = jnp.where(valid[..., None], peak[..., None] * jnp.maximum(integral, 0.0), 0.0)
    return tau.sum(1)


def _light_boxes(segs: Segments, axes: np.ndarray):
    """Each segment's tube (cut at ``Z_CUT`` r) in the light's frame: (u0, u1, v0, v1, top), top the farthest its
    tube reaches toward the light."""
    p1 = segs.p0 + segs.tangent * segs.length[:, None]
    a, b = segs.p0 @ axes.T, p1 @ axes.T
    reach = Z_CUT * segs.radius
    lo, hi = np.minimum(a, b) - reach[:, None], np.maximum(a, b) + reach[:, None]
    return lo[:, 0], hi[:, 0], lo[:, 1], hi[:, 1], hi[:, 2]


@dataclass(frozen=True, eq=False)
class LightIndex:
    """One light's segments binned across it (module docstring): ``axes`` (3, 3) (the third toward the light),
    tile ``origin`` (2,) and side ``tile``, ``shape`` (nx, ny) tiles; the entries sorted by ``key`` = tile id ·
    ``span`` + (top − ``top0``) with their segments ``cand``."""

    axes: np.ndarray
    origin: np.ndarray
    tile: float
    shape: tuple[int, int]
    top0: float
    span: float
    key: np.ndarray
    cand: np.ndarray


def light_index(segs: Segments, light, tile: float | None = None) -> LightIndex:
    """The :class:`LightIndex` of the light direction ``light`` (toward the light) with tiles of side ``tile``
    (default ``LIGHT_TILE`` median radii); its size is checked against the memory budget first."""
    tile = LIGHT_TILE * float(np.median(segs.radius)) if tile is None else float(tile)
    axes = frame_of(light)
    u0, u1, v0, v1, top = _light_boxes(segs, axes)
    origin = np.array([u0.min(), v0.min()])
    shape = (int(np.floor((u1.max() - origin[0]) / tile)) + 1, int(np.floor((v1.max() - origin[1]) / tile)) + 1)
    x0, x1, y0, y1 = (u0 - origin[0]) / tile, (u1 - origin[0]) / tile, (v0 - origin[1]) / tile, (v1 - origin[1]) / tile
    entries = float(((np.floor(x1) - np.floor(x0) + 1) * (np.floor(y1) - np.floor(y0) + 1)).sum())
    budget.check("strands", f"{segs.n} segments", 40 * entries, f"a light's shadow index ({entries:.3g} (tile, segment) entries)")
    tid, prim = bin_sorted(x0, x1, y0, y1, shape, 1)
    top0 = float(top.min())
    span = float(top.max() - top0) + 1.0
    key = tid * span + (top[prim] - top0)
    order = np.argsort(key, kind="stable")
    return LightIndex(axes, origin, tile, shape, top0, span, key[order], prim[order].astype(np.int32))


def point_depths(index: LightIndex, points, dev: tuple, stats: dict | None = None) -> np.ndarray:
    """τ (P,) float32: the exact optical depth from each of ``points`` (P, 3) toward ``index``'s light through the
    segments ``dev`` (``Segments.device()``); ``stats`` gains the points and the pairs tested and kept."""
    q = np.asarray(points, np.float64) @ index.axes.T
    n_pts = len(q)
    out = np.zeros(n_pts, np.float32)
    fu = np.floor((q[:, 0] - index.origin[0]) / index.tile)
    fv = np.floor((q[:, 1] - index.origin[1]) / index.tile)
    inside = (fu >= 0) & (fu < index.shape[0]) & (fv >= 0) & (fv < index.shape[1])
    tid = np.where(inside, fv * index.shape[0] + fu, 0.0)
    margin = 1e-3 * index.tile  # below the key's rounding: keeps a segment whose top is level with the point
    height = np.clip(q[:, 2] - index.top0 - margin, 0.0, index.span - 0.5)  # within the tile's key range
    start = np.searchsorted(index.key, tid * index.span + height)
    count = np.where(inside, np.searchsorted(index.key, (tid + 1) * index.span) - start, 0)
    cum = np.concatenate([[0], np.cumsum(count)])
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    d32 = f32(index.axes[2])
    d_all = jnp.broadcast_to(d32, (RAYS, 3))

    def run(k, ids, cand, o):
        tau = np.asarray(shadow_kernel(f32(o), d32, jnp.asarray(cand), f32(0.0), *dev, depth=1))[:, 0]
        good = ids >= 0
        out[ids[good]] = tau[good]

    queue = Queue(lambda k: batch_rows(8 * k), run)
    kept, s = 0, 0
    while s < n_pts:
        e = min(n_pts, s + RAYS)
        e = s + max(1, int(np.searchsorted(cum[s + 1 : e + 1] - cum[s], HOST_PAIRS, side="right")))
        c = count[s:e]
        o = np.zeros((RAYS, 3), np.float32)
        o[: e - s] = points[s:e]
        ray = np.repeat(np.arange(e - s, dtype=np.int32), c)
        seg = index.cand[np.repeat(start[s:e], c) + np.arange(int(c.sum())) - np.repeat(cum[s:e] - cum[s], c)]
        rays, near = keep_near(f32(o), d_all, ray, seg, dev, 0.0)
        kept += len(rays)
        for k, (r, rows) in compact(rays, near).items():
            queue.put(k, r + s, rows, o[r])
        s = e
    queue.flush()
    if stats is not None:
        for name, v in (("shadow_points", n_pts), ("shadow_pairs", int(cum[-1])), ("shadow_near_pairs", kept)):
            stats[name] = stats.get(name, 0) + v
    return out


def _light_frame(segs: Segments, light, cell: float):
    """A light's grid: (axes (3, 3), origin (3,), (nx, ny, nz)) covering the hair's bounds."""
    axes = frame_of(light)
    lo, hi = segs.bounds()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    lc = corners @ axes.T
    l_lo, l_hi = lc.min(0), lc.max(0)
    return axes, l_lo @ axes, tuple(int(x) for x in np.ceil((l_hi - l_lo) / cell).astype(int) + 2)


def shadow_grids(segs: Segments, lights, cell: float, stats: dict | None = None) -> list:
    """Each light's exact optical-depth grid (:func:`shadow_kernel`): [(τ (nx, ny, nz), origin, axes (3, 3))], node
    (i, j, k) at origin + cell·(i, j, k) @ axes.  One static depth (the deepest grid's, in multiples of
    ``DEPTH_STEP``) serves every light: fewer compiles.  The grids' size is checked against the memory budget."""
    frames = [_light_frame(segs, light, cell) for light in lights]
    nodes = sum(float(np.prod(f[2])) for f in frames)
    budget.check("cell", cell, 4 * nodes, f"the shadow grids ({nodes:.3g} nodes, float32)")
    depth = DEPTH_STEP * -(-max(f[2][2] for f in frames) // DEPTH_STEP)
    dev = segs.device()
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    ij = np.stack(np.meshgrid(np.arange(TILE), np.arange(TILE), indexing="ij"), -1).reshape(-1, 2)  # column in tile
    group = RAYS // (TILE * TILE)
    out = []
    for axes, origin, (nx, ny, nz) in frames:
        u0, u1, v0, v1, _ = _light_boxes(segs, axes)
        o2 = origin @ axes[:2].T
        buckets = bin_boxes((u0 - o2[0]) / cell, (u1 - o2[0]) / cell, (v0 - o2[1]) / cell, (v1 - o2[1]) / cell, (nx, ny), TILE)
        ny_p = -(-ny // TILE) * TILE
        grid = np.zeros((-(-nx // TILE) * TILE * ny_p, nz), np.float32)
        d32 = f32(axes[2])
        d_all = jnp.broadcast_to(d32, (RAYS, 3))

        def run(k, ids, cand, o, grid=grid, d32=d32, nz=nz):
            tau = np.asarray(shadow_kernel(f32(o), d32, jnp.asarray(cand), f32(cell), *dev, depth=depth))
            good = ids >= 0
            grid[ids[good]] = tau[good, :nz]

        queue = Queue(lambda k: batch_rows(k * depth), run)
        for tl, count, cand in tile_groups(buckets, group):
            g = tl[:, None, :] * TILE + ij[None]  # (n, 64, 2) node columns (i, j)
            o = np.zeros((RAYS, 3), np.float32)
            o[: g.shape[0] * g.shape[1]] = (origin + cell * (g[..., :1] * axes[0] + g[..., 1:] * axes[1])).reshape(-1, 3)
            ray, seg, pairs = near_pairs(f32(o), d_all, count, cand, TILE * TILE, dev, -1e20)
            col = (g[..., 0] * ny_p + g[..., 1]).reshape(-1)
            for k, (rays, near) in compact(ray, seg).items():
                queue.put(k, col[rays], near, o[rays])
            if stats is not None:
                stats["column_pairs"] = stats.get("column_pairs", 0) + pairs
                stats["column_near_pairs"] = stats.get("column_near_pairs", 0) + len(ray)
        queue.flush()
        out.append((grid.reshape(-1, ny_p, nz)[:nx, :ny], origin, axes))
    return out


def shadow_grid(segs: Segments, light, cell: float):
    """A light's exact optical-depth grid (:func:`shadow_grids`): (τ (nx, ny, nz), origin, axes (3, 3))."""
    return shadow_grids(segs, [light], cell)[0]


def grid_depths(grid: np.ndarray, origin: np.ndarray, axes: np.ndarray, cell: float, points) -> np.ndarray:
    """τ (P,) of a :func:`shadow_grid` (``grid`` (nx, ny, nz), ``origin``, ``axes``, ``cell``) at ``points`` (P, 3),
    interpolated trilinearly (clamped to the grid)."""
    g = (np.asarray(points, np.float64) - origin) @ axes.T / cell
    hi = np.array(grid.shape, np.float64) - 1.0
    g = np.clip(g, 0.0, hi)
    i0 = np.minimum(np.floor(g), hi - 1.0).astype(np.int64)
    f = g - i0
    out = np.zeros(len(g))
    for c in range(8):
        o = ((c >> 2) & 1, (c >> 1) & 1, c & 1)
        w = np.prod([f[:, a] if o[a] else 1.0 - f[:, a] for a in range(3)], axis=0)
        out += w * grid[i0[:, 0] + o[0], i0[:, 1] + o[1], i0[:, 2] + o[2]]
    return out.astype(np.float32)


def grid_nodes(segs: Segments, lights, cell: float) -> float:
    """The nodes of the lights' :func:`shadow_grids` at ``cell``."""
    return sum(float(np.prod(_light_frame(segs, light, cell)[2])) for light in lights)
