"""The strand render's ray march: the strands' Gaussian tubes ray-marched through the camera (``_strands``).

**Opacity** (Beer–Lambert).  Each camera ray meets the tubes of the segments binned to its screen tile
(``_tiles``) that it passes near (``_hits``: a first pass keeps, per ray, only the pairs that can add optical
depth); every such crossing's support is cut into ``steps`` equal steps whose optical depth is the exact
integral of that segment's density (``_strands.crossings``).  The steps of all crossings are sorted along the
ray and composited front to back: a step of optical depth τ_k weighs w_k = (1 − e^{−τ_k}) Π_{j<k} e^{−τ_j};
the pixel's α is 1 − exp(−Σ τ) (exact, whatever the step).

**Shading** (the scene's terms, satf eqs 8–11 / Scheuermann, through ``hairlut.synth.lighting_kernel``)
with each segment's own tangent, the normal facing the viewer (n = unit(v − (v·t) t)), the camera's
viewing direction v, and no environment term: colour_k = Σ_lights T_l(x_k) · lighting(t_k, l).
Noise, when on, takes its mean (½).  **Shadows**: T_l(x_k) = exp(−τ_l(x_k)), τ_l the optical depth from
the step's mid-point x_k toward light l through the same tubes (``_light``), off when the scene's shadow method is
``none``.  While the lights' grids at level ℓ's cell 4 r̄ / 2^ℓ (r̄ the median strand radius) hold at most
``GRID_NODES`` nodes, τ_l is exact at the grid's nodes and interpolated trilinearly; beyond, each step casts its
own exact shadow ray (memory: the image's samples, a batch at a time, not the hair's bounds).  Either way only
the steps in front of a camera transmittance of ``SEEN`` need it (those behind weigh less together and keep T = 1).

**Convergence.**  Level ℓ takes 4^ℓ samples per pixel (box filter) on a rank-1 lattice (:func:`pixel_offsets`:
4^ℓ distinct columns and rows, where the regular 2^ℓ × 2^ℓ grid has 2^ℓ, so a strand thinner than the grid's spacing
is not seen by whole rows or missed by them; on a dense 32² window of Ratboy at 128² its α error is 1.1–1.6× smaller
at 4–64 samples against 256 samples of either pattern, ``benchmarks/reference_convergence.py``), 2^(ℓ+1) steps per
crossing and (on the grid) a cell of 4 r̄ / 2^ℓ; the exact rays are the grid's limit.  :func:`render_strands`
refines level by level until the image changes by less than ``bound`` (RMSE of premultiplied RGB and of α,
each) from the level before, and stores the levels' changes; ``converged`` is false when ``max_level`` is
reached first.
"""

from __future__ import annotations

import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..march import exclusive_depth
from ._hits import RAYS, Queue, batch_rows, compact, near_pairs, tile_groups
from ._light import grid_depths, grid_nodes, light_index, point_depths, shadow_grids
from ._strands import Z_CUT, Segments, crossings
from ._tiles import bin_boxes

#: Screen tiles of the segments' bins: ``TILE`` pixels at one sample per pixel, ``TILE`` / ss (at least ``MIN_TILE``) at
#: ss × ss, so a tile's rays stay about ``TILE``² whatever the level and each tests fewer candidates (Ratboy at 128²,
#: a 32² window at level 2 without shadows: 41 → 8.4 M pairs tested, 4.5 → 1.9 CPU s warm, the image bitwise equal).
TILE = 8
MIN_TILE = 2
BACKGROUND_DEPTH = 1e10
#: Steps behind a camera transmittance below this are shaded without their shadow ray (:func:`step_points`): they
#: weigh less than SEEN together, so a pixel's colour moves by less than SEEN × its brightest lighting.
SEEN = 1e-5
#: A level's shadows come from the lights' grids (``_light.shadow_grids``, cell 4 r̄ / 2^ℓ) while they hold at most
#: this many nodes in all (2 GiB of float32: Sintel's level 3, 4.2e8 nodes), else from an exact shadow ray per step
#: (``_light.point_depths``; Ratboy from level 1 on, 1e9 nodes).
GRID_NODES = 1 << 29
#: The pixel samples: the rank-1 lattice of :func:`pixel_offsets` (True) or the regular grid (False).
LATTICE = True


def lattice_generator(n: int) -> int:
    """The generator g of the rank-1 lattice {((i + ½)/n, ((i·g mod n) + ½)/n)} of ``n`` points whose shortest
    vector on the unit torus is longest (the best-spread Korobov lattice; g = 1 for n ≤ 2)."""
    best, gen = -1.0, 1
    i = np.arange(1, n)
    for g in range(1, max(n, 2), 2):
        dx, dy = i / n, (i * g % n) / n
        m = float((np.minimum(dx, 1 - dx) ** 2 + np.minimum(dy, 1 - dy) ** 2).min()) if n > 1 else 0.0
        if m > best + 1e-12:
            best, gen = m, g
    return gen


