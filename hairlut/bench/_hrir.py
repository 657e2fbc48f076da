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
    from hairlut.hrir import sample_block
    from hairlut.march import sector_geometry

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
    configs = (
        [(16, 16, 1), (16, 32, 1), (32, 32, 1), (32, 64, 1), (32, 64, 2)]
        if ctx.quick
        else [(gr, st, 1) for gr in (16, 32, 64) for st in (16, 32, 64, 128)] + [(32, 64, 2), (32, 64, 4), (64, 128, 4)]
    )
    figs, dens = [], {}
    for grid, steps, rays in configs:
        if grid not in dens:
            dens[grid] = _inputs(r, n, [grid, grid], start)[0]
        rho = dens[grid]
        trace_sectors(rho, g, r, shadow=False, n_steps=steps, rays=rays)  # compile
        sec, (a, re) = timed(lambda: trace_sectors(rho, g, r, shadow=False, n_steps=steps, rays=rays), repeat=2)
        figs.append(
            Figure(
                PART,
                TABLE,
                f"tracer grid {grid}², {steps} steps, {rays} ray{'s' if rays > 1 else ''}",
                sec / n,
                _mean_err(a, re, ref),
                "mean |Δ| (α, re)",
                {"grid": grid, "steps": steps, "rays": rays},
                paper=steps == grid and rays == 1,
                extra={"default": (grid, steps, rays) == (grid0, steps0, 1)},
            )
        )
        if (grid, steps, rays) == (grid0, steps0, 1):
            f16 = _mean_err(a.astype(np.float16), re.astype(np.float16), ref)
            figs.append(Figure(PART, TABLE, "default, stored as float16", None, f16, "mean |Δ| (α, re)", {"storage": "float16"}))
    rho = dens[grid0] if grid0 in dens else _inputs(r, n, [grid0, grid0], start)[0]
    ph = [r["phong"][k] for k in ("ambient", "diffuse", "specular", "shininess")]
    views, lights = 2 * np.pi * np.arange(V) / V, 2 * np.pi * np.arange(L) / L

    def loop():
        out = [
            reference_hrir(rho[i], g[i], views, lights, ph, share_lights=True, n_pix=r["trace"]["pixels"], n_steps=steps0)
            for i in range(n)
        ]
        return np.stack([o[0] for o in out]), np.stack([o[1] for o in out])

    sec, (a, re) = timed(loop, repeat=1)
    figs.append(
        Figure(
            PART,
            TABLE,
            f"NumPy per-ray loop, grid {grid0}², {steps0} steps, float64",
            sec / n,
            _mean_err(a, re, ref),
            "mean |Δ| (α, re)",
            {"grid": grid0, "steps": steps0, "rays": 1},
            baseline=True,
        )
    )
    ctx.note(
        PART,
        f"{n} sectors of the default sector space ({V} views × {L} lights × {r['trace']['pixels']} px); "
        f"reference: grid {4 * grid0}², {4 * steps0} steps, 4 rays/px ({ref_s:.1f} s); times are per sector; "
        "self-shadowing off throughout; every row, the NumPy loop included, on the same sectors, views and lights",
    )
    return figs


def _errors(a, r, ref) -> tuple[float, float, float]:
    d = np.concatenate([np.abs(a - ref[0]).ravel(), np.abs(r - ref[1]).ravel()])
    return float(d.mean()), float(np.percentile(d, 99)), float(d.max())


