"""HRIR-DB bake: throughput of the JAX tracer against the NumPy per-ray loop, and run time against error.

Prints three tables and writes benchmarks/results/hrir_bake.json:

1. HRIRs per second (one HRIR = one sector × view × light record) for the default
   recipe: the jitted tracer on a block of sectors, the whole default database through
   ``hairlut.hrir.bake`` (sampling, density, tracing, HDF5 writes), and the NumPy
   per-ray loop (float64) on a small subset, scaled per HRIR.  Both use the same
   discretisation, so their error against the supersampled reference is the same; the
   table shows it, and the float32-vs-float64 difference between them.
2. Run time against error as the density grid and step count vary, against a 4×
   supersampled reference (grid ×4, steps ×4, 4 rays per pixel) of the default recipe.
3. Self-shadowing on/off: cost and the size of the effect (decides the default), and
   the error float16 storage adds.

Usage: python benchmarks/hrir_bake.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import best_of, save, table  # noqa: E402

from hairlut.geometry.density import sector_density  # noqa: E402
from hairlut.hrir import bake, reference_hrir, resolve_recipe, sample_block, sector_geometry, trace_sectors  # noqa: E402


def _inputs(recipe, n, grid=None, start=0):
    splats, params = sample_block(recipe, start, start + n)
    rho = sector_density(splats, tuple(grid or recipe["sectors"]["grid"]), chunk=1)
    g = sector_geometry(params, kappa=recipe["trace"]["extinction"], n_pix=recipe["trace"]["pixels"])
    return rho, g


def _errors(a, r, ref):
    d = np.concatenate([np.abs(a - ref[0]).ravel(), np.abs(r - ref[1]).ravel()])
    return float(d.mean()), float(np.percentile(d, 99)), float(d.max())


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer sectors (a smoke run)")
    args = ap.parse_args(argv)
    r = resolve_recipe({})
    V, L = r["angles"]["views"], r["angles"]["lights"]
    n_block = 16 if args.quick else 64
    n_err = 4 if args.quick else 16
    n_ref = 1 if args.quick else 2
    payload = {"recipe": r, "device": str(jax.devices()[0])}

    # 1. throughput ---------------------------------------------------------------------------
    rho, g = _inputs(r, n_block)
    trace_sectors(rho[:1], g[:1], r)  # compile
    t_default, _ = best_of(lambda: trace_sectors(rho, g, r), repeat=2)
    # the NumPy loop is compared without self-shadowing (its shadow march differs from the tracer's grid)
    trace_sectors(rho[:1], g[:1], r, shadow=False)
    t_tracer, (a, re) = best_of(lambda: trace_sectors(rho, g, r, shadow=False), repeat=2)
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
    # error of each against the supersampled reference, on the same sectors
    sup = {"n_steps": 4 * r["trace"]["steps"], "rays": 4}
    rho4 = _inputs(r, n_block, grid=[4 * x for x in r["sectors"]["grid"]])[0][pick]
    a4, re4 = trace_sectors(rho4, g[pick], r, shadow=False, **sup)
    err_tracer = _errors(a[pick], re[pick], (a4, re4))
    err_shared = _errors(np.stack([x[0] for x in shared]), np.stack([x[1] for x in shared]), (a4, re4))
    err_literal = _errors(np.stack([x[0] for x in literal]), np.stack([x[1] for x in literal]), (a4[:, :nv], re4[:, :nv]))
    rate_tracer = hrirs / t_tracer
    rows = [
        {"what": f"JAX tracer, default recipe (self_shadow on), float32 ({n_block} sectors)", "rate": hrirs / t_default,
         "sectors": n_block / t_default},
        {"what": f"JAX tracer, self_shadow off, float32 ({n_block} sectors, best of 2)", "rate": rate_tracer,
         "sectors": n_block / t_tracer, "err": err_tracer[0], "errmax": err_tracer[2]},
        {"what": f"NumPy per-ray loop, every (view, light, ray), float64 ({n_ref} sectors x {nv} views, scaled)",
         "rate": 1 / t_literal, "sectors": 1 / (t_literal * V * L), "err": err_literal[0], "errmax": err_literal[2],
         "ratio": rate_tracer * t_literal},
        {"what": f"NumPy per-ray loop, one march for all lights, float64 ({n_ref} sectors, scaled)",
         "rate": 1 / t_shared, "sectors": 1 / (t_shared * V * L), "err": err_shared[0], "errmax": err_shared[2],
         "ratio": rate_tracer * t_shared},
        {"what": f"full default DB via bake() ({rep['sectors']} sectors, incl. sampling + HDF5)",
         "rate": rep["sectors"] * V * L / t_bake, "sectors": rep["sectors"] / t_bake},
    ]
    print(f"## HRIRs per second, default recipe ({V} views x {L} lights x {r['trace']['pixels']} px, "
          f"{r['trace']['steps']} steps, grid {r['sectors']['grid']}; {payload['device']}); "
          "NumPy rows and errors without self-shadowing\n")
    print(table(rows, [("what", "", "s"), ("rate", "HRIRs/s", ",.0f"), ("sectors", "sectors/s", ".3f"),
                       ("ratio", "tracer speed-up", ".0f"),
                       ("err", "mean |err| vs 4x ref", ".2e"), ("errmax", "max |err| vs 4x ref", ".2e")]))
    print(f"\nequal error: same discretisation; float32 tracer vs float64 loop max |diff| = {f32_err:.1e}, "
          f"literal vs shared loop {lit_err:.1e}")
    print(f"default DB ({rep['sectors']} sectors) baked end to end in {t_bake:.1f} s (target <= 120 s)\n")
    payload["throughput"] = {"rows": rows, "float32_vs_float64": f32_err,
                             "default_db_seconds": t_bake}

    # 2. run time against error ---------------------------------------------------------------
    rho_ref, g_err = _inputs(r, n_err, grid=[4 * x for x in r["sectors"]["grid"]], start=1000)
    ref = trace_sectors(rho_ref, g_err, r, **sup)
    rows = []
    configs = [(gr, st, 1) for gr in (16, 32, 64) for st in (32, 64, 128)] + [(32, 64, 2), (32, 64, 4), (64, 128, 4)]
    dens = {}
    for grid, steps, rays in configs:
        if grid not in dens:
            dens[grid] = _inputs(r, n_err, grid=[grid, grid], start=1000)[0]
        rho_g = dens[grid]
        trace_sectors(rho_g[:1], g_err[:1], r, n_steps=steps, rays=rays)
        t, (aa, rr) = best_of(lambda: trace_sectors(rho_g, g_err, r, n_steps=steps, rays=rays), repeat=2)
        e = _errors(aa, rr, ref)
        rows.append({"grid": grid, "steps": steps, "rays": rays, "ms": 1e3 * t / n_err, "mean": e[0], "p99": e[1],
                     "max": e[2], "default": "<- default" if (grid, steps, rays) == (32, 64, 1) else ""})
    print(f"## Run time against error ({n_err} sectors; reference: grid x4, steps x4, 4 rays/pixel)\n")
    print(table(rows, [("grid", "grid", "d"), ("steps", "steps", "d"), ("rays", "rays/px", "d"), ("ms", "ms/sector", ".1f"),
                       ("mean", "mean |err|", ".2e"), ("p99", "p99 |err|", ".2e"), ("max", "max |err|", ".2e"),
                       ("default", "", "s")]))
    payload["error_table"] = rows

    # 3. self-shadowing and storage -----------------------------------------------------------
    rho_s, g_s = rho[:n_err], g[:n_err]
    trace_sectors(rho_s[:1], g_s[:1], r, shadow=True)
    t_on, (a_on, r_on) = best_of(lambda: trace_sectors(rho_s, g_s, r, shadow=True), repeat=1)
    t_off, (a_off, r_off) = best_of(lambda: trace_sectors(rho_s, g_s, r, shadow=False), repeat=2)
    effect = np.abs(r_on - r_off)
    f16 = {k: float(np.abs(x.astype(np.float16).astype(np.float64) - x).max()) for k, x in (("alpha", a), ("reflectance", re))}
    rows = [{"mode": "self_shadow = false", "ms": 1e3 * t_off / n_err, "db": 1e3 * t_off / n_err * 512 / 1e3},
            {"mode": "self_shadow = true (default)", "ms": 1e3 * t_on / n_err, "db": 1e3 * t_on / n_err * 512 / 1e3,
             "mean": float(effect.mean()), "max": float(effect.max())}]
    print(f"\n## In-plane self-shadowing ({n_err} sectors)\n")
    print(table(rows, [("mode", "", "s"), ("ms", "ms/sector", ".1f"), ("db", "s per 512 sectors", ".1f"),
                       ("mean", "mean |change| of re", ".2e"), ("max", "max |change| of re", ".2e")]))
    print(f"\nfloat16 storage adds max |err|: alpha {f16['alpha']:.1e}, reflectance {f16['reflectance']:.1e} "
          f"(float32 storage adds 0)")
    payload["shadow"] = rows
    payload["float16_error"] = f16
    print(f"\nwrote {save('hrir_bake', payload)}")


if __name__ == "__main__":
    main()
