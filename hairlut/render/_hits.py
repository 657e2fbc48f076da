"""Which (ray, segment) pairs of a tile add optical depth, compacted per ray: the strand render's first pass.

A tile's candidates (``_tiles.bin_boxes``) are every segment whose screen box overlaps it, but one ray meets
only the few tubes it passes within √D2_CUT r of (``_strands.support``).  :func:`hit_kernel` evaluates each
pair's support only (no erfc, no sort) for all rays of a chunk of tiles; :func:`compact` keeps, per ray, the
segments it is ``near`` and groups the rays by how many, padded to a power of two K; a :class:`Queue` gathers
those rows into batches of fixed shape (N rays × K segments), so the second pass (the optical depths, shading,
sorting and compositing of ``_strand_march``) works on K ≪ M pairs per ray and compiles once per K.  A pair left
out has an empty support or a ray farther than √D2_CUT r from its axis: it adds no optical depth above float32
rounding, so both passes together compute what one dense pass over every candidate would.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ._strands import support

#: Rays of one group of tiles, pairs of one first-pass call (fixed: the first pass compiles once), the least K of
#: a row (K grows by factors of ``K_STEP``: few second-pass shapes) and the elements one second-pass batch may hold.
RAYS = 1 << 16
PAIRS = 1 << 20
#: Pairs whose lists the host builds at once (memory: about 20 bytes each).
HOST_PAIRS = 1 << 23
LEAST_K = 16
K_STEP = 4
BATCH = 1 << 21


@jax.jit
def hit_kernel(o, d, ray, seg, p0, t, length, radius, sigma_t, s_lo):
    """(P,) bool: whether ray ``ray`` (P,) (origins ``o``, unit directions ``d`` (R, 3), starting at ``s_lo``) can
    gather optical depth from segment ``seg`` (P,) (−1: padding)."""
    valid = seg >= 0
    ix = jnp.where(valid, seg, 0)
    near = support(o[ray], d[ray], *(a[ix] for a in (p0, t, length, radius, sigma_t)), s_lo)[-1]
    return near & valid


def tile_groups(buckets, group: int):
    """The occupied tiles of ``_tiles.bin_boxes``' buckets, ``group`` at a time whatever their widths: (tiles (n, 2),
    candidate counts (n,), candidates tile by tile (Σ counts,))."""
    if not buckets:
        return
    tiles = np.concatenate([b.tiles for b in buckets])
    count = np.concatenate([(b.index >= 0).sum(1) for b in buckets])
    cand = np.concatenate([b.index[b.index >= 0] for b in buckets])
    start = np.concatenate([[0], np.cumsum(count)])
    for s in range(0, len(tiles), group):
        e = min(s + group, len(tiles))
        yield tiles[s:e], count[s:e], cand[start[s] : start[e]]


def near_pairs(o, d, count: np.ndarray, cand: np.ndarray, per_tile: int, dev: tuple, s_lo: float):
    """(rays, segments) of the near pairs, ordered by ray, and the number of pairs tested, of n tiles whose rays are
    ``o``, ``d`` (``RAYS``, 3) (tile i: rays i·``per_tile`` … (i + 1)·``per_tile`` − 1) against their ``count`` (n,)
    candidates ``cand`` (tile by tile).  The pair lists are built ``HOST_PAIRS`` at a time (whole tiles)."""
    count = count.astype(np.int32)
    block = per_tile * count.astype(np.int64)
    first = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    rays, segs, total, t0 = [], [], int(block.sum()), 0
    while t0 < len(count):
        t1 = t0 + max(1, int(np.searchsorted(np.cumsum(block[t0:]), HOST_PAIRS, side="right")))
        b = block[t0:t1].astype(np.int32)
        tile = np.repeat(np.arange(t0, t1, dtype=np.int32), b)
        q = np.arange(int(b.sum()), dtype=np.int32) - np.repeat(np.cumsum(b, dtype=np.int32) - b, b)
        r, j = np.divmod(q, count[tile])
        kept = keep_near(o, d, tile * np.int32(per_tile) + r, cand[first[tile] + j].astype(np.int32), dev, s_lo)
        rays.append(kept[0])
        segs.append(kept[1])
        t0 = t1
    if not rays:
        return np.zeros(0, np.int32), np.zeros(0, np.int32), 0
    return np.concatenate(rays), np.concatenate(segs), total


def keep_near(o, d, ray: np.ndarray, seg: np.ndarray, dev: tuple, s_lo: float) -> tuple[np.ndarray, np.ndarray]:
    """The pairs (``ray``, ``seg``) (int32, (P,)) of rays ``o``, ``d`` (R, 3) that can gather optical depth
    (:func:`hit_kernel`, ``PAIRS`` at a time), in their order."""
    rays, segs = [np.zeros(0, np.int32)], [np.zeros(0, np.int32)]
    for s in range(0, len(ray), PAIRS):
        rr, gg = ray[s : s + PAIRS], seg[s : s + PAIRS]
        pad = PAIRS - len(rr)
        if pad:
            rr, gg = np.concatenate([rr, np.zeros(pad, np.int32)]), np.concatenate([gg, np.full(pad, -1, np.int32)])
        keep = np.flatnonzero(np.asarray(hit_kernel(o, d, rr, gg, *dev, s_lo))[: len(ray) - s])
        rays.append(rr[keep])
        segs.append(gg[keep])
    return np.concatenate(rays), np.concatenate(segs)


def _width(count: np.ndarray) -> np.ndarray:
    """Each count padded to a power of ``K_STEP`` times ``LEAST_K``."""
    k = np.ceil(np.log(np.maximum(count, 1) / LEAST_K) / np.log(K_STEP) - 1e-9).clip(0).astype(np.int64)
    return LEAST_K * K_STEP**k


def compact(ray: np.ndarray, seg: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """{K: (rays (H,), segments (H, K))}: the near pairs (``ray`` non-decreasing, ``seg``) as one row per ray, grouped
    by the ray's count padded to K (:func:`_width`), with its segments (−1: padding)."""
    if ray.size == 0:
        return {}
    rays, start, count = np.unique(ray, return_index=True, return_counts=True)
    owner = np.repeat(np.arange(rays.size), count)
    pos = np.arange(ray.size) - start[owner]
    widths = _width(count)
    out = {}
    for k in np.unique(widths):
        sel = widths == k
        row = np.cumsum(sel) - 1  # each selected ray's row in this group
        rows = np.full((int(sel.sum()), int(k)), -1, np.int32)
        pick = sel[owner]
        rows[row[owner[pick]], pos[pick]] = seg[pick]
        out[int(k)] = (rays[sel], rows)
    return out


