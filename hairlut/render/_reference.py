"""The strand-level reference: the strands' Gaussian tubes ray-marched through the camera (``_strands``).

**Opacity** (Beer–Lambert).  Each camera ray meets the tubes of the segments binned to its screen tile
(``_tiles``) that it passes near (``_hits``: a first pass keeps, per ray, only the pairs that can add optical
depth); every such crossing's support is cut into ``steps`` equal steps whose optical depth is the exact
integral of that segment's density (``_strands.crossings``).  The steps of all crossings are sorted along the
ray and composited front to back: a step of optical depth τ_k weighs w_k = (1 − e^{−τ_k}) Π_{j<k} e^{−τ_j};
the pixel's α is 1 − exp(−Σ τ) (exact, whatever the step).

**Shading** (the scene's terms, satf eqs 8–11 / Scheuermann, through ``hairlut.synth.lighting_kernel``)
with each segment's own tangent, the normal facing the viewer (n = unit(v − (v·t) t)), the camera's
viewing direction v, and no environment term: colour_k = Σ_lights T_l(x_k) · lighting(t_k, l).
Noise, when on, takes its mean (½).  **Shadows**: T_l(x) = exp(−τ_l(x)), τ_l the optical depth from x
toward light l through the same tubes, computed exactly (one step, :func:`shadow_kernel`) at the nodes
of a light-aligned grid of spacing ``cell`` (each column of nodes is one ray toward the light: its crossings
are found once, ``_hits``, and integrated from every node on) and interpolated trilinearly; off when the scene's shadow
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

from .. import budget, errors
from jax.scipy.special import erfc

from ._hits import RAYS, Queue, batch_rows, compact, near_pairs, tile_groups
from ._strands import Z_CUT, Segments, crossings, support, tail_diff
from ._tiles import bin_boxes

TILE = 8
#: The shadow grid's depth (nodes along the light) is computed in multiples of this.
DEPTH_STEP = 16
BACKGROUND_DEPTH = 1e10


def _frame_of(direction) -> np.ndarray:
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


def _light_frame(segs: Segments, light, cell: float):
    """A light's grid: (axes (3, 3), origin (3,), (nx, ny, nz)) covering the hair's bounds."""
    axes = _frame_of(light)
    lo, hi = segs.bounds()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    lc = corners @ axes.T
    l_lo, l_hi = lc.min(0), lc.max(0)
    return axes, l_lo @ axes, tuple(int(x) for x in np.ceil((l_hi - l_lo) / cell).astype(int) + 2)


def shadow_grids(segs: Segments, lights, cell: float, stats: dict | None = None) -> list:
    """Each light's exact optical-depth grid (:func:`shadow_kernel`): [(τ (nx, ny, nz), origin, axes (3, 3))].
    One static depth (the deepest grid's, in multiples of ``DEPTH_STEP``) serves every light: fewer compiles."""
    frames = [_light_frame(segs, light, cell) for light in lights]
    depth = DEPTH_STEP * -(-max(f[2][2] for f in frames) // DEPTH_STEP)
    dev = segs.device()
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    p1 = segs.p0 + segs.tangent * segs.length[:, None]
    ij = np.stack(np.meshgrid(np.arange(TILE), np.arange(TILE), indexing="ij"), -1).reshape(-1, 2)  # column in tile
    group = RAYS // (TILE * TILE)
    out = []
    for axes, origin, (nx, ny, nz) in frames:
        a, b = (segs.p0 - origin) @ axes[:2].T / cell, (p1 - origin) @ axes[:2].T / cell
        reach = Z_CUT * segs.radius / cell
        buckets = bin_boxes(np.minimum(a[:, 0], b[:, 0]) - reach, np.maximum(a[:, 0], b[:, 0]) + reach,
                            np.minimum(a[:, 1], b[:, 1]) - reach, np.maximum(a[:, 1], b[:, 1]) + reach, (nx, ny), TILE)
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
            o[:g.shape[0] * g.shape[1]] = (origin + cell * (g[..., :1] * axes[0] + g[..., 1:] * axes[1])).reshape(-1, 3)
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


@partial(jax.jit, static_argnames=("tile", "ss", "perspective"))
def camera_rays(tiles, cam, *, tile: int, ss: int, perspective: bool):
    """Origins and unit directions (T, R, 3) of the rays of T tiles: R = tile² pixels × ss² samples, ray r =
    ((y·tile + x)·ss + sy)·ss + sx.  ``cam`` (6, 3): eye, right, up, back, (half width, half height, 0) of the frame
    at unit distance (perspective) or in world units (orthographic), (width, height, 0) in pixels."""
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
    return o.reshape(tiles.shape[0], -1, 3), d.reshape(tiles.shape[0], -1, 3)


@partial(jax.jit, static_argnames=("steps", "perspective", "shadows"))
def reference_kernel(o, d, cand, back, p0, t, length, radius, sigma_t, lit, grids, frames, cells, *,
                     steps: int, perspective: bool, shadows: bool):
    """Premultiplied RGB, α, Σ w·depth and Σ w of N rays (``o``, ``d`` (N, 3)) through their near segments ``cand``
    (N, K) (−1: none): (N, 6) (module docstring).  ``back`` (3,) the camera's back axis; ``lit`` (S, L, 3) each
    segment's lighting; ``grids`` a tuple of L (nx, ny, nz): the lights' optical depths, with ``frames`` (L, 4, 3)
    (origin, axes) and ``cells`` (L,)."""
    valid = cand >= 0
    ix = jnp.where(valid, cand, 0)
    seg = [a[ix] for a in (p0, t, length, radius, sigma_t)]
    o, d = o[:, None], d[:, None]  # (N, 1, 3)
    s_lo = 0.0 if perspective else -1e20  # an orthographic ray is the whole line (nothing lies behind its plane)
    tau, s = crossings(o, d, *seg, s_lo, steps)  # (N, K, steps)
    tau = jnp.where(valid[..., None], tau, 0.0)
    colour = jnp.broadcast_to(lit[ix][:, :, None], tau.shape + lit.shape[1:])  # (N, K, steps, L, 3)
    if shadows:
        x = o[..., None, :] + s[..., None] * d[..., None, :]  # (N, K, steps, 3)
        trans = []
        for li in range(len(grids)):
            g = jnp.einsum("...j,ij->...i", x - frames[li, 0], frames[li, 1:], precision=jax.lax.Precision.HIGHEST)
            trans.append(jnp.exp(-_trilinear(grids[li], g / cells[li])))
        colour = colour * jnp.stack(trans, -1)[..., None]
    colour = colour.sum(-2)
    n = tau.shape[0]
    depth = s * (-(d[..., None, :] * back).sum(-1)) if perspective else s
    keys = (s.reshape(n, -1), tau.reshape(n, -1), jnp.broadcast_to(depth, tau.shape).reshape(n, -1),
            *(colour[..., c].reshape(n, -1) for c in range(3)))
    s_, tau_, z_, r_, g_, b_ = jax.lax.sort(keys, dimension=-1, num_keys=1)
    total = jnp.cumsum(tau_, -1)
    before = jnp.exp(-(total - tau_))
    w = -jnp.expm1(-tau_) * before
    alpha = -jnp.expm1(-total[..., -1])
    return jnp.stack([(w * r_).sum(-1), (w * g_).sum(-1), (w * b_).sum(-1), alpha, (w * z_).sum(-1), w.sum(-1)], -1)


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
    """The (h, w, 5) RGBA + depth of one convergence level (module docstring).  ``stats`` gets the seconds of the
    shadow grids, of the first pass (``_hits``) and of the second (:func:`reference_kernel`), and the pair counts."""
    ss, steps = 1 << level, 2 << level
    cell = 4.0 * float(np.median(segs.radius)) / (1 << level)
    t0 = time.perf_counter()
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    st = {"pairs": 0, "near_pairs": 0, "rays": 0, "rays_hit": 0, "composite_seconds": 0.0}
    if shadows:
        nodes = sum(float(np.prod(_light_frame(segs, light, cell)[2])) for light in lights)
        budget.check("level", level, 2 * 4 * nodes, f"the shadow grids of level {level} ({nodes:.3g} nodes, float32, "
                     "on the host and the device)")
        made = shadow_grids(segs, lights, cell, st)
        frames = np.stack([np.concatenate([o[None], a]) for _, o, a in made])
        g_dev = []
        while made:  # each light's host grid is let go once it is on the device
            g_dev.append(f32(made.pop(0)[0]))
        g_dev = tuple(g_dev)
    else:
        g_dev, frames = (f32(np.zeros((2, 2, 2))),), np.zeros((1, 4, 3))
    t1 = time.perf_counter()
    w, h = camera.width, camera.height
    wp, hp = -(-w // TILE) * TILE, -(-h // TILE) * TILE
    acc = np.zeros((6, hp * wp))
    buckets = bin_boxes(*segment_boxes(segs, camera), (w, h), TILE)
    dev, cam = segs.device(), f32(camera_array(camera))
    f_dev, c_dev, back = f32(frames), f32(np.full(len(frames), cell)), f32(camera.back)
    perspective = camera.projection == "perspective"

    def run(k, ids, cand, o, d):
        tc = time.perf_counter()
        res = np.asarray(reference_kernel(f32(o), f32(d), jnp.asarray(cand), back, *dev, lit, g_dev, f_dev, c_dev,
                                          steps=steps, perspective=perspective, shadows=shadows), np.float64)
        good = ids >= 0
        for c in range(6):
            acc[c] += np.bincount(ids[good], res[good, c], minlength=acc.shape[1])
        st["composite_seconds"] += time.perf_counter() - tc

    queue = Queue(lambda k: batch_rows(k * steps * 8), run)
    per_tile = TILE * TILE * ss * ss
    r = np.arange(per_tile)
    ry, rx = r // (TILE * ss * ss), (r // (ss * ss)) % TILE  # ray r's pixel in its tile (camera_rays' order)
    group = max(RAYS // per_tile, 1)
    s_lo = 0.0 if perspective else -1e20
    for tl, count, cand in tile_groups(buckets, group):
        padded = np.concatenate([tl, np.repeat(tl[:1], group - len(tl), 0)])
        o, d = camera_rays(jnp.asarray(padded, jnp.int32), cam, tile=TILE, ss=ss, perspective=perspective)
        o, d = o.reshape(-1, 3), d.reshape(-1, 3)
        ray, seg, pairs = near_pairs(o, d, count, cand, per_tile, dev, s_lo)
        pix = ((tl[:, 1, None] * TILE + ry) * wp + tl[:, 0, None] * TILE + rx).reshape(-1)
        o, d = np.asarray(o), np.asarray(d)
        st["pairs"] += pairs
        st["near_pairs"] += len(ray)
        st["rays"] += len(tl) * per_tile
        for k, (rays, near) in compact(ray, seg).items():
            queue.put(k, pix[rays], near, o[rays], d[rays])
            st["rays_hit"] += len(rays)
    queue.flush()
    per = (acc / (ss * ss)).T.reshape(hp, wp, 6).astype(np.float32)
    out = np.concatenate([per[..., :4], np.where(per[..., 5:] > 0, per[..., 4:5] / np.where(per[..., 5:] > 0, per[..., 5:], 1.0),
                                                 np.float32(BACKGROUND_DEPTH))], -1)
    if stats is not None:
        t2 = time.perf_counter()
        comp = st.pop("composite_seconds")
        stats.update(shadow_seconds=t1 - t0, march_seconds=t2 - t1, hits_seconds=t2 - t1 - comp, composite_seconds=comp,
                     samples_per_pixel=ss * ss, steps_per_crossing=steps, shadow_cell=cell, **st)
    out = out[:h, :w]
    if not np.isfinite(out).all():
        raise errors.ValidationError("reference", "non-finite", "the reference produced non-finite pixels")
    return out
