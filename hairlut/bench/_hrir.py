"""Part ``hrir``: the HRIR database bake (satf §5.1), run time per sector against error.

The jitted tracer (``hairlut.hrir.trace_sectors``) at each (density grid, march steps, rays per
pixel) against a supersampled trace of the same sectors (grid × 4, steps × 4, 4 rays per pixel)
of the default recipe's angles and pixels, without in-plane self-shadowing (the NumPy loop has no
shadow march on the tracer's grid).  Baseline: the NumPy per-ray loop
(``hairlut.hrir.reference_hrir``, float64, one march for all lights) at the default grid and
steps, on the same sectors.  The paper traces one ray per
pixel through the density grid's points (§5.1: "the k-th grid point met by R_j"), so settings with
steps = grid cells and one ray are marked as the paper's; it states no grid size.
"""

from __future__ import annotations

import time

import numpy as np

from ._figure import Figure
from ._parts import Context, timed

PART = "hrir"
TABLE = "bake: HRIRs against a 4× supersampled trace"


def _inputs(recipe, n, grid, start):
    from hairlut.geometry.density import sector_density
    from hairlut.hrir import sample_block, sector_geometry

    splats, params = sample_block(recipe, start, start + n)
    rho = sector_density(splats, tuple(grid), chunk=1)
    g = sector_geometry(params, kappa=recipe["trace"]["extinction"], n_pix=recipe["trace"]["pixels"])
    return rho, g


def _mean_err(a, r, ref) -> float:
    return float(np.concatenate([np.abs(a - ref[0]).ravel(), np.abs(r - ref[1]).ravel()]).mean())


def run(ctx: Context) -> list[Figure]:
    from hairlut.hrir import reference_hrir, resolve_recipe, trace_sectors

    r = resolve_recipe({})
    V, L = r["angles"]["views"], r["angles"]["lights"]
    grid0, steps0 = r["sectors"]["grid"][0], r["trace"]["steps"]
    n = 2 if ctx.quick else 8
    start = 1000  # sectors away from the database's own first blocks
    sup = {"n_steps": 4 * steps0, "rays": 4}
    _, g = _inputs(r, n, [grid0, grid0], start)
    rho_ref = _inputs(r, n, [4 * grid0, 4 * grid0], start)[0]
    t0 = time.perf_counter()
    ref = trace_sectors(rho_ref, g, r, shadow=False, **sup)
    ref_s = time.perf_counter() - t0
    configs = ([(16, 16, 1), (16, 32, 1), (32, 32, 1), (32, 64, 1), (32, 64, 2)] if ctx.quick else
               [(gr, st, 1) for gr in (16, 32, 64) for st in (16, 32, 64, 128)] + [(32, 64, 2), (32, 64, 4), (64, 128, 4)])
    figs, dens = [], {}
    for grid, steps, rays in configs:
        if grid not in dens:
            dens[grid] = _inputs(r, n, [grid, grid], start)[0]
        rho = dens[grid]
        trace_sectors(rho, g, r, shadow=False, n_steps=steps, rays=rays)  # compile
        sec, (a, re) = timed(lambda: trace_sectors(rho, g, r, shadow=False, n_steps=steps, rays=rays), repeat=2)
        figs.append(Figure(PART, TABLE, f"tracer grid {grid}², {steps} steps, {rays} ray{'s' if rays > 1 else ''}", sec / n,
                           _mean_err(a, re, ref), "mean |Δ| (α, re)", {"grid": grid, "steps": steps, "rays": rays},
                           paper=steps == grid and rays == 1,
                           extra={"default": (grid, steps, rays) == (grid0, steps0, 1)}))
        if (grid, steps, rays) == (grid0, steps0, 1):
            f16 = _mean_err(a.astype(np.float16), re.astype(np.float16), ref)
            figs.append(Figure(PART, TABLE, "default, stored as float16", None, f16, "mean |Δ| (α, re)",
                               {"storage": "float16"}))
    rho = dens[grid0] if grid0 in dens else _inputs(r, n, [grid0, grid0], start)[0]
    ph = [r["phong"][k] for k in ("ambient", "diffuse", "specular", "shininess")]
    views, lights = 2 * np.pi * np.arange(V) / V, 2 * np.pi * np.arange(L) / L

    def loop():
        out = [reference_hrir(rho[i], g[i], views, lights, ph, share_lights=True, n_pix=r["trace"]["pixels"],
                              n_steps=steps0) for i in range(n)]
        return np.stack([o[0] for o in out]), np.stack([o[1] for o in out])

    sec, (a, re) = timed(loop, repeat=1)
    figs.append(Figure(PART, TABLE, f"NumPy per-ray loop, grid {grid0}², {steps0} steps, float64", sec / n,
                       _mean_err(a, re, ref), "mean |Δ| (α, re)", {"grid": grid0, "steps": steps0, "rays": 1},
                       baseline=True))
    ctx.note(PART, f"{n} sectors of the default sector space ({V} views × {L} lights × {r['trace']['pixels']} px); "
                   f"reference: grid {4 * grid0}², {4 * steps0} steps, 4 rays/px ({ref_s:.1f} s); times are per sector; "
                   "self-shadowing off throughout; every row, the NumPy loop included, on the same sectors, views and lights")
    return figs
