"""The layered model's frame in two passes: the fragments, once per camera and geometry, then the texturing, per frame.

What a pixel shows of the layer meshes (which layer surfaces cover it, where in their textures, in which order)
depends on the camera and the geometry only; the online maps (the textures) change every frame.  So:

1. :func:`plan_fragments` (once per camera and geometry): :func:`surface_kernel` rasterises every cluster's layer
   surfaces (``_raster.surfaces``: coverage, perspective-correct (u, t), the nearest fragment per layer surface and
   pixel), and the host lists the drawn fragments in compositing order: per pixel, the clusters by their nearest
   depth (ties: the lower index first) and within a cluster eq 14's surface order (``_raster.surface_order``).
   The fragments are stored in *depth slabs*: the pixels sorted by their number of fragments, most first, slab d
   holds every pixel's d-th fragment, so slab d is a prefix of the pixel list and compositing needs no sort, no
   scatter and no per-pixel loop.  Each fragment keeps its bilinear texel cell (``_raster.texel_cell``) and the
   two weights.
2. :func:`composite_kernel` (per frame; one jitted kernel with static shapes): gathers each fragment's 2 × 2 texels
   from the textures, interpolates (``_raster.bilerp``), and composites the slabs front to back,
   Ψ = Σ_f Ψ_f α_f Π_{g before f} (1 − α_g) (eq 14 between a cluster's layers, "over" between clusters).

The result equals :func:`~hairlut.render._raster.raster_kernel`'s (the one-pass reference) to float32 rounding: the
same fragments, texels and weights, composited in the same order (the reference multiplies the nearer clusters'
transmittances through exp Σ ln(1 − α); here they are multiplied in turn).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import budget, errors
from ._raster import FAR, bilerp, surface_order, surfaces, texel_cell

#: Bytes the camera pass holds per layer-surface slot of a tile: depth and (u, t) (float32), and, for a drawn
#: fragment, its host-side index and key arrays (int64) while they are ordered.
SLOT_BYTES = 12 + 8 * 8


@partial(jax.jit, static_argnames=("size", "tile", "cap"))
def surface_kernel(verts, origins, pairs, uv, matrix, eye, back, *, size, tile, cap):
    """Every cluster's layer surfaces (``_raster.surfaces``): depth (C, 2K, th, tw) (inf: not drawn), texture
    coordinates (C, 2K, th, tw, 2) and the most candidate pixels a cluster needed (> ``cap``: run again larger).
    Arguments as :func:`~hairlut.render._raster.raster_kernel`'s, less the textures."""
    one = partial(surfaces, pairs=pairs, uv=uv, matrix=matrix, eye=eye, back=back, size=size, tile=tile, cap=cap)
    z, tuv, need = jax.lax.map(lambda a: one(*a), (verts, origins))
    return z, tuv, jnp.max(need)


@partial(jax.jit, static_argnames=("n_t", "n_u"))
def _cells_of(u, t, layer, *, n_t, n_u):
    """Each fragment's texel cell (row i0 of the cell table of :func:`composite_kernel`) and weights (ws, wr)."""
    i0, _, j0, _, ws, wr = texel_cell(u, t, n_t, n_u)
    return (layer * max(n_t - 1, 1) + i0) * n_u + j0, jnp.stack([ws, wr], -1)


@dataclass(frozen=True, eq=False)
class FragmentPlan:
    """The fragments of one camera and geometry (module docstring): ``cell`` (F,) int32 texel cells and ``weight``
    (F, 2) bilinear weights, slab after slab; ``slabs`` the slab sizes (static); ``source`` (h·w,) each pixel's
    row in the slabs (``slabs[0]``: none); ``depth`` (h, w) the nearest eye depth (``FAR``: nothing drawn);
    ``textures`` the (C, K, n_t, n_u) texture shape it was planned for; ``info`` counts and seconds."""

    cell: jax.Array
    weight: jax.Array
    source: jax.Array
    slabs: tuple
    depth: np.ndarray
    size: tuple
    textures: tuple
    info: dict


