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
from ..hrir import (SHADOW_GRID, direct_lighting, front_to_back, grid_transmittance, light_depth_grid, march,
                    reflectance, sector_fields, smooth_matrix, to_pixels)
from ._direct import _SIGMA_PX, bucket


def _grid_one(rho, g, views_half, lights, phong, *, n_pix, n_steps, rays, shadow, smooth, eps):
    """α (V, P) and premultiplied re (V, L, P) of one sector on the views θ (V/2,) and θ + π."""
    fields = sector_fields(rho)
    lanes = n_pix * rays
    flip = lambda x: jnp.flip(x, axis=(1, 2))  # noqa: E731  (views, lanes, steps): the mirror view's order
    half = march(fields, g, views_half, lanes, n_steps)  # each (H, lanes, K)
    tau, gx, gy, rs, rr, inside = (jnp.concatenate([x, flip(x)], axis=0) for x in half)
    views = jnp.concatenate([views_half, views_half + jnp.pi])
    w, alpha = front_to_back(tau, eps)  # eq 5 front-to-back weights (per view)
    direct = direct_lighting(rho, gx, gy, rs, rr, inside, views, lights, phong)  # (V, L, lanes, K)
    if shadow:
        depth = light_depth_grid(fields, g, lights, n_steps, min(n_steps, SHADOW_GRID))  # (M, M, L)
        t_half = grid_transmittance(depth, g, views_half, lanes, n_steps)  # (H, lanes, K, L)
        trans_l = jnp.concatenate([t_half, flip(t_half)], axis=0)  # the mirror views read it reversed
        direct = direct * jnp.moveaxis(trans_l, -1, 1)
    refl = reflectance(alpha, direct, w, phong)
    S = smooth_matrix(g[_SIGMA_PX], n_pix) if smooth else None
    alpha, refl = to_pixels(alpha, n_pix, rays, S), to_pixels(refl, n_pix, rays, S)
    return alpha, refl


@partial(jax.jit, static_argnames=("n_pix", "n_steps", "rays", "shadow", "smooth", "eps", "block"))
def view_grid_kernel(rho, geom, views_half, lights, phong, *, n_pix: int, n_steps: int, rays: int = 1,
                     shadow: bool = True, smooth: bool = True, eps: float = 1e-4, block: int = 1):
    """α (B, V, P) and premultiplied re (B, V, L, P) of B sectors on the views ``views_half`` (V/2,)
    followed by the same views + π, and the lights ``lights`` (L,).  ``rho`` (B, n_s, n_r), ``geom``
    (B, 11) rows of ``hairlut.hrir.GEOM``, ``phong`` = (k_a, k_d, k_s, p); B a multiple of ``block``."""
    one = partial(_grid_one, n_pix=n_pix, n_steps=n_steps, rays=rays, shadow=shadow, smooth=smooth, eps=eps)
    return jax.lax.map(lambda a: one(a[0], a[1], views_half, lights, phong), (rho, geom), batch_size=block)


#: Sectors per kernel call of :func:`trace_view_grid`.
CALL = 32



def trace_view_grid(density, geometry, recipe: dict, *, views: int, lights: int, block: int = 1,
                    progress=None) -> tuple[np.ndarray, np.ndarray]:
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
    alpha = np.zeros((n, V, P), np.float32)
    re = np.zeros((n, V, L, P), np.float32)
    live = np.flatnonzero(rho.reshape(n, -1).max(axis=1, initial=0.0) > 0) if n else np.zeros(0, np.int64)
    vh = jnp.asarray(2 * np.pi * np.arange(V // 2) / V, jnp.float32)
    lt = jnp.asarray(2 * np.pi * np.arange(L) / L, jnp.float32)
    ph = jnp.asarray(phong, jnp.float32)
    for start in range(0, live.size, CALL):
        idx = live[start:start + CALL]
        size = bucket(idx.size, block) if idx.size < CALL else idx.size
        size = -(-size // block) * block
        rows = np.concatenate([idx, np.full(size - idx.size, idx[0])])
        a, r = view_grid_kernel(jnp.asarray(rho[rows], jnp.float32), jnp.asarray(g[rows], jnp.float32), vh, lt, ph,
                                block=block, **cfg)
        a, r = np.asarray(a)[:idx.size], np.asarray(r)[:idx.size]
        if not (np.isfinite(a).all() and np.isfinite(r).all()):
            raise errors.HairlutError("trace_view_grid: the kernel produced non-finite maps (check the density scale)")
        alpha[idx], re[idx] = a, r
        if progress:
            progress(min(start + CALL, live.size), live.size)
    return alpha, re
