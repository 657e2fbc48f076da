"""Sectors traced on a full circle of view angles, each sample computed once (the scene table's bake).

The ``scene_maps`` bake needs every non-empty sector's α and premultiplied re on V
views θv,i = 2πi/V × L lights (satf eqs 4–5), exactly what ``hairlut.hrir.trace_sectors``
computes with the tracer's conventions (``_direct``'s module docstring).  This kernel computes the
same arrays with less work, using two facts of the planar geometry:

* **Mirror views share their samples.**  The sample at (lane i, step k) of view θ + π is the point
  of view θ at (lane P·rays − 1 − i, step K − 1 − k): with d′ = −d, t′ = −t and z′ = −z,
  −d′_y t′ + d′_x z′ = −d_y t + d_x z.  Density, inside mask and ∇ρ (hence the normal wherever
  ∇ρ is resolved) depend on the point alone, and so does the in-sector transmittance toward each
  light.  So the view march and the light-transmittance lookups (the two gather-heavy parts) run
  on the V/2 views θ < π only; the other half reads them reversed.  What depends on the viewing
  direction (the front-to-back weights w_k = α_k T_k, the Phong half vector, the fallback normal
  n = d where ∇ρ vanishes) is still evaluated per view.
* **The bake shares more** (:func:`bake_view_grid`, :func:`_bake_one`): one optical-depth march on the V/2 views
  gives α and, on the kept views, eq 5's weights both ways along each ray; only the samples where either weight
  is nonzero are shaded (compacted, :func:`_shade_weighted`: outside the sector, on empty cells and past the
  termination nothing is computed), and a view and its mirror share each such sample's normal, light
  transmittance and Phong power |r·d|^p (r·d changes sign, n·l does not where ∇ρ is resolved).
* **Sectors in blocks.**  ``block`` sectors are vmapped together inside one ``lax.map`` (as the
  direct kernel), and the host pads the live sectors to a few bucketed counts, so one compilation
  serves a whole bake.

The light-transmittance lookup is the tracer's (``shadow="grid"``: the light march resampled on an
M × M Cartesian grid, M = min(K, 128), then sampled bilinearly), so the results equal
``trace_sectors``' to float32 rounding (tests/test_map_methods.py).  Float32; the contraction over
the steps and the smoothing state ``precision=HIGHEST``.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..validate import check_int
from ._compact import compact
from ._direct import _SIGMA_PX, bucket
from ._march import (
    SHADOW_GRID,
    direct_lighting,
    fence,
    front_to_back,
    grid_transmittance,
    light_depth_grid,
    march,
    reflectance,
    resolved,
    sample,
    sample_points,
    sector_fields,
    smooth_matrix,
    to_pixels,
    transmittance_at,
)

HIGHEST = jax.lax.Precision.HIGHEST


@partial(jax.jit, static_argnames=("n_pix", "n_steps", "rays", "shadow", "smooth", "eps", "block"))
def view_grid_kernel(
    rho,
    geom,
    views_half,
    lights,
    phong,
    *,
    n_pix: int,
    n_steps: int,
    rays: int = 1,
    shadow: bool = True,
    smooth: bool = True,
    eps: float = 1e-4,
    block: int = 1,
):
    """α (B, V, P) and premultiplied re (B, V, L, P) of B sectors on the views ``views_half`` (V/2,)
    followed by the same views + π, and the lights ``lights`` (L,).  ``rho`` (B, n_s, n_r), ``geom``
    (B, 11) rows of ``hairlut.hrir.GEOM``, ``phong`` = (k_a, k_d, k_s, p); B a multiple of ``block``."""
    one = partial(
        _shade_one, n_pix=n_pix, n_steps=n_steps, rays=rays, shadow=shadow, smooth=smooth, eps=eps, mirror=True, bins=n_pix
    )  # every view of the circle, per pixel
    return jax.lax.map(lambda a: one(a[0], a[1], views_half, lights, phong), (rho, geom), batch_size=block)


#: Sectors per kernel call of :func:`trace_view_grid`.
CALL = 32


def trace_view_grid(
    density, geometry, recipe: dict, *, views: int, lights: int, block: int = 1, progress=None
) -> tuple[np.ndarray, np.ndarray]:
    """α (N, V, P) and premultiplied re (N, V, L, P) of N sectors on θv,i = 2πi/V (V even) and
    θl,j = 2πj/L: what ``hairlut.hrir.trace_sectors`` returns for those grids (float32 rounding
    apart; module docstring), in about half the work.  ``recipe``: an HRIR recipe (``trace`` and
    ``phong``; the light lookup is the tracer's grid).  All-zero sectors give 0 and are not traced;
    the others go through the kernel :data:`CALL` at a time, padded to a bucketed count (few
    compilations).  ``progress(done, total)`` is called after each call."""
    from ._direct import _check_inputs, _settings

    V, L = check_int(views, "views", 2), check_int(lights, "lights", 1)
    if V % 2:
        raise errors.ValidationError("views", V, "an even number of views (θ and θ + π share their samples)")
    cfg, phong = _settings(recipe, None, {}, "grid")
    cfg["shadow"] = bool(cfg["shadow"])
    block = check_int(block, "block", 1)
    n = len(np.asarray(density))
    rho, g, _, _ = _check_inputs(density, geometry, np.zeros(n), np.zeros((n, 1)))
    P = cfg["n_pix"]
    vh = jnp.asarray(2 * np.pi * np.arange(V // 2) / V, jnp.float32)
    lt = jnp.asarray(2 * np.pi * np.arange(L) / L, jnp.float32)
    ph = jnp.asarray(phong, jnp.float32)
    kernel = lambda r, gg: view_grid_kernel(r, gg, vh, lt, ph, block=block, **cfg)  # noqa: E731
    return _live_calls(kernel, rho, g, ((V, P), (V, L, P)), block, "trace_view_grid", progress)


def _live_calls(kernel, rho, g, shapes, block: int, name: str, progress) -> tuple[np.ndarray, ...]:
    """``kernel(rho, geom)``'s float32 outputs of shapes (N, *shape) for ``shapes``: zero for the all-zero
    sectors, the others :data:`CALL` at a time, padded to a bucketed multiple of ``block`` (few
    compilations), checked finite; ``progress(done, total)`` after each call."""
    n = len(rho)
    outs = tuple(np.zeros((n, *shape), np.float32) for shape in shapes)
    live = np.flatnonzero(rho.reshape(n, -1).max(axis=1, initial=0.0) > 0) if n else np.zeros(0, np.int64)
    for start in range(0, live.size, CALL):
        idx = live[start : start + CALL]
        size = bucket(idx.size, block) if idx.size < CALL else idx.size
        size = -(-size // block) * block
        rows = np.concatenate([idx, np.full(size - idx.size, idx[0])])
        got = [np.asarray(x)[: idx.size] for x in kernel(jnp.asarray(rho[rows], jnp.float32), jnp.asarray(g[rows], jnp.float32))]
        if not all(np.isfinite(x).all() for x in got):
            raise errors.HairlutError(f"{name}: the kernel produced non-finite maps (check the density scale)")
        for out, x in zip(outs, got):
            out[idx] = x
        if progress:
            progress(min(start + CALL, live.size), live.size)
    return outs


# ---------------------------------------------------------------------------------------------
# the bake's fast path: α by one matrix product, re only where the table keeps it


def projection_matrix(m: int, views: int, lanes: int, n_steps: int) -> np.ndarray:
    """(m², V/2 · lanes) float32: the tracer's midpoint march (lanes × ``n_steps`` steps over [−R, R], the
    views θi = 2πi/V, i < V/2) through the bilinear interpolant of an m × m Cartesian node grid on the
    sector's [−R, R]² box (nodes at cell centres, zero outside the box), summed over the steps.  It
    does not depend on the sector: R scales out.  Float32 (each entry a sum of ≤ 4·steps weights in [0, 1])."""
    th = 2 * np.pi * np.arange(views // 2) / views
    dx, dy = np.cos(th)[:, None, None], np.sin(th)[:, None, None]
    t = (-1 + (np.arange(lanes) + 0.5) * (2 / lanes))[None, :, None]
    z = (1 - (np.arange(n_steps) + 0.5) * (2 / n_steps))[None, None, :]
    fi, fj = ((-dy * t + dx * z) + 1) / 2 * m - 0.5, ((dx * t + dy * z) + 1) / 2 * m - 0.5  # view_points / R
    i0, j0 = np.floor(fi).astype(np.int64), np.floor(fj).astype(np.int64)
    a, b = fi - i0, fj - j0
    col = np.broadcast_to(np.arange(views // 2 * lanes).reshape(views // 2, lanes, 1), fi.shape)
    out = np.zeros((m * m, views // 2 * lanes), np.float32)
    for di, dj, w in ((0, 0, (1 - a) * (1 - b)), (1, 0, a * (1 - b)), (0, 1, (1 - a) * b), (1, 1, a * b)):
        i, j = i0 + di, j0 + dj
        ok = (i >= 0) & (i < m) & (j >= 0) & (j < m)
        np.add.at(out, ((i * m + j)[ok], col[ok]), w[ok])
    return out


def _shade_one(rho, g, views_kept, lights, phong, *, n_pix, n_steps, rays, shadow, smooth, eps, mirror, bins):
    """Per-bin α (Vr, Q) and premultiplied re (Vr, L, Q) of one sector on the kept views (the ratio's):
    ``views_kept`` then, with ``mirror``, the same + π (their samples and light lookups shared: the module docstring)."""
    fields = sector_fields(rho)
    lanes = n_pix * rays
    flip = (lambda x: jnp.concatenate([x, jnp.flip(x, axis=(1, 2))], axis=0)) if mirror else (lambda x: x)
    tau, gx, gy, rs, rr, inside = (flip(x) for x in march(fields, g, views_kept, lanes, n_steps))
    views = jnp.concatenate([views_kept, views_kept + jnp.pi]) if mirror else views_kept
    w, alpha = front_to_back(tau, eps)
    direct = direct_lighting(rho, gx, gy, rs, rr, inside, views, lights, phong)  # (Vr, L, lanes, K)
    if shadow:
        depth = light_depth_grid(fields, g, lights, n_steps, min(n_steps, SHADOW_GRID))
        direct = direct * jnp.moveaxis(flip(grid_transmittance(depth, g, views_kept, lanes, n_steps)), -1, 1)
    S = smooth_matrix(g[_SIGMA_PX], n_pix) if smooth else None
    a, r = to_pixels(alpha, n_pix, rays, S), to_pixels(reflectance(alpha, direct, w, phong), n_pix, rays, S)
    return a.reshape(*a.shape[:-1], bins, -1).sum(-1), r.reshape(*r.shape[:-1], bins, -1).sum(-1)


def _mirror_phong(scale, gx, gy, rs, rr, inside, vx, vy, lights, phong, power: int = 0):
    """The Phong direct term (``hairlut.hrir`` ``phong_direct``, eq 5's shading) at march samples seen along d = (``vx``,
    ``vy``) (the samples' shape) and from the mirror view −d: two (..., L) arrays (lights minor), from one power per
    (sample, light).  ``scale``: the sector's peak density (the normal's resolution threshold, ``hairlut.hrir``
    ``normals``).

    With d′ = −d: where ∇ρ is resolved the normal is the same, so n·l′ = n·l and r·d′ = −r·d; where it is not
    (n = d, n′ = −d) n′·l = −n·l and r′·d′ = −r·d too.  So |r·d|^p is shared and lands on whichever view of the
    pair has r·d > 0; the diffuse max(0, n·l) is shared where the normal is resolved.  ``power`` > 0 (static: the
    shininess p when it is that integer) forms |r·d|^p by repeated multiplication instead of exp(p log |r·d|) (two
    transcendentals per (sample, light); the same to float32 rounding)."""
    ok, inv = resolved(scale, gx, gy, rs, rr, inside)
    nx, ny = jnp.where(ok, -gx * inv, vx)[..., None], jnp.where(ok, -gy * inv, vy)[..., None]
    lx, ly = jnp.cos(lights), jnp.sin(lights)
    vx, vy = vx[..., None], vy[..., None]
    nl = nx * lx + ny * ly
    rv = 2 * nl * (nx * vx + ny * vy) - (lx * vx + ly * vy)
    cos = jnp.minimum(jnp.abs(rv), 1.0)  # |r·d| ≤ 1, clamped as ``phong_direct`` clamps it (rounding, amplified by p)
    if power:
        spec = phong[2] * jax.lax.integer_pow(cos, power)
    else:
        spec = phong[2] * jnp.exp(phong[3] * jnp.log(jnp.where(rv != 0, cos, 1.0)))
    nl_m = jnp.where(ok[..., None], nl, -nl)
    front = phong[1] * jnp.maximum(nl, 0.0) + jnp.where((nl > 0) & (rv > 0), spec, 0.0)
    back = phong[1] * jnp.maximum(nl_m, 0.0) + jnp.where((nl_m > 0) & (rv < 0), spec, 0.0)
    return front, back


def _weights(opacity, depth_before, eps):
    """Eq 5's w_k = α_k T_k, T_k = exp(−``depth_before``), zero once T_k < ``eps`` (``hairlut.hrir`` ``front_to_back``)."""
    trans = jnp.exp(-depth_before)
    return jnp.where(trans >= eps, opacity * trans, 0.0)


#: Samples shaded per step of :func:`_shade_weighted`'s loop (the fastest of 4,096 … 16,384 measured on XLA:CPU).
SHADE_CHUNK = 8192


def _shade_weighted(fields, scale, g, views, lights, phong, w, w_m, light_depth, *, power: int, chunk: int = SHADE_CHUNK):
    """Eq 5's Σ_k w_k direct_k of a march on ``views`` (Vk,) with weights ``w`` (Vk, lanes, K), and of the mirror views
    with ``w_m`` (in the march's sample order): two (Vk, L, lanes) arrays, the mirror's lanes in the march's order.

    Only the samples where either weight is nonzero are shaded: they are compacted (``_compact``) and shaded
    ``chunk`` at a time (a while loop over ⌈count/chunk⌉ steps), each sample's ∇ρ, Phong terms
    (:func:`_mirror_phong`) and light transmittance (``hairlut.hrir`` ``transmittance_at`` in ``light_depth``, or 1
    when it is None) computed once for both views, its products with the two weights added into its lane
    (a sorted scatter-add, in step order).  A sample of zero weight adds nothing, so the sums are the dense
    contraction's (tests/test_view_grid.py: against the tracer) at a cost that follows the live samples: 30 % of
    the box on the paper model's sectors, fewer on thin strands.  Each step's pieces run behind
    ``hairlut.hrir`` ``fence`` calls (XLA:CPU would otherwise recompute a gather's index arithmetic per consumer)."""
    Vk, lanes, K = w.shape
    L = lights.shape[0]
    w, w_m = w.reshape(-1), w_m.reshape(-1)
    live, count = fence(lambda a, b: compact((a > 0) | (b > 0)), w, w_m)
    live = jnp.concatenate([live, jnp.zeros(chunk, live.dtype)])  # the last step's slice stays in bounds
    cv, sv = jnp.cos(views), jnp.sin(views)

    def step(carry):
        j, acc = carry
        ids = jax.lax.dynamic_slice(live, (j * chunk,), (chunk,))
        valid = j * chunk + jnp.arange(chunk) < count
        v, lane, k = ids // (lanes * K), (ids // K) % lanes, ids % K
        qx, qy, dx, dy = fence(lambda v, lane, k: (*sample_points(g, cv[v], sv[v], lane, k, lanes, K), cv[v], sv[v]), v, lane, k)
        _, inside, gx, gy, rs, rr = fence(lambda x, y: sample(fields, g, x, y, fenced=True), qx, qy)
        front, back = fence(lambda *a: _mirror_phong(scale, *a, lights, phong, power), gx, gy, rs, rr, inside, dx, dy)
        if light_depth is not None:
            t_l = fence(lambda x, y: transmittance_at(light_depth, g, x, y), qx, qy)
            front, back = front * t_l, back * t_l
        wk, wmk = (jnp.where(valid, x[ids], 0.0)[:, None] for x in (w, w_m))
        return j + 1, acc.at[ids // K].add(jnp.concatenate([front * wk, back * wmk], axis=1), indices_are_sorted=True)

    acc = jnp.zeros((Vk * lanes, 2 * L), w.dtype)
    _, acc = jax.lax.while_loop(lambda c: c[0] * chunk < count, step, (jnp.int32(0), acc))
    acc = jnp.moveaxis(acc.reshape(Vk, lanes, 2, L), 1, -1)  # (Vk, 2, L, lanes)
    return acc[:, 0], acc[:, 1]


def _bake_one(
    rho, g, views_half, lights, phong, *, n_pix, n_steps, rays, step, shadow, smooth, eps, bins, alpha, power=0, shadow_grid=0
):
    """``_shade_one``'s per-bin α and re on the kept views (every ``step``-th of ``views_half``, then the same + π),
    from one optical-depth march: eq 5's weights both ways along each ray, then the shading of the samples where
    either is nonzero (:func:`_shade_weighted`: each sample's normal, light transmittance and Phong power computed once
    for a view and its mirror).  With ``alpha``, the march runs on every view of ``views_half`` and α (V/2, lanes) of
    all of them (eq 5's Σ_k w_k) comes back too, else on the kept views only and α is None.  ``shadow_grid``:
    :func:`bake_view_grid`'s (0: the tracer's light grid)."""
    fields = sector_fields(rho)
    lanes = n_pix * rays
    views = views_half[::step]
    tau = march(fields, g, views_half if alpha else views, lanes, n_steps, fenced=True, depth_only=True)
    # eq 5's weights both ways along each ray from one product with the strict triangles (XLA:CPU's cumsum is a
    # reduce-window): T_k = exp(−Σ_{i<k} τ_i) from the march's side, exp(−Σ_{i>k} τ_i) from the mirror's, each summed
    # directly; as differences of one prefix sum they cancelled at large optical depths (``hairlut.hrir``
    # ``exclusive_depth``)
    K = n_steps
    sides = jnp.concatenate([jnp.triu(jnp.ones((K, K), tau.dtype), 1), jnp.tril(jnp.ones((K, K), tau.dtype), -1)], axis=1)
    depths = jnp.matmul(tau, sides, precision=HIGHEST)
    before, after = depths[..., :K], depths[..., K:]
    opacity = -jnp.expm1(-tau)
    w_all = _weights(opacity, before, eps)
    a_all = jnp.sum(w_all, axis=-1)
    opacity, after, w, a = (x[::step] for x in (opacity, after, w_all, a_all)) if alpha else (opacity, after, w_all, a_all)
    w_m = _weights(opacity, after, eps)  # the mirror views' weights, in the march's order
    a_m = jnp.flip(jnp.sum(w_m, axis=-1), axis=-1)  # lanes in the mirror's order
    light_depth = (
        light_depth_grid(fields, g, lights, n_steps, shadow_grid or min(n_steps, SHADOW_GRID), fenced=True) if shadow else None
    )
    direct, direct_m = _shade_weighted(fields, jnp.max(jnp.abs(rho)), g, views, lights, phong, w, w_m, light_depth, power=power)
    # eq 5's k_a α + Σ_k w_k direct_k (``hairlut.hrir`` ``reflectance``) in this layout: (Vk, L, lanes)
    r = phong[0] * a[:, None] + direct
    r_m = phong[0] * a_m[:, None] + jnp.flip(direct_m, axis=-1)  # lanes in the mirror's order
    S = smooth_matrix(g[_SIGMA_PX], n_pix) if smooth else None
    ab, rb = (to_pixels(jnp.concatenate(x, axis=0), n_pix, rays, S) for x in ((a, a_m), (r, r_m)))
    binned = tuple(x.reshape(*x.shape[:-1], bins, -1).sum(-1) for x in (ab, rb))
    return (a_all if alpha else None), *binned


@partial(
    jax.jit,
    static_argnames=(
        "n_views",
        "n_pix",
        "n_steps",
        "rays",
        "m",
        "shade_rays",
        "shade_steps",
        "shadow",
        "smooth",
        "eps",
        "mirror",
        "bins",
        "power",
        "shadow_grid",
    ),
)
def bake_grid_kernel(
    rho,
    geom,
    proj,
    views_kept,
    lights,
    phong,
    *,
    n_views: int,
    n_pix: int,
    n_steps: int,
    rays: int,
    m: int,
    shade_rays: int,
    shade_steps: int,
    shadow: bool = True,
    smooth: bool = True,
    eps: float = 1e-4,
    mirror: bool = True,
    bins: int = 8,
    power: int = 0,
    shadow_grid: int = 0,
):
    """The scene bake's arrays of B sectors: α (B, V/2, P) on the views 2πi/V, i < V/2, and per bin of P/Q
    pixels α (B, Vr, Q) and premultiplied re (B, Vr, L, Q) on the ratio's views (:func:`bake_view_grid`).

    α (eq 4), with ``m`` > 0: each sector's density sampled on an m × m Cartesian node grid of its [−R, R]²
    box (the exact bilinear (s, r) interpolant at m² points), then every view's march at once as one
    product with ``proj`` (:func:`projection_matrix`, precision HIGHEST): τ = σ_t Δs Σ_k ρ(q_k),
    α = 1 − e^−τ (eq 5's Σ_k w_k without the ``eps`` cut-off, which changes α by < eps), rays averaged,
    smoothed; with ``m`` = 0, the tracer's march per view (eq 5's Σ_k w_k; ``proj`` unused).
    re (eq 5): the tracer's own march with ``shade_rays`` rays per pixel and ``shade_steps`` steps (0: the
    trace's), on the kept views only; when the kept views' mirrors are kept too (``mirror``), each view and its
    mirror share samples, light lookups and Phong powers, and only the samples of nonzero weight are shaded
    (:func:`_bake_one`); at the trace's own rays and steps with ``m`` = 0 the one march gives both α and the
    shading (the α march above is not run); otherwise :func:`_shade_one` (the tracer's dense path).  ``power``: the
    Phong exponent when it is that integer (:func:`_mirror_phong`), else 0.  ``shadow_grid``:
    :func:`bake_view_grid`'s, on the mirror path."""
    lanes = n_pix * rays
    half = n_views // 2
    sr, sk = shade_rays or rays, shade_steps or n_steps
    shared = mirror and not m and (sr, sk) == (rays, n_steps)  # α's march is the shading's on the kept views
    S = jax.vmap(lambda s: smooth_matrix(s, n_pix))(geom[:, _SIGMA_PX]) if smooth else None
    if mirror:
        # the V/2 views as the host computes them (float64, then rounded): the kept ones bitwise views_kept
        views = jnp.asarray(2 * np.pi * np.arange(half) / n_views, rho.dtype) if shared else views_kept
        shade = partial(
            _bake_one,
            n_pix=n_pix,
            n_steps=sk,
            rays=sr,
            step=half // views_kept.shape[0] if shared else 1,
            shadow=shadow,
            smooth=smooth,
            eps=eps,
            bins=bins,
            alpha=shared,
            power=power,
            shadow_grid=shadow_grid,
        )
        alpha, ab, rb = jax.lax.map(lambda a: shade(a[0], a[1], views, lights, phong), (rho, geom))
    else:
        shade = partial(
            _shade_one, n_pix=n_pix, n_steps=sk, rays=sr, shadow=shadow, smooth=smooth, eps=eps, mirror=False, bins=bins
        )
        ab, rb = jax.lax.map(lambda a: shade(a[0], a[1], views_kept, lights, phong), (rho, geom))
    if m:

        def nodes(r, g):  # σ_t ρ 2R/m at the m × m node grid (x major): the view-0 march's samples, x reversed
            return jnp.flip(
                march(sector_fields(r), g, jnp.zeros(1, rho.dtype), m, m, fenced=True, depth_only=True)[0], axis=1
            ).T.reshape(-1)

        tau_nodes = jax.lax.map(lambda a: nodes(a[0], a[1]), (rho, geom))  # (B, m²)
        tau = jnp.matmul(tau_nodes, proj, precision=HIGHEST).reshape(-1, half, lanes) * (m / n_steps)
        alpha = -jnp.expm1(-tau)
    elif not shared:  # the tracer's march on the V/2 views, eq 5's Σ_k w_k with its cut-off
        views = 2 * jnp.pi * jnp.arange(half, dtype=rho.dtype) / (2 * half)
        alpha = jax.lax.map(
            lambda a: front_to_back(march(sector_fields(a[0]), a[1], views, lanes, n_steps, fenced=True, depth_only=True), eps)[
                1
            ],
            (rho, geom),
        )
    alpha = to_pixels(alpha, n_pix, rays)
    if smooth:
        alpha = jnp.einsum("bvp,bpq->bvq", alpha, S, precision=HIGHEST)
    return alpha, ab, rb


_PROJ: dict[tuple, jax.Array] = {}  # one entry: (m, V, lanes, steps) → projection_matrix on the device


def bake_view_grid(
    density,
    geometry,
    recipe: dict,
    *,
    views: int,
    lights: int,
    ratio_step: int = 1,
    bins: int,
    alpha_grid: int,
    shade_rays: int | None = None,
    shade_steps: int | None = None,
    shadow_grid: int = 0,
    progress=None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the scene table stores, computed directly: α (N, V/2, P) on θv,i = 2πi/V, i < V/2, and per bin
    of P/``bins`` pixels α (N, Vr, Q) and premultiplied re (N, Vr, L, Q) on the ratio's views θv,i,
    i = 0, ``ratio_step``, 2·ratio_step, … (Vr = V/ratio_step) and θl,j = 2πj/L (:func:`bake_grid_kernel`).

    Against :func:`trace_view_grid` (the reference: every view and light per pixel, then binned): α
    through an ``alpha_grid`` × ``alpha_grid`` Cartesian resampling of each sector's density (one
    matrix product for all views instead of a polar-coordinate march per view; its error falls with
    ``alpha_grid``: tests/test_view_grid.py states the bound), re on the kept views only and, when
    ``shade_rays`` / ``shade_steps`` are given, with those rays per pixel and march steps instead
    of the recipe's.  The light transmittance (eq 5's self-shadowing, ``shadow="grid"``) is the tracer's unless
    ``shadow_grid`` > 0 (the Cartesian light-depth grid's side M instead of min(steps, 128); it applies where a view
    and its mirror are shaded together, ratio_step dividing V/2).  All-zero sectors give 0 and are not traced."""
    from ._direct import _check_inputs, _settings

    V, L = check_int(views, "views", 2), check_int(lights, "lights", 1)
    if V % 2:
        raise errors.ValidationError("views", V, "an even number of views (θ and θ + π share their samples)")
    step = check_int(ratio_step, "ratio_step", 1)
    if V % step:
        raise errors.ValidationError("ratio_step", step, f"must divide views ({V})")
    m = check_int(alpha_grid, "alpha_grid", 0)
    if m == 1:
        raise errors.ValidationError("alpha_grid", m, "0 (the tracer's march) or a node grid side ≥ 2")
    cfg, phong = _settings(recipe, None, {}, "grid")
    P, Q = cfg["n_pix"], check_int(bins, "bins", 1)
    if P % Q:
        raise errors.ValidationError("bins", Q, f"must divide the pixels ({P})")
    sr = cfg["rays"] if shade_rays is None else check_int(shade_rays, "shade_rays", 1)
    sk = cfg["n_steps"] if shade_steps is None else check_int(shade_steps, "shade_steps", 2)
    grid = check_int(shadow_grid, "shadow_grid", 0)
    if grid == 1:
        raise errors.ValidationError("shadow_grid", grid, "0 (min(steps, 128)) or a grid side ≥ 2")
    n = len(np.asarray(density))
    rho, g, _, _ = _check_inputs(density, geometry, np.zeros(n), np.zeros((n, 1)))
    key = (m, V, P * cfg["rays"], cfg["n_steps"])
    if not m:
        _PROJ[key] = jnp.zeros((1, 1), jnp.float32)  # unused: α by the tracer's march
    elif key not in _PROJ:
        _PROJ.clear()
        _PROJ[key] = jnp.asarray(projection_matrix(*key))
    mirror = (V // 2) % step == 0  # the kept views' mirrors are kept views too: march V/(2·step), read both
    kept = np.arange(0, V // 2 if mirror else V, step)
    Vr = V // step
    vk = jnp.asarray(2 * np.pi * kept / V, jnp.float32)
    lt = jnp.asarray(2 * np.pi * np.arange(L) / L, jnp.float32)
    ph = jnp.asarray(phong, jnp.float32)
    settings = dict(
        n_views=V,
        n_pix=P,
        n_steps=cfg["n_steps"],
        rays=cfg["rays"],
        m=m,
        shade_rays=sr,
        shade_steps=sk,
        shadow=bool(cfg["shadow"]),
        smooth=cfg["smooth"],
        eps=cfg["eps"],
        mirror=mirror,
        bins=Q,
        power=int(phong[3]) if phong[3] == int(phong[3]) and 1 <= phong[3] <= 64 else 0,
        shadow_grid=grid,
    )
    kernel = lambda r, gg: bake_grid_kernel(r, gg, _PROJ[key], vk, lt, ph, **settings)  # noqa: E731
    return _live_calls(kernel, rho, g, ((V // 2, P), (Vr, Q), (Vr, L, Q)), 1, "bake_view_grid", progress)
