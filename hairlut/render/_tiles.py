"""Screen tiles and the primitives that may touch them (host side, NumPy): the spatial index of both renderers.

:func:`bin_boxes` takes each primitive's screen bounding box (pixels, inclusive) and returns, per
occupied tile, the indices of the primitives whose box overlaps it, grouped in buckets of equal
padded width (8, 16, 32, …) so that a jitted kernel sees few distinct shapes.  A tile that no
primitive touches is not listed (it stays background).  :func:`pairs_of` pairs a layer mesh's triangles
for the layered render's rasteriser, :func:`candidates` bounds the candidate pixels a tile's pairs need, and
``_bucket`` rounds a count up to few compile shapes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Bucket:
    """Tiles of one padded width: ``tiles`` (n, 2) tile column/row, ``index`` (n, width) primitive indices
    (−1: padding)."""

    tiles: np.ndarray
    index: np.ndarray

    @property
    def width(self) -> int:
        return self.index.shape[1]


def _bucket_width(n: int, least: int = 8) -> int:
    return 1 << (max(int(n), least) - 1).bit_length()


def bin_sorted(x0, x1, y0, y1, shape: tuple[int, int], tile: int) -> tuple[np.ndarray, np.ndarray]:
    """Every (tile, primitive) overlap of boxes [x0, x1] × [y0, y1] (pixel units) on a frame of ``shape`` = (w, h)
    pixels cut into ``tile`` × ``tile`` tiles, boxes wholly off the frame dropped: (tile ids ty·nx + tx, primitive
    indices), both (E,), sorted by tile id (stably: primitives in index order within a tile)."""
    w, h = shape
    nx, ny = -(-w // tile), -(-h // tile)
    x0, x1, y0, y1 = (np.asarray(a, np.float64) for a in (x0, x1, y0, y1))
    keep = np.isfinite(x0 + x1 + y0 + y1) & (x1 >= 0) & (y1 >= 0) & (x0 < w) & (y0 < h)
    prim = np.flatnonzero(keep)
    tx0 = np.clip(np.floor(x0[prim] / tile), 0, nx - 1).astype(np.int64)
    tx1 = np.clip(np.floor(x1[prim] / tile), 0, nx - 1).astype(np.int64)
    ty0 = np.clip(np.floor(y0[prim] / tile), 0, ny - 1).astype(np.int64)
    ty1 = np.clip(np.floor(y1[prim] / tile), 0, ny - 1).astype(np.int64)
    cw, ch = tx1 - tx0 + 1, ty1 - ty0 + 1
    count = cw * ch
    owner = np.repeat(np.arange(prim.size), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    tile_id = (ty0[owner] + k // cw[owner]) * nx + tx0[owner] + k % cw[owner]
    order = np.argsort(tile_id, kind="stable")
    return tile_id[order], prim[owner[order]]


def bin_boxes(x0, x1, y0, y1, shape: tuple[int, int], tile: int) -> list[Bucket]:
    """Buckets of (tile, candidate primitives) for boxes [x0, x1] × [y0, y1] in pixel units on a frame of
    ``shape`` = (w, h) pixels cut into ``tile`` × ``tile`` tiles; boxes wholly off the frame are dropped."""
    nx = -(-shape[0] // tile)
    tile_id, cand = bin_sorted(x0, x1, y0, y1, shape, tile)
    if tile_id.size == 0:
        return []
    ids, start, n = np.unique(tile_id, return_index=True, return_counts=True)
    widths = np.array([_bucket_width(c) for c in n])
    out = []
    for wd in np.unique(widths):
        sel = np.flatnonzero(widths == wd)
        index = np.full((sel.size, wd), -1, np.int64)
        for row, j in enumerate(sel):
            index[row, : n[j]] = cand[start[j] : start[j] + n[j]]
        out.append(Bucket(np.stack([ids[sel] % nx, ids[sel] // nx], 1), index))
    return out


def chunks(bucket: Bucket, per_tile: int, budget: int):
    """(tiles, index) slices of a bucket, a power-of-two number of tiles at a time so that tiles × ``per_tile``
    elements stay within ``budget``; the last slice is padded with copies of its first tile (drop them)."""
    n = len(bucket.tiles)
    size = 1 << max(0, int(np.log2(max(budget // max(per_tile, 1), 1))))
    size = min(size, _bucket_width(n, 1))
    for s in range(0, n, size):
        t, ix = bucket.tiles[s : s + size], bucket.index[s : s + size]
        pad = size - len(t)
        if pad:
            t = np.concatenate([t, np.repeat(t[:1], pad, 0)])
            ix = np.concatenate([ix, np.repeat(ix[:1], pad, 0)])
        yield s, min(s + size, n) - s, t, ix


def _bucket(n: float) -> int:
    """n rounded up to a multiple of an eighth of its power of two (few compile shapes, ≤ 12.5 % waste)."""
    p = 1 << max(int(math.ceil(n)) - 1, 1).bit_length()
    step = max(p // 8, 256)
    return int(step * math.ceil(n / step))


def pairs_of(triangles) -> np.ndarray:
    """(T, 3) triangles → (⌈T/2⌉, 2, 3) consecutive pairs (a grid quad's two; an odd last one pairs with a
    degenerate copy of itself, which covers nothing)."""
    tri = np.asarray(triangles, np.int32).reshape(-1, 3)
    if len(tri) % 2:
        tri = np.concatenate([tri, tri[-1:, [0, 0, 0]]])
    return tri.reshape(-1, 2, 3)


def candidates(cam, vertices, pairs, origins, tile) -> int:
    """The most candidate pixels (pair boxes clipped to the tile) any cluster needs, from a float64 projection."""
    x, y, _ = cam.project(vertices)  # (C, K, V)
    th, tw = tile
    x = x - np.asarray(origins)[:, 0, None, None]
    y = y - np.asarray(origins)[:, 1, None, None]
    px, py = x[..., pairs], y[..., pairs]  # (C, K, P, 2, 3)
    x0 = np.clip(np.ceil(px.min(axis=(-2, -1)) - 0.5), 0, tw)
    x1 = np.clip(np.floor(px.max(axis=(-2, -1)) - 0.5), -1, tw - 1)
    y0 = np.clip(np.ceil(py.min(axis=(-2, -1)) - 0.5), 0, th)
    y1 = np.clip(np.floor(py.max(axis=(-2, -1)) - 0.5), -1, th - 1)
    n = np.maximum(x1 - x0 + 1, 0) * np.maximum(y1 - y0 + 1, 0)
    return int(n.reshape(len(n), -1).sum(-1).max(initial=0))
