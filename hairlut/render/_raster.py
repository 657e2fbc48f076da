"""The layered model's rasteriser (satf §6.1, eq 14): every cluster's layer meshes, textured, composited.

One jitted kernel, :func:`raster_kernel`, no OpenGL, the same on CPU and GPU:

1. **Projection.**  Each vertex through the camera's 4 × 4 world-to-clip matrix (``hairlut.scene.Camera``,
   the OpenGL convention): pixel x = (X/W + 1)/2 · w, y = (1 − Y/W)/2 · h (pixel centres at integers + ½),
   eye depth (eye − p)·back.
2. **Coverage.**  Triangles go in pairs (a grid quad's two) that share one box of pixel centres; every
   box's pixels get consecutive candidate slots (a prefix sum; ``cap`` slots per cluster, static, sized on the
   host), and each candidate tests both triangles of its pair.  A centre is inside when all three
   edge functions have the triangle's sign.  Each edge function is evaluated in one canonical vertex order
   (lower mesh index first), so a shared edge gives bitwise-opposite values in its two triangles, and a
   centre exactly on it belongs to the triangle on the positive side only: no pixel is drawn twice or
   missed along a shared edge (a constant-α quad renders to exactly that α).
3. **Interpolation.**  Perspective-correct: the screen barycentrics λ_i are weighted by 1/w_i (clip w) and
   renormalised; texture coordinates and eye depth are interpolated with those weights.
4. **Depth test per layer surface.**  Each (layer, facing) of a cluster keeps its nearest fragment per
   pixel (a z-buffer each): the front faces (outward normal toward the viewer) and the back faces of a
   layer's closed tube are separate surfaces.
5. **Texturing.**  The layer's map (premultiplied shaded RGB and α on the (n_t, n_u) texel grid, texel
   (i, j) at t = (i + ½)/n_t, u = (j + ½)/n_u of the mesh's uv) sampled bilinearly, periodic in u.
6. **Eq 14 between a cluster's layers.**  Front faces outermost first, then back faces innermost first
   (the depth order of nested shells): Ψ = Σ_f Ψ_f α_f Π_{g before f} (1 − α_g), accumulated front to back;
   for the front faces this is eq 14 (Ψ_k α_k Π_{j>k} (1 − α_j)).
7. **Between clusters**: front-to-back "over" in the order of each cluster's nearest depth per pixel, without a
   sort: each cluster's RGBA is weighted by Π (1 − α_j) over the clusters j nearer at that pixel (ties: the
   lower index first), read from their tiles (C² tile-sized passes, not C frame-sized buffers), and added in.

The frame is premultiplied linear RGB, α and eye depth (``FAR`` where nothing was drawn).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

#: Eye depth written where nothing was drawn (the ``Z`` convention of ``_frame``).
FAR = 1e10
HIGHEST = jax.lax.Precision.HIGHEST


def _edge(ax, ay, bx, by, px, py):
    """Twice the signed area of (a, b, p) in pixel coordinates."""
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax)


def texel_cell(u, t, n_t: int, n_u: int):
    """The bilinear footprint of texture coordinates u ∈ [0, 1] (periodic), t ∈ [0, 1] on an (n_t, n_u) texel
    grid (texel (i, j) at t = (i + ½)/n_t, u = (j + ½)/n_u): rows i0, i1 = min(i0 + 1, n_t − 1) (i0 clamped to
    [0, n_t − 2]), columns j0, j1 = j0 + 1 mod n_u, and the weights ws (along u) and wr (along t)."""
    s = u * n_u - 0.5
    j0f = jnp.floor(s)
    ws = s - j0f
    j0 = jnp.mod(j0f.astype(jnp.int32), n_u)
    j1 = jnp.mod(j0 + 1, n_u)
    r = jnp.clip(t * n_t - 0.5, 0.0, n_t - 1.0)
    i0 = jnp.clip(jnp.floor(r).astype(jnp.int32), 0, max(n_t - 2, 0))
    i1 = jnp.minimum(i0 + 1, n_t - 1)
    return i0, i1, j0, j1, ws, r - i0


def bilerp(a, b, c, d, ws, wr):
    """(a, b) along u on row i0, (c, d) on row i1: exact for a constant texture (a + w·(b − a))."""
    top, bot = a + ws * (b - a), c + ws * (d - c)
    return top + wr * (bot - top)


def sample_texture(tex, u, t):
    """Bilinear RGBA of ``tex`` (n_t, n_u, 4) at mesh texture coordinates u ∈ [0, 1] (periodic), t ∈ [0, 1]
    (:func:`texel_cell`); a constant texture returns its value exactly."""
    n_t, n_u = tex.shape[:2]
    i0, i1, j0, j1, ws, wr = texel_cell(u, t, n_t, n_u)
    flat = tex.reshape(-1, tex.shape[-1])
    return bilerp(
        flat[i0 * n_u + j0], flat[i0 * n_u + j1], flat[i1 * n_u + j0], flat[i1 * n_u + j1], ws[..., None], wr[..., None]
    )


def _records(x, y, w, depth, uv, pairs):
    """Per triangle pair (K, P) of one cluster: the record (K, P, 2, 27) each candidate pixel reads and the pair's
    pixel box.  Per triangle: for each edge (opposite vertex 0, 1, 2) the canonical edge function's A, B, C
    (E = A·x + B·y + C, lower mesh index first) and s = σ·sign(area) (σ = −1 where the canonical order reverses
    the triangle's; 0 for a degenerate triangle or one behind the eye); 1/|area|; per vertex 1/w, d/w, u/w, t/w;
    and whether it faces the viewer."""
    X, Y, Wc, D = (a[:, pairs] for a in (x, y, w, depth))  # (K, P, 2, 3)
    U, V = uv[pairs, 0], uv[pairs, 1]  # (P, 2, 3)
    area = _edge(X[..., 0], Y[..., 0], X[..., 1], Y[..., 1], X[..., 2], Y[..., 2])  # (K, P, 2)
    ok = (area != 0) & jnp.all(Wc > 0, -1)
    sgn = jnp.where(ok, jnp.sign(area), 0.0)
    fields = []
    for a, b in ((1, 2), (2, 0), (0, 1)):
        lo = pairs[..., a] < pairs[..., b]  # (P, 2)
        ax, ay = jnp.where(lo, X[..., a], X[..., b]), jnp.where(lo, Y[..., a], Y[..., b])
        bx, by = jnp.where(lo, X[..., b], X[..., a]), jnp.where(lo, Y[..., b], Y[..., a])
        ca, cb = -(by - ay), bx - ax
        fields += [ca, cb, -(ca * ax + cb * ay), jnp.where(lo, 1.0, -1.0) * sgn]
    iw = 1.0 / jnp.where(Wc > 0, Wc, 1.0)
    per_vertex = [iw, D * iw, jnp.broadcast_to(U, X.shape) * iw, jnp.broadcast_to(V, X.shape) * iw]
    fields.append(1.0 / jnp.where(area != 0, jnp.abs(area), 1.0))
    rec = jnp.concatenate([jnp.stack(fields, -1)] + per_vertex + [(area < 0)[..., None].astype(jnp.float32)], -1)
    lo_x = jnp.ceil(jnp.min(jnp.where(ok[..., None], X, jnp.inf), axis=(-2, -1)) - 0.5)
    hi_x = jnp.floor(jnp.max(jnp.where(ok[..., None], X, -jnp.inf), axis=(-2, -1)) - 0.5)
    lo_y = jnp.ceil(jnp.min(jnp.where(ok[..., None], Y, jnp.inf), axis=(-2, -1)) - 0.5)
    hi_y = jnp.floor(jnp.max(jnp.where(ok[..., None], Y, -jnp.inf), axis=(-2, -1)) - 0.5)
    return rec, (lo_x, hi_x, lo_y, hi_y)


def surfaces(verts, origin, pairs, uv, matrix, eye, back, *, size, tile, cap):
    """One cluster's layer surfaces in its tile at ``origin`` (steps 1–4 of the module docstring): the nearest
    fragment's eye depth (2K, th, tw) (inf where none; surface 2k: layer k's front faces, 2k + 1: its back
    faces), its texture coordinates (2K, th, tw, 2) (u, t), and the number of candidate pixels the cluster
    needed (at most ``cap`` are tested)."""
    W, H = size
    th, tw = tile
    K = verts.shape[0]
    clip = jnp.einsum("kvj,ij->kvi", verts, matrix[:, :3], precision=HIGHEST) + matrix[:, 3]
    w = clip[..., 3]
    ws = jnp.where(w > 0, w, 1.0)
    x = (clip[..., 0] / ws + 1.0) * (0.5 * W) - origin[0]
    y = (1.0 - clip[..., 1] / ws) * (0.5 * H) - origin[1]
    depth = jnp.einsum("kvj,j->kv", eye - verts, back, precision=HIGHEST)
    rec, (lo_x, hi_x, lo_y, hi_y) = _records(x, y, w, depth, uv, pairs)
    P = pairs.shape[0]
    # each pair's box of pixel centres, clipped to the tile; its pixels get consecutive candidate slots
    x0 = jnp.clip(lo_x, 0, tw).astype(jnp.int32)
    x1 = jnp.clip(hi_x, -1, tw - 1).astype(jnp.int32)
    y0 = jnp.clip(lo_y, 0, th).astype(jnp.int32)
    y1 = jnp.clip(hi_y, -1, th - 1).astype(jnp.int32)
    bw = jnp.maximum(x1 - x0 + 1, 0).reshape(-1)
    n = bw * jnp.maximum(y1 - y0 + 1, 0).reshape(-1)
    csum = jnp.cumsum(n)
    start = csum - n
    total = csum[-1]
    owner = jnp.zeros(cap, jnp.int32).at[jnp.where(n > 0, start, cap)].max(jnp.arange(K * P, dtype=jnp.int32), mode="drop")
    owner = jax.lax.cummax(owner)
    k = jnp.arange(cap, dtype=jnp.int32)
    loc = k - start[owner]
    wo = jnp.maximum(bw[owner], 1)
    px = x0.reshape(-1)[owner] + loc % wo
    py = y0.reshape(-1)[owner] + loc // wo
    T = rec.reshape(K * P * 2, -1).T  # (27, 2KP) field-major: each candidate gathers single fields (1-D, fused)
    cx = px.astype(jnp.float32) + 0.5
    cy = py.astype(jnp.float32) + 0.5
    inside, se = [], []
    for i in range(2):  # the pair's two triangles
        col = owner * 2 + i
        e = [T[4 * q][col] * cx + T[4 * q + 1][col] * cy + T[4 * q + 2][col] for q in range(3)]
        s = [T[4 * q + 3][col] for q in range(3)]
        inside.append(jnp.all(jnp.stack([(sq * eq > 0) | ((eq == 0) & (sq > 0)) for sq, eq in zip(s, e)]), 0))
        se.append([sq * eq for sq, eq in zip(s, e)])
    col = owner * 2 + jnp.where(inside[0], 0, 1)  # the triangle that holds the centre
    lam = [jnp.where(inside[0], a, b) * T[12][col] for a, b in zip(*se)]

    def interpolate(j):
        return sum(lam[q] * T[j + q][col] for q in range(3))

    qs = interpolate(13)
    qs = jnp.where(qs != 0, qs, 1.0)
    z, tu, tt = interpolate(16) / qs, interpolate(19) / qs, interpolate(22) / qs
    hit = (k < total) & (inside[0] | inside[1])
    n_pix = th * tw
    slot = (owner // P) * 2 + jnp.where(T[25][col] > 0, 0, 1)  # layer k: front faces 2k, back faces 2k + 1
    dump = 2 * K * n_pix
    idx = jnp.where(hit, slot * n_pix + py * tw + px, dump)
    zf = jnp.where(hit, z, jnp.inf)
    zbuf = jnp.full(dump + 1, jnp.inf, jnp.float32).at[idx].min(zf)
    win = hit & (zf == zbuf[idx])
    uvbuf = jnp.zeros((dump + 1, 2), jnp.float32).at[jnp.where(win, idx, dump)].set(jnp.stack([tu, tt], -1))
    return zbuf[:dump].reshape(2 * K, th, tw), uvbuf[:dump].reshape(2 * K, th, tw, 2), total


def surface_order(K: int) -> list[int]:
    """Eq 14's front-to-back order of a cluster's 2K surfaces: front faces outermost first, then back faces
    innermost first (the depth order of nested shells)."""
    return [2 * k for k in range(K - 1, -1, -1)] + [2 * k + 1 for k in range(K)]


def _cluster(verts, tex, origin, pairs, uv, matrix, eye, back, *, size, tile, cap):
    """One cluster: (th, tw, 4) premultiplied RGBA, (th, tw) nearest depth of its tile at ``origin``, and the
    number of candidate pixels it needed (at most ``cap`` are tested)."""
    th, tw = tile
    K = verts.shape[0]
    zb, uvb, total = surfaces(verts, origin, pairs, uv, matrix, eye, back, size=size, tile=tile, cap=cap)
    rgba = jax.vmap(sample_texture)(jnp.repeat(tex, 2, axis=0), uvb[..., 0], uvb[..., 1])
    drawn = jnp.isfinite(zb)
    rgba = jnp.where(drawn[..., None], rgba, 0.0)
    acc = jnp.zeros((th, tw, 4), jnp.float32)
    trans = jnp.ones((th, tw), jnp.float32)
    for sl in surface_order(K):  # eq 14, front to back
        acc = acc + trans[..., None] * rgba[sl]
        trans = trans * (1.0 - rgba[sl, ..., 3])
    near = jnp.min(jnp.where(drawn, zb, FAR), axis=0)
    return acc, near, total


@partial(jax.jit, static_argnames=("size", "tile", "cap"))
def raster_kernel(verts, tex, origins, pairs, uv, matrix, eye, back, *, size, tile, cap):
    """The frame of the layered model (module docstring): ``verts`` (C, K, V, 3) world positions of every
    cluster's layer meshes (sharing ``tri`` (T, 3) and ``uv`` (V, 2) = (u/2π, t)); ``tex`` (C, K, n_t, n_u, 4)
    premultiplied RGBA per layer; ``origins`` (C, 2) each cluster's tile corner (x, y) in pixels; ``matrix``
    (4, 4) world-to-clip, ``eye`` and ``back`` (3,) the camera's eye and unit view axis; ``size`` (w, h),
    ``tile`` (th, tw) and ``cap`` (candidate pixels per cluster) static.  ``pairs`` (P, 2, 3): the triangles in
    pairs that share a pixel box (a grid quad's two; pad with a degenerate triangle).  Returns RGBA (h, w, 4)
    premultiplied, depth (h, w) and the most candidate pixels a cluster needed (> ``cap``: pixels were lost,
    run again with a larger cap)."""
    W, H = size
    th, tw = tile
    one = partial(_cluster, pairs=pairs, uv=uv, matrix=matrix, eye=eye, back=back, size=size, tile=tile, cap=cap)
    rgba, near, need = jax.lax.map(lambda a: one(*a), (verts, tex, origins))  # (C, th, tw, 4), (C, th, tw)
    C = verts.shape[0]
    ys = jnp.arange(th, dtype=jnp.int32)[None, :, None]
    xs = jnp.arange(tw, dtype=jnp.int32)[None, None, :]
    ox, oy = origins[:, 0, None, None], origins[:, 1, None, None]  # (C, 1, 1)
    ids = jnp.arange(C, dtype=jnp.int32)[:, None, None]
    log_keep = jnp.log1p(-jnp.clip(rgba[..., 3], 0.0, 1.0 - 1e-7))  # (C, th, tw): ln(1 − α) of each cluster's tile

    def front(acc, j):
        """Add cluster j's ln(1 − α) to every cluster's pixels that j covers nearer (ties: the lower index)."""
        yj, xj = oy + ys - origins[j, 1], ox + xs - origins[j, 0]  # every tile's pixels in tile j's coordinates
        inside = (yj >= 0) & (yj < th) & (xj >= 0) & (xj < tw)
        flat = jnp.clip(yj, 0, th - 1) * tw + jnp.clip(xj, 0, tw - 1)
        zj = near[j].reshape(-1)[flat]
        nearer = inside & ((zj < near) | ((zj == near) & (j < ids)))
        return acc + jnp.where(nearer, log_keep[j].reshape(-1)[flat], 0.0), None

    # "over" between clusters, front to back, without sorting: each cluster's RGBA times the transmittance of the
    # clusters nearer at that pixel, Π (1 − α_j) (the same sum as the per-pixel depth-sorted composite)
    log_t, _ = jax.lax.scan(front, jnp.zeros((C, th, tw), jnp.float32), jnp.arange(C, dtype=jnp.int32))
    gy, gx = oy + ys, ox + xs
    inframe = (gx >= 0) & (gx < W) & (gy >= 0) & (gy < H)
    gidx = jnp.where(inframe, gy * W + gx, W * H).reshape(-1)
    contrib = (rgba * jnp.exp(log_t)[..., None]).reshape(-1, 4)
    acc = jnp.zeros((W * H + 1, 4), jnp.float32).at[gidx].add(contrib)[: W * H]
    depth = jnp.full((W * H + 1,), FAR, jnp.float32).at[gidx].min(near.reshape(-1))[: W * H]
    return acc.reshape(H, W, 4), depth.reshape(H, W), jnp.max(need)
