"""The strand-level reference: the strands' Gaussian tubes ray-marched through the camera (``_strands``).

**Opacity** (Beer–Lambert).  Each camera ray meets the tubes of the segments binned to its screen tile
(``_tiles``); every (ray, segment) crossing's support is cut into ``steps`` equal steps whose optical
depth is the exact integral of that segment's density (``_strands.crossings``).  The steps of all
crossings are sorted along the ray and composited front to back: a step of optical depth τ_k weighs
w_k = (1 − e^{−τ_k}) Π_{j<k} e^{−τ_j}; the pixel's α is 1 − exp(−Σ τ) (exact, whatever the step).

**Shading** (the scene's terms, satf eqs 8–11 / Scheuermann, through ``hairlut.synth.lighting_kernel``)
with each segment's own tangent, the normal facing the viewer (n = unit(v − (v·t) t)), the camera's
viewing direction v, and no environment term: colour_k = Σ_lights T_l(x_k) · lighting(t_k, l).
Noise, when on, takes its mean (½).  **Shadows**: T_l(x) = exp(−τ_l(x)), τ_l the optical depth from x
toward light l through the same tubes, computed exactly (one step, :func:`shadow_kernel`) at the nodes
of a light-aligned grid of spacing ``cell`` and interpolated trilinearly; off when the scene's shadow
method is ``none``.

**Convergence.**  Level ℓ takes 2^ℓ × 2^ℓ samples per pixel (a regular grid, box filter), 2^(ℓ+1) steps
per crossing and a shadow grid of spacing 4 r̄ / 2^ℓ (r̄ the median strand radius).  :func:`render_reference`
refines level by level until the image changes by less than ``bound`` (RMSE of premultiplied RGB and
of α, each) from the level before, and stores the levels' changes; ``converged`` is false when
``max_level`` is reached first.
"""

from __future__ import annotations

import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ._strands import Z_CUT, Segments, crossings
from ._tiles import bin_boxes, chunks

TILE = 8
BUDGET = 1 << 21
#: The shadow grid's depth (nodes along the light) is computed in multiples of this.
DEPTH_STEP = 16
BACKGROUND_DEPTH = 1e10


