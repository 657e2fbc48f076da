"""The layered model's rasteriser (satf §6.1, eq 14): every cluster's layer meshes, textured, composited.

One jitted kernel, :func:`raster_kernel`, no OpenGL, the same on CPU and GPU:

1. **Projection.**  Each vertex through the camera's 4 × 4 world-to-clip matrix (``hairlut.scene.Camera``,
   the OpenGL convention): pixel x = (X/W + 1)/2 · w, y = (1 − Y/W)/2 · h (pixel centres at integers + ½),
   eye depth (eye − p)·back.
2. **Coverage.**  Each triangle tests the pixel centres of an S × S stamp from its bounding box's corner
   (S is static, chosen on the host so that every triangle's box fits).  A centre is inside when all three
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
7. **Between clusters**: per pixel the clusters sorted by their nearest depth, then front-to-back "over".

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


def sample_texture(tex, u, t):
    """Bilinear RGBA of ``tex`` (n_t, n_u, 4) at mesh texture coordinates u ∈ [0, 1] (periodic), t ∈ [0, 1];
    a constant texture returns its value exactly (a + w·(b − a))."""
    n_t, n_u = tex.shape[:2]
    s = u * n_u - 0.5
    j0f = jnp.floor(s)
    ws = (s - j0f)[..., None]
    j0 = jnp.mod(j0f.astype(jnp.int32), n_u)
    j1 = jnp.mod(j0 + 1, n_u)
    r = jnp.clip(t * n_t - 0.5, 0.0, n_t - 1.0)
    i0 = jnp.clip(jnp.floor(r).astype(jnp.int32), 0, max(n_t - 2, 0))
    i1 = jnp.minimum(i0 + 1, n_t - 1)
    wr = (r - i0)[..., None]
    flat = tex.reshape(-1, tex.shape[-1])
    a, b = flat[i0 * n_u + j0], flat[i0 * n_u + j1]
    c, d = flat[i1 * n_u + j0], flat[i1 * n_u + j1]
    top, bot = a + ws * (b - a), c + ws * (d - c)
    return top + wr * (bot - top)


def _cluster(verts, tex, origin, tri, uv, matrix, eye, back, *, size, tile, stamp):
    """One cluster: (th, tw, 4) premultiplied RGBA and (th, tw) nearest depth of its tile at ``origin``."""
    W, H = size
    th, tw = tile
    K = verts.shape[0]
    clip = jnp.einsum("kvj,ij->kvi", verts, matrix[:, :3], precision=HIGHEST) + matrix[:, 3]
    w = clip[..., 3]
    ws = jnp.where(w > 0, w, 1.0)
    x = (clip[..., 0] / ws + 1.0) * (0.5 * W) - origin[0]
    y = (1.0 - clip[..., 1] / ws) * (0.5 * H) - origin[1]
    depth = jnp.einsum("kvj,j->kv", eye - verts, back, precision=HIGHEST)
    X, Y, Wc, D = (a[:, tri] for a in (x, y, w, depth))  # (K, T, 3)
    U, V = uv[tri, 0], uv[tri, 1]  # (T, 3)
    area = _edge(X[..., 0], Y[..., 0], X[..., 1], Y[..., 1], X[..., 2], Y[..., 2])  # (K, T)
    ok = (area != 0) & jnp.all(Wc > 0, -1)
    front = area < 0  # y points down on screen: a counter-clockwise (outward-facing) triangle has negative area
    bx0 = jnp.ceil(jnp.min(X, -1) - 0.5)
    by0 = jnp.ceil(jnp.min(Y, -1) - 0.5)
    off = jnp.arange(stamp, dtype=jnp.float32)
    px = bx0[..., None, None] + off[None, :]  # (K, T, 1, S): columns
    py = by0[..., None, None] + off[:, None]  # (K, T, S, 1): rows
    cx, cy = px + 0.5, py + 0.5
    inside = ok[..., None, None] & (px >= 0) & (px < tw) & (py >= 0) & (py < th)
    sgn = jnp.sign(area)[..., None, None]
    lam = []
    for a, b in ((1, 2), (2, 0), (0, 1)):  # the edge opposite vertex 0, 1, 2
        lo = tri[:, a] < tri[:, b]  # canonical order: lower mesh index first
        sig = jnp.where(lo, 1.0, -1.0)[None, :, None, None]
        ax, ay = jnp.where(lo, X[..., a], X[..., b]), jnp.where(lo, Y[..., a], Y[..., b])
        bx, by = jnp.where(lo, X[..., b], X[..., a]), jnp.where(lo, Y[..., b], Y[..., a])
        e = _edge(ax[..., None, None], ay[..., None, None], bx[..., None, None], by[..., None, None], cx, cy)
        s = sig * sgn
        inside = inside & ((s * e > 0) | ((e == 0) & (s > 0)))
        lam.append(sig * e / jnp.where(area != 0, area, 1.0)[..., None, None])
    q = [lam[i] / Wc[..., i, None, None] for i in range(3)]  # perspective-correct weights
    qs = q[0] + q[1] + q[2]
    qs = jnp.where(inside, qs, 1.0)
    b = [qi / qs for qi in q]

    def interp(a):  # (…, 3) per triangle → (K, T, S, S)
        a = jnp.broadcast_to(a, (K, *a.shape[-2:]))
        return sum(b[i] * a[..., i, None, None] for i in range(3))

    z = interp(D)
    tu, tt = interp(U), interp(V)
    n_pix = th * tw
    slot = jnp.arange(K)[:, None] * 2 + jnp.where(front, 0, 1)  # (K, T): layer k front 2k, back 2k + 1
    pix = (slot[..., None, None] * n_pix + py.astype(jnp.int32) * tw + px.astype(jnp.int32))
    dump = 2 * K * n_pix
    idx = jnp.where(inside, pix, dump).reshape(-1)
    zf = jnp.where(inside, z, jnp.inf).reshape(-1)
    zbuf = jnp.full(dump + 1, jnp.inf, jnp.float32).at[idx].min(zf)
    win = inside.reshape(-1) & (zf == zbuf[idx])
    widx = jnp.where(win, idx, dump)
    uvbuf = jnp.zeros((dump + 1, 2), jnp.float32).at[widx].set(jnp.stack([tu.reshape(-1), tt.reshape(-1)], -1))
    zb = zbuf[:dump].reshape(2 * K, th, tw)
    uvb = uvbuf[:dump].reshape(2 * K, th, tw, 2)
    layer_tex = jnp.repeat(tex, 2, axis=0)
    rgba = jax.vmap(sample_texture)(layer_tex, uvb[..., 0], uvb[..., 1])
    drawn = jnp.isfinite(zb)
    rgba = jnp.where(drawn[..., None], rgba, 0.0)
    order = [2 * k for k in range(K - 1, -1, -1)] + [2 * k + 1 for k in range(K)]
    acc = jnp.zeros((th, tw, 4), jnp.float32)
    trans = jnp.ones((th, tw), jnp.float32)
    for s in order:  # eq 14, front to back
        acc = acc + trans[..., None] * rgba[s]
        trans = trans * (1.0 - rgba[s, ..., 3])
    near = jnp.min(jnp.where(drawn, zb, FAR), axis=0)
    return acc, near


@partial(jax.jit, static_argnames=("size", "tile", "stamp"))
def raster_kernel(verts, tex, origins, tri, uv, matrix, eye, back, *, size, tile, stamp):
    """The frame of the layered model (module docstring): ``verts`` (C, K, V, 3) world positions of every
    cluster's layer meshes (sharing ``tri`` (T, 3) and ``uv`` (V, 2) = (u/2π, t)); ``tex`` (C, K, n_t, n_u, 4)
    premultiplied RGBA per layer; ``origins`` (C, 2) each cluster's tile corner (x, y) in pixels; ``matrix``
    (4, 4) world-to-clip, ``eye`` and ``back`` (3,) the camera's eye and unit view axis; ``size`` (w, h),
    ``tile`` (th, tw) and ``stamp`` S static.  Returns RGBA (h, w, 4) premultiplied and depth (h, w)."""
    W, H = size
    th, tw = tile
    one = partial(_cluster, tri=tri, uv=uv, matrix=matrix, eye=eye, back=back, size=size, tile=tile, stamp=stamp)
    rgba, near = jax.lax.map(lambda a: one(*a), (verts, tex, origins))  # (C, th, tw, 4), (C, th, tw)
    C = verts.shape[0]
    gy = origins[:, 1, None, None] + jnp.arange(th)[None, :, None]
    gx = origins[:, 0, None, None] + jnp.arange(tw)[None, None, :]
    inframe = (gx >= 0) & (gx < W) & (gy >= 0) & (gy < H)
    gidx = jnp.where(inframe, gy * W + gx, W * H).reshape(C, -1)
    cols = jnp.concatenate([near[..., None], rgba], -1).reshape(C, -1, 5)
    empty = jnp.concatenate([jnp.full((1,), FAR, jnp.float32), jnp.zeros((4,), jnp.float32)])
    buf = jnp.broadcast_to(empty, (C, W * H + 1, 5))
    buf = jax.vmap(lambda b, i, v: b.at[i].set(v))(buf, gidx, cols)[:, :W * H]
    keys = jax.lax.sort(tuple(buf[..., i] for i in range(5)), dimension=0, num_keys=1)  # per pixel, nearest first

    def over(carry, f):
        acc, trans = carry
        z, r, g, b, a = f
        return (acc + trans[:, None] * jnp.stack([r, g, b, a], -1), trans * (1.0 - a)), None

    init = (jnp.zeros((W * H, 4), jnp.float32), jnp.ones((W * H,), jnp.float32))
    (acc, _), _ = jax.lax.scan(over, init, keys)
    return acc.reshape(H, W, 4), keys[0][0].reshape(H, W)