def hrir_bake_study(quick: bool = False) -> dict:
    """What ``benchmarks/hrir_bake.py`` prints, as one document: ``throughput`` (HRIRs per second of the jitted
    tracer, the NumPy per-ray loops and the whole default bake, with each one's error against a 4× supersampled
    trace; the float32-vs-float64 and literal-vs-shared loop differences; the default bake's seconds),
    ``error_table`` (run time against error over grid, steps and rays per pixel), ``shadow`` (self-shadowing on
    and off) and ``float16_error`` (what float16 storage adds); ``recipe``, ``device`` and the sizes used."""
    import tempfile
    from pathlib import Path

    import jax

    from hairlut.hrir import bake, reference_hrir, resolve_recipe, trace_sectors

    r = resolve_recipe({})
    V, L = r["angles"]["views"], r["angles"]["lights"]
    n_block, n_err, n_ref = (16, 4, 1) if quick else (64, 16, 2)
    out = {"recipe": r, "device": str(jax.devices()[0]), "n_block": n_block, "n_err": n_err, "n_ref": n_ref}
    grid = r["sectors"]["grid"]
    # 1. throughput
    rho, g = _inputs(r, n_block, grid, 0)
    trace_sectors(rho[:1], g[:1], r)  # compile
    t_default, _ = timed(lambda: trace_sectors(rho, g, r), repeat=2)
    # the NumPy loop is compared without self-shadowing (its shadow march differs from the tracer's grid)
    trace_sectors(rho[:1], g[:1], r, shadow=False)
    t_tracer, (a, re) = timed(lambda: trace_sectors(rho, g, r, shadow=False), repeat=2)
    hrirs = n_block * V * L
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        rep = bake({}, Path(tmp) / "default.h5")
        t_bake = time.perf_counter() - start
    ph = [r["phong"][k] for k in ("ambient", "diffuse", "specular", "shininess")]
    views, lights = 2 * np.pi * np.arange(V) / V, 2 * np.pi * np.arange(L) / L
    kw = {"n_pix": r["trace"]["pixels"], "n_steps": r["trace"]["steps"]}
    pick = np.flatnonzero(rho.max(axis=(1, 2)) > 0)[:n_ref]  # non-empty sectors (an empty one costs the loop little)
    start = time.perf_counter()
    shared = [reference_hrir(rho[i], g[i], views, lights, ph, share_lights=True, **kw) for i in pick]
    t_shared = (time.perf_counter() - start) / (n_ref * V * L)  # per HRIR
    nv = 2  # the literal loop traces every (view, light, ray): a subset of views, scaled
    start = time.perf_counter()
    literal = [reference_hrir(rho[i], g[i], views[:nv], lights, ph, **kw) for i in pick]
    t_literal = (time.perf_counter() - start) / (n_ref * nv * L)
    f32_err = max(max(np.abs(a[i] - sh[0]).max(), np.abs(re[i] - sh[1]).max()) for i, sh in zip(pick, shared))
    lit_err = max(np.abs(li[1] - sh[1][:nv]).max() for li, sh in zip(literal, shared))
    sup = {"n_steps": 4 * r["trace"]["steps"], "rays": 4}
    rho4 = _inputs(r, n_block, [4 * x for x in grid], 0)[0][pick]
    a4, re4 = trace_sectors(rho4, g[pick], r, shadow=False, **sup)
    err_tracer = _errors(a[pick], re[pick], (a4, re4))
    err_shared = _errors(np.stack([x[0] for x in shared]), np.stack([x[1] for x in shared]), (a4, re4))
    err_literal = _errors(np.stack([x[0] for x in literal]), np.stack([x[1] for x in literal]), (a4[:, :nv], re4[:, :nv]))
    rate_tracer = hrirs / t_tracer
    rows = [
        {
            "what": f"JAX tracer, default recipe (self_shadow on), float32 ({n_block} sectors)",
            "rate": hrirs / t_default,
            "sectors": n_block / t_default,
        },
        {
            "what": f"JAX tracer, self_shadow off, float32 ({n_block} sectors, best of 2)",
            "rate": rate_tracer,
            "sectors": n_block / t_tracer,
            "err": err_tracer[0],
            "errmax": err_tracer[2],
        },
        {
            "what": f"NumPy per-ray loop, every (view, light, ray), float64 ({n_ref} sectors x {nv} views, scaled)",
            "rate": 1 / t_literal,
            "sectors": 1 / (t_literal * V * L),
            "err": err_literal[0],
            "errmax": err_literal[2],
            "ratio": rate_tracer * t_literal,
        },
        {
            "what": f"NumPy per-ray loop, one march for all lights, float64 ({n_ref} sectors, scaled)",
            "rate": 1 / t_shared,
            "sectors": 1 / (t_shared * V * L),
            "err": err_shared[0],
            "errmax": err_shared[2],
            "ratio": rate_tracer * t_shared,
        },
        {
            "what": f"full default DB via bake() ({rep['sectors']} sectors, incl. sampling + HDF5)",
            "rate": rep["units"] * V * L / t_bake,
            "sectors": rep["units"] / t_bake,
        },
    ]
    out["throughput"] = {
        "rows": rows,
        "float32_vs_float64": f32_err,
        "literal_vs_shared": lit_err,
        "default_db_seconds": t_bake,
        "default_db_sectors": rep["units"],
    }
    # 2. run time against error
    rho_ref, g_err = _inputs(r, n_err, [4 * x for x in grid], 1000)
    ref = trace_sectors(rho_ref, g_err, r, **sup)
    rows, dens = [], {}
    for gr, steps, rays in [(gr, st, 1) for gr in (16, 32, 64) for st in (32, 64, 128)] + [
        (32, 64, 2),
        (32, 64, 4),
        (64, 128, 4),
    ]:
        if gr not in dens:
            dens[gr] = _inputs(r, n_err, [gr, gr], 1000)[0]
        rho_g = dens[gr]
        trace_sectors(rho_g[:1], g_err[:1], r, n_steps=steps, rays=rays)
        t, (aa, rr) = timed(lambda: trace_sectors(rho_g, g_err, r, n_steps=steps, rays=rays), repeat=2)
        e = _errors(aa, rr, ref)
        rows.append(
            {
                "grid": gr,
                "steps": steps,
                "rays": rays,
                "ms": 1e3 * t / n_err,
                "mean": e[0],
                "p99": e[1],
                "max": e[2],
                "default": "<- default" if (gr, steps, rays) == (32, 64, 1) else "",
            }
        )
    out["error_table"] = rows
    # 3. self-shadowing and storage
    rho_s, g_s = rho[:n_err], g[:n_err]
    trace_sectors(rho_s[:1], g_s[:1], r, shadow=True)
    t_on, (_, r_on) = timed(lambda: trace_sectors(rho_s, g_s, r, shadow=True), repeat=1)
    t_off, (_, r_off) = timed(lambda: trace_sectors(rho_s, g_s, r, shadow=False), repeat=2)
    effect = np.abs(r_on - r_off)
    out["shadow"] = [
        {"mode": "self_shadow = false", "ms": 1e3 * t_off / n_err, "db": 1e3 * t_off / n_err * 512 / 1e3},
        {
            "mode": "self_shadow = true (default)",
            "ms": 1e3 * t_on / n_err,
            "db": 1e3 * t_on / n_err * 512 / 1e3,
            "mean": float(effect.mean()),
            "max": float(effect.max()),
        },
    ]
    out["float16_error"] = {
        k: float(np.abs(x.astype(np.float16).astype(np.float64) - x).max()) for k, x in (("alpha", a), ("reflectance", re))
    }
    return out