def pixel_offsets(ss: int, lattice: bool) -> np.ndarray:
    """(ss², 2) sample offsets (x, y) in a pixel: the regular ss × ss grid (sample i = sy·ss + sx) or the rank-1
    lattice of :func:`lattice_generator` (n = ss² distinct columns and rows: a thin strand at any angle meets
    about n·width of them, not ss·width or none)."""
    n = ss * ss
    i = np.arange(n)
    if lattice:
        return np.stack([(i + 0.5) / n, (i * lattice_generator(n) % n + 0.5) / n], 1)
    return np.stack([(i % ss + 0.5) / ss, (i // ss + 0.5) / ss], 1)


@partial(jax.jit, static_argnames=("tile", "ss", "perspective", "lattice"))
def camera_rays(tiles, cam, *, tile: int, ss: int, perspective: bool, lattice: bool = False):
    """Origins and unit directions (T, R, 3) of the rays of T tiles: R = tile² pixels × ss² samples, ray r =
    (y·tile + x)·ss² + i, sample i at :func:`pixel_offsets` (``lattice`` or the grid).  ``cam`` (6, 3): eye,
    right, up, back, (half width, half height, 0) of the frame at unit distance (perspective) or in world units
    (orthographic), (width, height, 0) in pixels."""
    eye, right, up, back, half = cam[0], cam[1], cam[2], cam[3], cam[4]
    sub = jnp.asarray(pixel_offsets(ss, lattice), jnp.float32)
    pix = jnp.arange(tile, dtype=jnp.float32)
    px = tiles[:, 0, None, None, None] * tile + pix[None, None, :, None] + sub[None, None, None, :, 0]
    py = tiles[:, 1, None, None, None] * tile + pix[None, :, None, None] + sub[None, None, None, :, 1]
    px, py = jnp.broadcast_arrays(px, py)  # (T, y, x, i)
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


@partial(jax.jit, static_argnames=("steps", "perspective"))
def step_points(o, d, cand, p0, t, length, radius, sigma_t, *, steps: int, perspective: bool):
    """The steps of N rays (``o``, ``d`` (N, 3)) through their near segments ``cand`` (N, K) (−1: none), M = K·steps
    of them per ray sorted along it: optical depth τ (N, M) (``_strands.crossings``: each crossing's support cut
    into ``steps`` equal steps), mid-point s (N, M), segment (N, M) (0 where none: τ = 0), mid-point x (N, M, 3) and
    whether the step needs its shadow (N, M): it holds optical depth and the camera ray's transmittance in front of
    it is at least ``SEEN`` (the steps behind weigh less than ``SEEN`` together).  The crossings are found once
    here; :func:`strand_march_kernel` composites these sorted steps."""
    valid = cand >= 0
    ix = jnp.where(valid, cand, 0)
    tau, s = crossings(
        o[:, None], d[:, None], *(a[ix] for a in (p0, t, length, radius, sigma_t)), 0.0 if perspective else -1e20, steps
    )
    tau = jnp.where(valid[..., None], tau, 0.0)
    n = tau.shape[0]
    seg = jnp.broadcast_to(ix[..., None], tau.shape)
    s_, tau_, seg_ = jax.lax.sort((s.reshape(n, -1), tau.reshape(n, -1), seg.reshape(n, -1)), dimension=-1, num_keys=1)
    front = exclusive_depth(tau_)  # optical depth in front of each step, in ray order (never total − own step)
    x = o[:, None] + s_[..., None] * d[:, None]
    return tau_, s_, seg_, x, (tau_ > 0) & (front < -np.log(SEEN))


@partial(jax.jit, static_argnames=("perspective",))
def strand_march_kernel(tau, s, seg, d, back, lit, shade, *, perspective: bool):
    """Premultiplied RGB, α, Σ w·depth and Σ w of N rays (unit directions ``d`` (N, 3)) from their steps sorted along
    the ray (:func:`step_points`: optical depth ``tau``, mid-point ``s``, segment ``seg``, all (N, M)): (N, 6)
    (module docstring).  ``back`` (3,) the camera's back axis; ``lit`` (S, L, 3) each segment's lighting; ``shade``
    (N, M, L) each step's optical depth toward each light (``_light``; zeros: no shadows)."""
    colour = (lit[seg] * jnp.exp(-shade)[..., None]).sum(-2)  # (N, M, 3)
    depth = s * (-(d * back).sum(-1))[:, None] if perspective else s
    w = -jnp.expm1(-tau) * jnp.exp(-exclusive_depth(tau))
    alpha = -jnp.expm1(-tau.sum(-1))
    rgb = (w[..., None] * colour).sum(1)
    return jnp.concatenate([rgb, jnp.stack([alpha, (w * depth).sum(-1), w.sum(-1)], -1)], -1)


def camera_array(camera) -> np.ndarray:
    """The (6, 3) camera rows :func:`strand_march_kernel` and the rasteriser take."""
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


def render_level(
    segs: Segments,
    camera,
    lit,
    lights,
    *,
    level: int,
    shadows: bool,
    stats: dict | None = None,
    samples: int | None = None,
    steps: int | None = None,
    lattice: bool | None = None,
) -> np.ndarray:
    """The (h, w, 5) RGBA + depth of one convergence level (module docstring).  ``stats`` gets where the shadows came
    from (``grid`` or ``rays``), the seconds of the lights' grids or indexes, of the shadow lookups (``_light``), of
    the first pass (``_hits``) and of the second (:func:`strand_march_kernel`), and the pair counts."""
    ss = 1 << level if samples is None else int(samples)
    steps = 2 << level if steps is None else int(steps)
    lattice = LATTICE if lattice is None else bool(lattice)
    t0 = time.perf_counter()
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    dev = segs.device()
    st = {"pairs": 0, "near_pairs": 0, "rays": 0, "rays_hit": 0, "composite_seconds": 0.0, "shadow_seconds": 0.0}
    cell = 4.0 * float(np.median(segs.radius)) / (1 << level)
    lookups, source = [], "none"
    if shadows and grid_nodes(segs, lights, cell) <= GRID_NODES:
        lookups, source = [partial(grid_depths, *g, cell) for g in shadow_grids(segs, lights, cell, st)], "grid"
    elif shadows:
        lookups, source = [partial(point_depths, light_index(segs, light), dev=dev, stats=st) for light in lights], "rays"
    t1 = time.perf_counter()
    w, h = camera.width, camera.height
    tile = max(MIN_TILE, TILE // ss)
    wp, hp = -(-w // tile) * tile, -(-h // tile) * tile
    acc = np.zeros((6, hp * wp))
    buckets = bin_boxes(*segment_boxes(segs, camera), (w, h), tile)
    cam = f32(camera_array(camera))
    back = f32(camera.back)
    perspective = camera.projection == "perspective"
    n_l = lit.shape[1]

    def run(k, ids, cand, o, d):
        tc = time.perf_counter()
        o, d, cand = f32(o), f32(d), jnp.asarray(cand)
        tau, s, seg, x, live = step_points(o, d, cand, *dev, steps=steps, perspective=perspective)
        shade = np.zeros((len(ids), k * steps, n_l), np.float32)
        if lookups:
            ts = time.perf_counter()
            live = np.asarray(live) & (ids >= 0)[:, None]
            pts = np.asarray(x)[live]
            for li, lookup in enumerate(lookups):
                shade[live, li] = lookup(pts)
            st["shadow_seconds"] += time.perf_counter() - ts
        res = np.asarray(strand_march_kernel(tau, s, seg, d, back, lit, f32(shade), perspective=perspective), np.float64)
        good = ids >= 0
        for c in range(6):
            acc[c] += np.bincount(ids[good], res[good, c], minlength=acc.shape[1])
        st["composite_seconds"] += time.perf_counter() - tc

    queue = Queue(lambda k: batch_rows(k * steps * 8), run)
    per_tile = tile * tile * ss * ss
    r = np.arange(per_tile)
    ry, rx = r // (tile * ss * ss), (r // (ss * ss)) % tile  # ray r's pixel in its tile (camera_rays' order)
    group = max(RAYS // per_tile, 1)
    s_lo = 0.0 if perspective else -1e20
    for tl, count, cand in tile_groups(buckets, group):
        padded = np.concatenate([tl, np.repeat(tl[:1], group - len(tl), 0)])
        o, d = camera_rays(jnp.asarray(padded, jnp.int32), cam, tile=tile, ss=ss, perspective=perspective, lattice=lattice)
        o, d = o.reshape(-1, 3), d.reshape(-1, 3)
        ray, seg, pairs = near_pairs(o, d, count, cand, per_tile, dev, s_lo)
        pix = ((tl[:, 1, None] * tile + ry) * wp + tl[:, 0, None] * tile + rx).reshape(-1)
        o, d = np.asarray(o), np.asarray(d)
        st["pairs"] += pairs
        st["near_pairs"] += len(ray)
        st["rays"] += len(tl) * per_tile
        for k, (rays, near) in compact(ray, seg).items():
            queue.put(k, pix[rays], near, o[rays], d[rays])
            st["rays_hit"] += len(rays)
    queue.flush()
    per = (acc / (ss * ss)).T.reshape(hp, wp, 6).astype(np.float32)
    out = np.concatenate(
        [
            per[..., :4],
            np.where(
                per[..., 5:] > 0, per[..., 4:5] / np.where(per[..., 5:] > 0, per[..., 5:], 1.0), np.float32(BACKGROUND_DEPTH)
            ),
        ],
        -1,
    )
    if stats is not None:
        t2 = time.perf_counter()
        comp, shade_s = st.pop("composite_seconds"), st.pop("shadow_seconds")
        stats.update(
            shadow_source=source,
            shadow_cell=cell if source == "grid" else None,
            setup_seconds=t1 - t0,
            shadow_seconds=shade_s,
            march_seconds=t2 - t1,
            hits_seconds=t2 - t1 - comp,
            composite_seconds=comp - shade_s,
            samples_per_pixel=ss * ss,
            steps_per_crossing=steps,
            pattern="lattice" if lattice else "grid",
            **st,
        )
    out = out[:h, :w]
    if not np.isfinite(out).all():
        raise errors.ValidationError("strands", "non-finite", "the strand render produced non-finite pixels")
    return out