def order_fragments(z, tuv, origins, size, n_t: int, n_u: int):
    """Host side of :func:`plan_fragments`: the drawn fragments of ``z`` (C, 2K, th, tw) / ``tuv`` in compositing
    order, laid out in depth slabs.  Returns (cell, weight, source, slabs, depth)."""
    W, H = size
    C, S, th, tw = z.shape
    drawn = np.isfinite(z)
    if not drawn.any():  # a frame that catches no hair: no slabs, every pixel the composite's empty last row
        return (
            np.zeros(0, np.int32),
            np.zeros((0, 2), np.float32),
            np.zeros(W * H, np.int32),
            (),
            np.full((H, W), FAR, np.float32),
        )
    near = np.where(drawn, z, np.inf).min(1)  # (C, th, tw)
    ox, oy = np.asarray(origins, np.int64)[:, 0], np.asarray(origins, np.int64)[:, 1]
    # clusters at each pixel, nearest first (ties: the lower index), as in the reference's composite
    cc, yy, xx = np.nonzero(np.isfinite(near))
    gpix = (oy[cc] + yy) * W + ox[cc] + xx
    o = np.lexsort((cc, near[cc, yy, xx], gpix))
    gs = gpix[o]
    first = np.r_[True, gs[1:] != gs[:-1]]
    group = np.cumsum(first) - 1
    rank = np.empty(len(o), np.int64)
    rank[o] = np.arange(len(o)) - np.flatnonzero(first)[group]
    crank = np.zeros((C, th, tw), np.int64)
    crank[cc, yy, xx] = rank
    # fragments: key (pixel, cluster rank, surface rank)
    srank = np.empty(S, np.int64)
    srank[surface_order(S // 2)] = np.arange(S)
    fc, fs, fy, fx = np.nonzero(drawn)
    fpix = (oy[fc] + fy) * W + ox[fc] + fx
    key = (fpix * C + crank[fc, fy, fx]) * S + srank[fs]
    o = np.argsort(key, kind="stable")
    fc, fs, fy, fx, fpix = fc[o], fs[o], fy[o], fx[o], fpix[o]
    fz = z[fc, fs, fy, fx]
    # per pixel: its fragments' count and each fragment's place d in the pixel's list
    first = np.r_[True, fpix[1:] != fpix[:-1]]
    starts = np.flatnonzero(first)
    pix = fpix[starts]
    count = np.diff(np.r_[starts, len(fpix)])
    d = np.arange(len(fpix)) - np.repeat(starts, count)
    # slabs: pixels with the most fragments first, so slab d is a prefix of the pixel list
    porder = np.argsort(-count, kind="stable")
    prank = np.empty(len(pix), np.int64)
    prank[porder] = np.arange(len(pix))
    slabs = tuple(int(n) for n in np.bincount(count, minlength=1)[::-1].cumsum()[::-1][1:]) if len(pix) else ()
    slab_start = np.r_[0, np.cumsum(slabs)].astype(np.int64)
    dest = slab_start[d] + np.repeat(prank, count)
    # each fragment's texel cell and weights, in slab order
    u, t = tuv[fc, fs, fy, fx, 0], tuv[fc, fs, fy, fx, 1]
    layer = fc * (S // 2) + fs // 2
    cell, weight = _cells_of(
        jnp.asarray(u, jnp.float32), jnp.asarray(t, jnp.float32), jnp.asarray(layer, jnp.int32), n_t=n_t, n_u=n_u
    )
    inv = np.empty(len(dest), np.int64)
    inv[dest] = np.arange(len(dest))
    cell, weight = np.asarray(cell)[inv], np.asarray(weight)[inv]
    source = np.full(W * H, len(pix), np.int32)  # the composite's last row stays empty
    source[pix] = prank
    depth = np.full(W * H, FAR, np.float32)
    if len(pix):
        depth[pix] = np.minimum.reduceat(fz, starts)
    return cell, weight, source, slabs, depth.reshape(H, W)


def plan_fragments(
    cam, vertices, triangles, uv, texture_shape, *, tile, origins, keep=None, limit: int | None = None
) -> FragmentPlan:
    """The :class:`FragmentPlan` of (C, K, V, 3) ``vertices`` (triangles (T, 3), uv (V, 2) shared) through ``cam``,
    for textures of shape (C, K, n_t, n_u) (module docstring, step 1); ``tile``/``origins`` as ``_layered.layout``
    gives them.  ``keep``: (C, th, tw) bool on the same tiles, the pixels where each cluster may draw (the trim,
    ``_trim.strand_footprints``); a cluster's fragments elsewhere are dropped (None: all kept).  Refuses (``BudgetError``) when the camera pass would not fit the memory budget (``limit``: bytes,
    default ``hairlut.budget.memory_limit()``)."""
    from ._tiles import _bucket, candidates, pairs_of

    t0 = time.perf_counter()
    f32 = jnp.float32
    C, K, n_t, n_u = (int(n) for n in texture_shape[:4])
    if vertices.shape[:2] != (C, K):
        raise errors.ValidationError("textures", list(texture_shape), f"need (C, K) = {list(vertices.shape[:2])} first")
    th, tw = (int(t) for t in tile)
    # the surface buffers (depth, u, t) and, at most one fragment per buffer slot, the host's fragment arrays
    budget.check(
        "camera.resolution",
        [cam.width, cam.height],
        budget.product(C, 2 * K, th, tw, SLOT_BYTES),
        f"the camera pass's {C} clusters x {2 * K} layer surfaces on {th} x {tw}-pixel tiles",
        limit,
    )
    pairs = pairs_of(triangles)
    args = (
        jnp.asarray(vertices, f32),
        jnp.asarray(origins, jnp.int32),
        jnp.asarray(pairs, jnp.int32),
        jnp.asarray(uv, f32),
        jnp.asarray(cam.matrix, f32),
        jnp.asarray(cam.eye, f32),
        jnp.asarray(cam.back, f32),
    )
    size = (cam.width, cam.height)
    kw = {"size": size, "tile": tuple(int(t) for t in tile)}
    cap = _bucket(1.02 * candidates(cam, vertices, pairs, origins, tile) + 64)
    z, tuv, need = surface_kernel(*args, **kw, cap=cap)
    if int(need) > cap:
        cap = _bucket(int(need))
        z, tuv, need = surface_kernel(*args, **kw, cap=cap)
    z, tuv = np.asarray(z), np.asarray(tuv)
    trimmed = 0
    if keep is not None:
        keep = np.asarray(keep, bool)
        if keep.shape != (C, th, tw):
            raise errors.ValidationError("keep", list(keep.shape), f"need (C, th, tw) = {[C, th, tw]}")
        drop = np.isfinite(z) & ~keep[:, None]
        trimmed = int(drop.sum())
        z = np.where(drop, np.inf, z)
    t1 = time.perf_counter()
    cell, weight, source, slabs, depth = order_fragments(z, tuv, origins, size, n_t, n_u)
    info = {
        "fragments": int(len(cell)),
        "trimmed": trimmed,
        "pixels": int(slabs[0]) if slabs else 0,
        "slabs": len(slabs),
        "candidates_per_cluster": cap,
        "seconds": {"surfaces": t1 - t0, "order": time.perf_counter() - t1},
    }
    return FragmentPlan(
        jnp.asarray(cell, jnp.int32),
        jnp.asarray(weight, f32),
        jnp.asarray(source, jnp.int32),
        slabs,
        depth,
        size,
        (C, K, n_t, n_u),
        info,
    )


def texel_cells(textures):
    """(C·K·rows·n_u, 16): each bilinear texel cell's 2 × 2 RGBA (texels (i0, j0), (i0, j1), (i1, j0), (i1, j1) of
    ``_raster.texel_cell``; rows = max(n_t − 1, 1)) of ``textures`` (C, K, n_t, n_u, 4)."""
    C, K, n_t, n_u = textures.shape[:4]
    rows = max(n_t - 1, 1)
    tex = textures.reshape(C * K, n_t, n_u, 4)
    r0 = tex[:, :rows]
    r1 = tex[:, np.minimum(np.arange(rows) + 1, n_t - 1)]
    return jnp.stack([r0, jnp.roll(r0, -1, 2), r1, jnp.roll(r1, -1, 2)], -2).reshape(-1, 16)


@partial(jax.jit, static_argnames=("slabs",))
def composite_kernel(textures, cell, weight, source, *, slabs):
    """The frame's premultiplied RGBA (h·w, 4) from ``textures`` (C, K, n_t, n_u, 4) and a plan's ``cell``,
    ``weight``, ``source`` and ``slabs`` (module docstring, step 2).  The running colour and transmittance of
    every pixel live in one (n + 1, 5) array updated in place slab by slab (one fused gather, interpolation and
    update per slab: nothing fragment-sized is written)."""
    cells = texel_cells(textures)
    n = slabs[0] if slabs else 0
    state = jnp.concatenate([jnp.zeros((n + 1, 4), jnp.float32), jnp.ones((n + 1, 1), jnp.float32)], -1)
    off = 0
    for m in slabs:  # front to back: slab d holds the d-th fragment of the first m pixels
        g = jnp.take(cells, cell[off : off + m], axis=0, mode="clip")
        w = weight[off : off + m]
        f = bilerp(g[:, 0:4], g[:, 4:8], g[:, 8:12], g[:, 12:16], w[:, :1], w[:, 1:])
        s = state[:m]
        state = state.at[:m].set(jnp.concatenate([s[:, :4] + s[:, 4:] * f, s[:, 4:] * (1.0 - f[:, 3:])], -1))
        off += m
    return jnp.take(state[:, :4], source, axis=0, mode="clip")


def draw_plan(plan: FragmentPlan, textures) -> tuple[np.ndarray, float]:
    """The frame (h, w, 4) of ``textures`` (the plan's shape) through ``plan``, and the seconds it took (host
    arrays in and out included)."""
    t0 = time.perf_counter()
    tex = np.asarray(textures, np.float32)
    if tex.shape[:4] != plan.textures or tex.shape[4:] != (4,):
        raise errors.ValidationError("textures", list(tex.shape), f"the plan needs {list(plan.textures) + [4]}")
    W, H = plan.size
    out = np.asarray(composite_kernel(jnp.asarray(tex), plan.cell, plan.weight, plan.source, slabs=plan.slabs))
    return out.reshape(H, W, 4), time.perf_counter() - t0


def draw_layers(cam, vertices, triangles, uv, textures, *, tile, origins, repeat: int = 0, plan=None, keep=None):
    """The two-pass frame of (C, K, V, 3) ``vertices`` and (C, K, n_t, n_u, 4) premultiplied ``textures``, as
    ``_layered.rasterise`` draws it in one pass: (rgba, depth, seconds, plan).  ``plan``: a :class:`FragmentPlan`
    of the same camera and geometry to reuse; ``keep``: :func:`plan_fragments`'s trim.  ``seconds``: ``plan`` (the camera pass, 0 when reused),
    ``raster_first`` (the first frame, compile included) and, with ``repeat`` more frames, ``raster`` (the best:
    the frame time once the camera pass is done, maps excluded)."""
    t0 = time.perf_counter()
    if plan is None:
        plan = plan_fragments(cam, vertices, triangles, uv, np.shape(textures)[:4], tile=tile, origins=origins, keep=keep)
    sec = {"plan": time.perf_counter() - t0}
    rgba, sec["raster_first"] = draw_plan(plan, textures)
    times = [draw_plan(plan, textures)[1] for _ in range(max(int(repeat), 0))]
    if times:
        sec["raster"] = min(times)
    if not np.isfinite(rgba).all():
        raise errors.ValidationError("frame", "non-finite", "the compositor produced non-finite pixels")
    return rgba, plan.depth, sec, plan
