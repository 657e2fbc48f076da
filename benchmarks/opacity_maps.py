"""Opacity shadow maps (kim thesis §6.2, Table 6-1): build the maps and shadow every strand vertex.

On the Sintel groom (tables/grooms/sintel_lite.tfx), for a few (slices, resolution) settings, times
- hairlut: ``opacity_shadow_maps`` (one jitted scatter-add + cumulative sum) and ``.at`` on every
  vertex, float64, best of the timed runs after a warm-up (first call, with compilation, too);
- a straightforward NumPy version of the paper's procedure: the same pieces and grid (the layout of
  hairlut's maps at that setting: frame, origin, texel edge, near depth, slice spacing), vertices
  bucketed by slice (loop 2), then per slice Ω_i = Ω_{i-1} + np.add.at of that slice's pieces and
  a bilinear + depth-linear lookup of that slice's vertices in Ω_{i-1}, Ω_i (loops 3 and 4).
Errors are |Δτ| at the vertices against a many-slice, high-resolution hairlut reference; against
a reference with as many slices at the setting's own resolution ("slices only": the error of
the depth interpolation alone); and between hairlut and NumPy at the same setting (the same
discretisation: should be ~0).
Prints a table and writes benchmarks/results/opacity_maps.json.

Usage: python benchmarks/opacity_maps.py [--kappa 0.05] [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import best_of, save, table  # noqa: E402

from hairlut.geometry import Strands, read_strands  # noqa: E402
from hairlut.shadows import OpacityMaps, opacity_shadow_maps  # noqa: E402

GROOM = Path(__file__).resolve().parents[1] / "tables" / "grooms" / "sintel_lite.tfx"
LIGHT = np.array([0.3, 1.0, 0.5])


def numpy_osm(strands: Strands, layout: OpacityMaps, kappa: float) -> np.ndarray:
    """τ at every vertex by Table 6-1, in NumPy, on the grid of ``layout`` (hairlut's maps at the same
    setting: only their layout is used, never their Ω) and with hairlut's pieces (width 1)."""
    q = np.asarray(strands.points, np.float64) @ layout.frame.T
    (ox, oy), h, near = layout.origin, layout.spacing, layout.near
    n_slices, H, W = layout.shape
    dz = float(layout.depths[0] - near)
    step = 0.25 * min(h, dz)
    seg = strands.segments
    a, b = q[seg[:, 0]], q[seg[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    n = np.maximum(1, np.ceil(length / step)).astype(int)
    rep = np.repeat(np.arange(len(seg)), n)
    k = np.arange(rep.size) - np.repeat(np.cumsum(n) - n, n)
    f = ((k + 0.5) / n[rep])[:, None]
    s = a[rep] + f * (b[rep] - a[rep])
    w = (length / n)[rep] / h**2
    ix = np.clip(np.floor((s[:, 0] - ox) / h).astype(int), 0, W - 1)
    iy = np.clip(np.floor((s[:, 1] - oy) / h).astype(int), 0, H - 1)
    iz = np.clip(np.floor((s[:, 2] - near) / dz).astype(int), 0, n_slices - 1)
    order = np.argsort(iz, kind="stable")
    cuts = np.searchsorted(iz[order], np.arange(n_slices + 1))
    # loop 2: vertices by slice
    sp = (q[:, 2] - near) / dz
    slot = np.clip(np.floor(sp).astype(int), 0, n_slices - 1)
    porder = np.argsort(slot, kind="stable")
    pcuts = np.searchsorted(slot[porder], np.arange(n_slices + 1))
    gx, gy = (q[:, 0] - ox) / h - 0.5, (q[:, 1] - oy) / h - 0.5
    tau = np.ones(len(q))
    prev, cur = np.zeros((H, W)), np.zeros((H, W))

    def sample(buf, x, y):
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = x - x0, y - y0
        out = np.zeros(len(x))
        for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):
            xi, yi = x0 + dx, y0 + dy
            ok = (xi >= 0) & (xi < W) & (yi >= 0) & (yi < H)
            wgt = (fx if dx else 1 - fx) * (fy if dy else 1 - fy) * ok
            out += wgt * buf[np.clip(yi, 0, H - 1), np.clip(xi, 0, W - 1)]
        return out

    for i in range(n_slices):  # loop 3
        prev, cur = cur, cur.copy()
        sel = order[cuts[i]:cuts[i + 1]]
        np.add.at(cur, (iy[sel], ix[sel]), w[sel])
        p = porder[pcuts[i]:pcuts[i + 1]]  # loop 4
        t = np.clip(sp[p] - i, 0.0, 1.0)
        omega = (1 - t) * sample(prev, gx[p], gy[p]) + t * sample(cur, gx[p], gy[p])
        tau[p] = np.exp(-kappa * omega)
    return tau


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kappa", type=float, default=0.05, help="extinction per unit hair length (width 1)")
    ap.add_argument("--quick", action="store_true", help="two small settings and a smaller reference")
    args = ap.parse_args()

    strands, source = read_strands(GROOM), GROOM.name
    verts = strands.points
    settings = [(8, 32), (16, 64)] if args.quick else [(8, 32), (16, 64), (32, 128)]
    ref_setting = (64, 128) if args.quick else (128, 256)
    print(f"{source}: {strands.n_strands} strands, {strands.n_points} vertices; light {LIGHT.tolist()}, "
          f"κ = {args.kappa}; reference {ref_setting[0]} slices × {ref_setting[1]} texels")

    def hairlut_run(n_slices, res):
        return opacity_shadow_maps(strands, LIGHT, n_slices=n_slices, resolution=res, kappa=args.kappa).at(verts)

    ref = hairlut_run(*ref_setting)
    repeat = 3 if args.quick else 5
    rows = []
    for n_slices, res in settings:
        t0 = time.perf_counter()
        hairlut_run(n_slices, res)
        t_first = time.perf_counter() - t0
        t_jax, tau_j = best_of(lambda: hairlut_run(n_slices, res), repeat=repeat)
        m = opacity_shadow_maps(strands, LIGHT, n_slices=n_slices, resolution=res, kappa=args.kappa)
        t_np, tau_n = best_of(lambda: numpy_osm(strands, m, args.kappa), repeat=repeat)
        dj, dn, dx = tau_j - ref, tau_n - ref, tau_j - tau_n
        dd = tau_j - hairlut_run(ref_setting[0], res)
        rows.append({"setting": f"{n_slices} × {res}", "maps": "×".join(map(str, m.shape)), "t_jax": t_jax * 1e3,
                     "t_first": t_first * 1e3, "t_np": t_np * 1e3, "speedup": t_np / t_jax,
                     "max_jax": float(np.abs(dj).max()), "rms_jax": float(np.sqrt((dj**2).mean())),
                     "max_np": float(np.abs(dn).max()), "rms_np": float(np.sqrt((dn**2).mean())),
                     "max_depth": float(np.abs(dd).max()), "rms_depth": float(np.sqrt((dd**2).mean())),
                     "max_cross": float(np.abs(dx).max()), "mean_tau": float(tau_j.mean())})
    print()
    print(table(rows, [("setting", "slices × res", "s"), ("maps", "Ω maps", "s"), ("t_jax", "hairlut (ms)", ".2f"),
                       ("t_first", "first call (ms)", ".0f"), ("t_np", "NumPy (ms)", ".2f"),
                       ("speedup", "NumPy / hairlut", ".1f"), ("max_jax", "max |Δτ| ref", ".3f"),
                       ("rms_jax", "RMS |Δτ| ref", ".4f"), ("max_np", "NumPy max |Δτ| ref", ".3f"),
                       ("rms_np", "NumPy RMS |Δτ| ref", ".4f"), ("max_depth", "max |Δτ| slices only", ".3f"),
                       ("rms_depth", "RMS |Δτ| slices only", ".4f"), ("max_cross", "max |τ_hairlut − τ_NumPy|", ".1e"),
                       ("mean_tau", "mean τ", ".3f")]))
    print(f"\ntimes: maps + τ at every vertex, best of {repeat} runs after a warm-up. The reference shares the method, "
          "so 'ref' errors are discretisation differences (slices, texel filter width, pieces); finer texels resolve "
          "single strands (a strand shadows its own vertices more), so they do not converge to zero with resolution.")
    path = save("opacity_maps", {
        "jax": jax.__version__, "device": str(jax.devices()[0]), "groom": source,
        "strands": strands.n_strands, "vertices": strands.n_points, "light": LIGHT.tolist(), "kappa": args.kappa,
        "reference": {"n_slices": ref_setting[0], "resolution": ref_setting[1]}, "quick": args.quick,
        "rows": rows,
    })
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