def _frame_of(direction) -> np.ndarray:
    back = np.asarray(direction, np.float64) / np.linalg.norm(direction)
    helper = np.array([0.0, 1.0, 0.0]) if abs(back[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(helper, back)
    right /= np.linalg.norm(right)
    return np.stack([right, np.cross(back, right), back])


@partial(jax.jit, static_argnames=("depth", "tile"))
def shadow_kernel(tiles, index, origin, axes, cell, p0, t, length, radius, sigma_t, *, depth: int, tile: int):
    """Optical depth toward the light (``axes[2]``) at the nodes (tile, tile, depth) of each tile's column of a
    light-aligned grid (node (i, j, k) at origin + cell·(i, j, k) in ``axes``): (T, tile, tile, depth)."""
    ij = jnp.arange(tile, dtype=jnp.float32)
    k = jnp.arange(depth, dtype=jnp.float32)
    gi = tiles[:, 0, None, None, None] * tile + ij[None, :, None, None]
    gj = tiles[:, 1, None, None, None] * tile + ij[None, None, :, None]
    pts = origin + cell * (gi[..., None] * axes[0] + gj[..., None] * axes[1] + k[None, None, None, :, None] * axes[2])
    pts = pts.reshape(pts.shape[0], -1, 1, 3)
    valid = index >= 0
    ix = jnp.where(valid, index, 0)
    seg = [a[ix][:, None] for a in (p0, t, length, radius, sigma_t)]  # (T, 1, M, …)
    tau, _ = crossings(pts, axes[2], *seg, 0.0, 1)
    tau = jnp.where(valid[:, None, :], tau[..., 0], 0.0).sum(-1)
    return tau.reshape(tiles.shape[0], tile, tile, depth)


def shadow_grid(segs: Segments, light, cell: float):
    """A light's exact optical-depth grid (:func:`shadow_kernel`): (τ (nx, ny, nz), origin, axes (3, 3))."""
    axes = _frame_of(light)
    lo, hi = segs.bounds()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    lc = corners @ axes.T
    l_lo, l_hi = lc.min(0), lc.max(0)
    shape = np.ceil((l_hi - l_lo) / cell).astype(int) + 2
    origin = l_lo @ axes
    nx, ny, nz = (int(x) for x in shape)
    depth = DEPTH_STEP * -(-nz // DEPTH_STEP)  # the kernel's static depth, bucketed (fewer compiles; cropped below)
    p1 = segs.p0 + segs.tangent * segs.length[:, None]
    a, b = (segs.p0 - origin) @ axes[:2].T / cell, (p1 - origin) @ axes[:2].T / cell
    reach = Z_CUT * segs.radius / cell
    buckets = bin_boxes(np.minimum(a[:, 0], b[:, 0]) - reach, np.maximum(a[:, 0], b[:, 0]) + reach,
                        np.minimum(a[:, 1], b[:, 1]) - reach, np.maximum(a[:, 1], b[:, 1]) + reach, (nx, ny), TILE)
    tiles_x, tiles_y = -(-nx // TILE), -(-ny // TILE)
    grid = np.zeros((tiles_x * TILE, tiles_y * TILE, nz), np.float32)
    dev = segs.device()
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    for bk in buckets:
        for s, n, tl, ix in chunks(bk, TILE * TILE * depth * bk.width, BUDGET):
            tau = np.asarray(shadow_kernel(jnp.asarray(tl, jnp.int32), jnp.asarray(ix, jnp.int32), f32(origin), f32(axes),
                                           f32(cell), *dev, depth=depth, tile=TILE))
            for m in range(n):
                x, y = tl[m]
                grid[x * TILE:(x + 1) * TILE, y * TILE:(y + 1) * TILE] = tau[m, ..., :nz]
    return grid[:nx, :ny], origin, axes


def _trilinear(grid, g):
    """grid (nx, ny, nz) at continuous node coordinates g (…, 3), clamped to the grid."""
    hi = jnp.array(grid.shape, g.dtype) - 1.0
    g = jnp.clip(g, 0.0, hi)
    i0 = jnp.minimum(jnp.floor(g), hi - 1.0).astype(jnp.int32)
    f = g - i0
    out = 0.0
    for c in range(8):
        o = ((c >> 2) & 1, (c >> 1) & 1, c & 1)
        w = 1.0
        for a in range(3):
            w = w * (f[..., a] if o[a] else 1.0 - f[..., a])
        out = out + w * grid[i0[..., 0] + o[0], i0[..., 1] + o[1], i0[..., 2] + o[2]]
    return out


@partial(jax.jit, static_argnames=("tile", "ss", "steps", "perspective", "shadows"))
def reference_kernel(tiles, index, cam, p0, t, length, radius, sigma_t, lit, grids, frames, cells, *,
                     tile: int, ss: int, steps: int, perspective: bool, shadows: bool):
    """RGBA (premultiplied) and α-weighted depth of the pixels of T tiles: (T, tile·tile, 5) (module docstring).
    ``cam`` (5, 3): eye, right, up, back, (half width, half height, 0) of the frame at unit distance
    (perspective) or in world units (orthographic); ``lit`` (S, L, 3) each segment's lighting; ``grids``
    (L, nx, ny, nz) the lights' optical depths with ``frames`` (L, 4, 3) (origin, axes) and ``cells`` (L,)."""
    eye, right, up, back, half = cam[0], cam[1], cam[2], cam[3], cam[4]
    sub = (jnp.arange(ss, dtype=jnp.float32) + 0.5) / ss
    pix = jnp.arange(tile, dtype=jnp.float32)
    px = (tiles[:, 0, None, None, None, None] * tile + pix[None, None, :, None, None] + sub[None, None, None, None, :])
    py = (tiles[:, 1, None, None, None, None] * tile + pix[None, :, None, None, None] + sub[None, None, None, :, None])
    px, py = jnp.broadcast_arrays(px, py)  # (T, y, x, sy, sx)
    sx = (2.0 * px / cam[5, 0] - 1.0) * half[0]
    sy = (1.0 - 2.0 * py / cam[5, 1]) * half[1]
    if perspective:
        d = sx[..., None] * right + sy[..., None] * up - back
        d = d / jnp.linalg.norm(d, axis=-1, keepdims=True)
        o = jnp.broadcast_to(eye, d.shape)
    else:
        o = eye + sx[..., None] * right + sy[..., None] * up
        d = jnp.broadcast_to(-back, o.shape)
    n_t = tiles.shape[0]
    o, d = o.reshape(n_t, -1, 1, 3), d.reshape(n_t, -1, 1, 3)
    valid = index >= 0
    ix = jnp.where(valid, index, 0)
    seg = [a[ix][:, None] for a in (p0, t, length, radius, sigma_t)]
    s_lo = 0.0 if perspective else -1e20  # an orthographic ray is the whole line (nothing lies behind its plane)
    tau, s = crossings(o, d, *seg, s_lo, steps)  # (T, R, M, steps)
    tau = jnp.where(valid[:, None, :, None], tau, 0.0)
    colour = jnp.broadcast_to(lit[ix][:, None, :, None], tau.shape + lit.shape[1:])  # (T, R, M, steps, L, 3)
    if shadows:
        x = o[..., None, :] + s[..., None] * d[..., None, :]  # (T, R, M, steps, 3)
        trans = []
        for li in range(grids.shape[0]):
            g = jnp.einsum("...j,ij->...i", x - frames[li, 0], frames[li, 1:], precision=jax.lax.Precision.HIGHEST)
            trans.append(jnp.exp(-_trilinear(grids[li], g / cells[li])))
        colour = colour * jnp.stack(trans, -1)[..., None]
    colour = colour.sum(-2)
    shape = tau.shape[:2] + (-1,)
    depth = s * (-(d[..., None, :] * back).sum(-1)) if perspective else s
    keys = (s.reshape(shape), tau.reshape(shape), jnp.broadcast_to(depth, tau.shape).reshape(shape),
            *(colour[..., c].reshape(shape) for c in range(3)))
    s_, tau_, z_, r_, g_, b_ = jax.lax.sort(keys, dimension=-1, num_keys=1)
    total = jnp.cumsum(tau_, -1)
    before = jnp.exp(-(total - tau_))
    w = -jnp.expm1(-tau_) * before
    alpha = -jnp.expm1(-total[..., -1])
    rgb = jnp.stack([(w * r_).sum(-1), (w * g_).sum(-1), (w * b_).sum(-1)], -1)
    wz = (w * z_).sum(-1)
    per = jnp.concatenate([rgb, alpha[..., None], wz[..., None], w.sum(-1)[..., None]], -1)
    per = per.reshape(n_t, tile * tile, ss * ss, 6).mean(2)
    z = jnp.where(per[..., 5] > 0, per[..., 4] / jnp.where(per[..., 5] > 0, per[..., 5], 1.0), BACKGROUND_DEPTH)
    return jnp.concatenate([per[..., :4], z[..., None]], -1)


def camera_array(camera) -> np.ndarray:
    """The (6, 3) camera rows :func:`reference_kernel` and the rasteriser take."""
    if camera.projection == "perspective":
        c = np.tan(np.radians(camera.fov) / 2)
        half = (c * camera.aspect, c)
    else:
        half = (camera.extent / 2 * camera.aspect, camera.extent / 2)
    return np.stack([camera.eye, camera.right, camera.up, camera.back, [*half, 0.0], [camera.width, camera.height, 0.0]])


def segment_boxes(segs: Segments, camera):
    """Screen boxes (x0, x1, y0, y1) of each segment's tube (cut at ``Z_CUT`` r), in pixels."""
    p1 = segs.p0 + segs.tangent * segs.length[:, None]
    xa, ya, za = camera.project(segs.p0)
    xb, yb, zb = camera.project(p1)
    reach = Z_CUT * segs.radius
    if camera.projection == "perspective":
        zmin = np.minimum(za, zb) - reach
        if (zmin <= 0).any():
            raise errors.ValidationError("camera.position", camera.eye.tolist(), "hair reaches behind the eye")
        px = reach * camera.height / (2 * np.tan(np.radians(camera.fov) / 2) * zmin)
    else:
        px = reach * camera.height / camera.extent
    return np.minimum(xa, xb) - px - 1, np.maximum(xa, xb) + px + 1, np.minimum(ya, yb) - px - 1, np.maximum(ya, yb) + px + 1


def render_level(segs: Segments, camera, lit, lights, *, level: int, shadows: bool, stats: dict | None = None) -> np.ndarray:
    """The (h, w, 5) RGBA + depth of one convergence level (module docstring)."""
    ss, steps = 1 << level, 2 << level
    cell = 4.0 * float(np.median(segs.radius)) / (1 << level)
    t0 = time.perf_counter()
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    if shadows:
        made = [shadow_grid(segs, l, cell) for l in lights]
        shape = np.max([g.shape for g, _, _ in made], axis=0)
        grids = np.zeros((len(made), *shape), np.float32)
        for i, (g, _, _) in enumerate(made):
            grids[i, :g.shape[0], :g.shape[1], :g.shape[2]] = g
            grids[i, g.shape[0]:], grids[i, :, g.shape[1]:], grids[i, :, :, g.shape[2]:] = 0, 0, 0
        frames = np.stack([np.concatenate([o[None], a]) for _, o, a in made])
    else:
        grids, frames = np.zeros((1, 2, 2, 2), np.float32), np.zeros((1, 4, 3))
    t1 = time.perf_counter()
    w, h = camera.width, camera.height
    out = np.zeros((-(-h // TILE) * TILE, -(-w // TILE) * TILE, 5), np.float32)
    out[..., 4] = BACKGROUND_DEPTH
    buckets = bin_boxes(*segment_boxes(segs, camera), (w, h), TILE)
    dev, cam = segs.device(), f32(camera_array(camera))
    g_dev, f_dev, c_dev = f32(grids), f32(frames), f32(np.full(len(frames), cell))
    for bk in buckets:
        for s, n, tl, ix in chunks(bk, TILE * TILE * ss * ss * bk.width * steps * 4, BUDGET):
            res = np.asarray(reference_kernel(jnp.asarray(tl, jnp.int32), jnp.asarray(ix, jnp.int32), cam, *dev, lit,
                                              g_dev, f_dev, c_dev, tile=TILE, ss=ss, steps=steps,
                                              perspective=camera.projection == "perspective", shadows=shadows))
            for m in range(n):
                x, y = tl[m]
                out[y * TILE:(y + 1) * TILE, x * TILE:(x + 1) * TILE] = res[m].reshape(TILE, TILE, 5)
    if stats is not None:
        stats.update(shadow_seconds=t1 - t0, march_seconds=time.perf_counter() - t1, samples_per_pixel=ss * ss,
                     steps_per_crossing=steps, shadow_cell=cell)
    out = out[:h, :w]
    if not np.isfinite(out).all():
        raise errors.ValidationError("reference", "non-finite", "the reference produced non-finite pixels")
    return out