class Queue:
    """Rows (an id, K segments and per-row arrays) queued per K and handed to ``run(k, ids, segments, *arrays)`` in
    batches of ``rows(k)``; :meth:`flush` pads the last batch of each K (id −1, no segments)."""

    def __init__(self, rows, run):
        self.rows, self.run, self.pending = rows, run, {}

    def put(self, k: int, ids, segments, *arrays) -> None:
        got = self.pending.setdefault(k, [])
        got.append((ids, segments, *arrays))
        n = self.rows(k)
        while sum(len(g[0]) for g in got) >= n:
            cat = [np.concatenate(c) for c in zip(*got)]
            self.run(k, *(c[:n] for c in cat))
            got[:] = [tuple(c[n:] for c in cat)]

    def flush(self) -> None:
        for k, got in self.pending.items():
            cat = [np.concatenate(c) for c in zip(*got)]
            if len(cat[0]) == 0:
                continue
            pad = self.rows(k) - len(cat[0])
            ids = np.concatenate([cat[0], np.full(pad, -1, cat[0].dtype)])
            segs = np.concatenate([cat[1], np.full((pad, k), -1, cat[1].dtype)])
            rest = [np.concatenate([c, np.repeat(c[:1], pad, 0)]) for c in cat[2:]]
            self.run(k, ids, segs, *rest)
        self.pending = {}


def batch_rows(per_row: int) -> int:
    """Rows of one second-pass batch: a power of two with rows × ``per_row`` ≤ ``BATCH`` (at least 16)."""
    return max(16, 1 << int(np.log2(max(BATCH // max(per_row, 1), 1))))
