"""SH convolution tables: bake time and error, the paper's quadrature against hairlut's exact form.

    python benchmarks/sh_tables.py [--quick]

1. Bake: the paper's cube-map quadrature (ω on n×n×6, n = 7, 16, 32, 64) and
   hairlut's Legendre–Gaunt bake, both producing Rd, Rs at the paper's grid
   (t on 7×7×6 texel centres, θ′ in steps of π/8, p = 49, 9/64 light and 9
   transmittance coefficients).  Error: max and RMS against an independent
   high-order reference (``hairlut.shtables.reference_r``: direct quadrature split
   at the kernel's kinks).  Times are warm (JIT compile excluded and reported).
2. Per-vertex radiance for 10⁶ random (t, θ′): dense-table interpolation at the
   paper's grid (bilinear on the cube face, linear in θ′) against exact evaluation.
3. Light update: new a_i → Cd/Cs ready.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import best_of, save, table  # noqa: E402

from hairlut.bench import dense_radiance, radiance_inputs  # noqa: E402  (the shader's dense-grid lookup)
from hairlut.envlight import cube_dirs  # noqa: E402
from hairlut.sh import gaunt_quadrature  # noqa: E402  (the uncached Gaunt tensor)
from hairlut.shtables import bake_compact, compute, paper_tables, reference_r, resolve_recipe  # noqa: E402

P = 49.0


def reference(t_dirs, theta_v):
    rd = np.stack([reference_r(t, 0.0, P, 2, 2, specular=False) for t in t_dirs])
    rs = np.stack([[reference_r(t, tv, P, 7, 2) for tv in theta_v] for t in t_dirs])
    return rd, rs


def err(a, b):
    d = np.abs(np.asarray(a) - b)
    return float(d.max()), float(np.sqrt(np.mean(d**2)))


def hairlut_bake(recipe, t_dirs, theta_v):
    gaunt_quadrature(9, 7, 2)  # uncached: the Gaunt tensor is part of the bake
    tables, _ = bake_compact(recipe)
    rd = np.asarray(tables.rd(t_dirs))
    rs = np.asarray(tables.rs(t_dirs[:, None, :], theta_v[None, :]))
    return tables, rd, rs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer ω resolutions and 10⁵ vertices")
    ap.add_argument("--radiance-only", action="store_true", help="skip the bake comparison (and its slow reference)")
    args = ap.parse_args(argv)
    t_dirs, _ = cube_dirs(7)
    theta_v = np.linspace(0, np.pi, 9)
    recipe = resolve_recipe({"kernel": {"p": P}, "bands": {"light_specular": 8}})

    rows, ref_time = [], None
    if not args.radiance_only:
        rows, ref_time = bake_rows(args, recipe, t_dirs, theta_v)
    radiance_rows(args, rows, ref_time)


def bake_rows(args, recipe, t_dirs, theta_v):
    start = time.perf_counter()
    ref_d, ref_s = reference(t_dirs, theta_v)
    ref_time = time.perf_counter() - start
    print(f"reference: {len(t_dirs)} tangents × {len(theta_v)} θ′ in {ref_time:.1f} s "
          f"(max |Rd| {np.abs(ref_d).max():.3f}, max |Rs| {np.abs(ref_s).max():.3f})")

    rows = []
    for n in (7, 16) if args.quick else (7, 16, 32, 64):
        start = time.perf_counter()
        paper_tables(n, t_dirs, theta_v, P, 2, 7, 2)
        cold = time.perf_counter() - start
        sec, (rd, rs) = best_of(lambda: paper_tables(n, t_dirs, theta_v, P, 2, 7, 2), repeat=3)
        (dmax, drms), (smax, srms) = err(rd, ref_d), err(rs, ref_s)
        rows.append({"method": f"paper quadrature, ω on {n}×{n}×6", "sec": sec, "cold": cold,
                     "rd_max": dmax, "rd_rms": drms, "rs_max": smax, "rs_rms": srms})
    start = time.perf_counter()
    hairlut_bake(recipe, t_dirs, theta_v)
    cold = time.perf_counter() - start
    sec, (tables, rd, rs) = best_of(lambda: hairlut_bake(recipe, t_dirs, theta_v), repeat=5)
    compact_sec, _ = best_of(lambda: (gaunt_quadrature(9, 7, 2), bake_compact(recipe)), repeat=5)
    (dmax, drms), (smax, srms) = err(rd, ref_d), err(rs, ref_s)
    rows.append({"method": "hairlut Legendre-Gaunt (exact), + dense grid", "sec": sec, "cold": cold,
                 "rd_max": dmax, "rd_rms": drms, "rs_max": smax, "rs_rms": srms})
    rows.append({"method": "hairlut compact form only", "sec": compact_sec})
    for dtype in ("float32", "float16"):
        (smax, srms) = err(rs.astype(dtype).astype(np.float64), ref_s)
        (dmax, drms) = err(rd.astype(dtype).astype(np.float64), ref_d)
        rows.append({"method": f"hairlut dense tables stored as {dtype}", "rd_max": dmax, "rd_rms": drms,
                     "rs_max": smax, "rs_rms": srms})
    paper_sec = rows[0]["sec"]
    for r in rows:
        if r.get("sec"):
            r["ratio"] = r["sec"] / paper_sec
    cols = [("method", "method", "s"), ("sec", "warm s", ".4f"), ("ratio", "× paper 7³", ".2f"), ("cold", "cold s", ".2f"),
            ("rd_max", "Rd max err", ".1e"), ("rd_rms", "Rd RMS", ".1e"), ("rs_max", "Rs max err", ".1e"), ("rs_rms", "Rs RMS", ".1e")]
    print("\n## Bake: time and error against the independent reference (p = 49, paper grid)\n")
    print(table(rows, cols))
    return rows, ref_time


def radiance_rows(args, rows, ref_time):

    # ------------------------------------------------------------------ per-vertex radiance
    n_vert = 100_000 if args.quick else 1_000_000
    t, tv, b, a = radiance_inputs(n_vert)
    res = compute({"kernel": {"p": P}, "bands": {"light_specular": 8}, "dense": {"t_resolution": 7, "theta_v_steps": 9}})
    contracted = res["tables"].contract(a)
    cd = np.asarray(contracted.cd(res["dense"]["t_dirs"]))
    cs = np.asarray(contracted.cs(res["dense"]["t_dirs"][:, None, :], res["dense"]["theta_v"][None, :]))
    exact = np.asarray(contracted.radiance(b, t, tv, 0.6, 0.4))
    exact_sec, _ = best_of(lambda: jax.block_until_ready(contracted.radiance(b, t, tv, 0.6, 0.4)), repeat=3)
    fast = np.asarray(contracted.radiance(b, t, tv, 0.6, 0.4, dtype="float32"))
    f32_sec, _ = best_of(lambda: jax.block_until_ready(contracted.radiance(b, t, tv, 0.6, 0.4, dtype="float32")), repeat=3)
    with jax.enable_x64(True):
        args_d = (jnp.asarray(t), jnp.asarray(tv), jnp.asarray(b), jnp.asarray(cd), jnp.asarray(cs), 0.6, 0.4)
        dense = np.asarray(dense_radiance(*args_d, n=7))
        dense_sec, _ = best_of(lambda: jax.block_until_ready(dense_radiance(*args_d, n=7)), repeat=3)
    scale = float(np.abs(exact).max())
    vrows = [
        {"method": "dense tables at the paper's grid, interpolated", "sec": dense_sec,
         "max": float(np.abs(dense - exact).max()) / scale, "rms": float(np.sqrt(np.mean((dense - exact) ** 2))) / scale},
        {"method": "hairlut exact (Legendre-Gaunt, contracted light)", "sec": exact_sec, "max": 0.0, "rms": 0.0},
        {"method": "hairlut exact form evaluated in float32", "sec": f32_sec,
         "max": float(np.abs(fast - exact).max()) / scale, "rms": float(np.sqrt(np.mean((fast - exact) ** 2))) / scale},
    ]
    print(f"\n## Per-vertex radiance, {n_vert:,} random (t, θ′), RGB; error relative to max |I| = {scale:.3g}\n")
    print(table(vrows, [("method", "method", "s"), ("sec", "warm s", ".3f"), ("max", "max rel err", ".1e"), ("rms", "RMS rel err", ".1e")]))

    # ------------------------------------------------------------------ light update
    tables = res["tables"]
    tables.contract(a)
    upd_sec, c2 = best_of(lambda: jax.block_until_ready(tables.contract(a + 0.01).hs), repeat=20)
    print(f"\n## Light update (new a_i → Cd/Cs ready, p = 49, 64 + 9 light coefficients, RGB): {upd_sec * 1e3:.2f} ms\n")

    save("sh_tables", {"bake": rows, "radiance": vrows, "light_update_ms": upd_sec * 1e3, "n_vertices": n_vert,
                       "reference_seconds": ref_time})


if __name__ == "__main__":
    main()
