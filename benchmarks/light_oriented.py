"""Light-oriented shadow map (bertails §2–3) against a per-vertex NumPy ray march.

    python benchmarks/light_oriented.py [--resolutions 32 64 128] [--reference 256] [--kappa 0.05] [--quick]

On the Sintel groom (tables/grooms/sintel_lite.tfx), for each resolution N:
- hairlut: ``light_oriented_map`` (jitted, float64: density + transmittance in the light
  frame) plus ``.at`` at every strand vertex; best of 5 warm runs (first call reported too);
- NumPy baseline: ``voxelize`` (world-aligned grid, N cells along the longest side) and a
  ray march from every vertex toward the light, trilinear density samples every half cell,
  T = exp(−κ Σ ρ Δt); best of 2 runs.
Errors are max and RMS |ΔT| over the vertices against the NumPy ray march at ``--reference``
cells (step a quarter cell).  "vs NumPy" is hairlut against the baseline at the same N.
The storage lines give the error that float32 / float16 storage of the transmittance grid adds.

Prints a table and writes benchmarks/results/light_oriented.json.
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

from hairlut.geometry import read_strands  # noqa: E402
from hairlut.shadows import LightOrientedMap, light_oriented_map, ray_march  # noqa: E402

GROOM = Path(__file__).resolve().parents[1] / "tables" / "grooms" / "sintel_lite.tfx"
LIGHT = np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5])


def numpy_baseline(strands, light, kappa, res, step=0.5):
    """voxelize + march every vertex toward the light until it leaves the grid (``_reference.ray_march``)."""
    return ray_march(strands.points, light, kappa, strands, res, step=step)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolutions", type=int, nargs="+", default=[32, 64, 128])
    ap.add_argument("--reference", type=int, default=256)
    ap.add_argument("--kappa", type=float, default=0.05, help="fibre blocking width (scene units)")
    ap.add_argument("--quick", action="store_true", help="resolutions 32 64, reference 128")
    args = ap.parse_args()
    if args.quick:
        args.resolutions, args.reference = [32, 64], 128

    strands, source = read_strands(GROOM), GROOM.name
    pts = strands.points
    print(f"groom: {source}: {strands.n_strands} strands, {strands.n_points} vertices, "
          f"length {strands.lengths().sum():.1f}; light {np.round(LIGHT, 3).tolist()}, κ = {args.kappa}")

    t0 = time.perf_counter()
    ref = numpy_baseline(strands, LIGHT, args.kappa, args.reference, step=0.25)
    t_ref = time.perf_counter() - t0
    print(f"reference: NumPy ray march at {args.reference} cells, quarter-cell steps ({t_ref:.1f} s); "
          f"T at vertices: min {ref.min():.3f}, mean {ref.mean():.3f}")

    def ours(res):
        return light_oriented_map(strands, LIGHT, resolution=res, kappa=args.kappa)

    rows, out = [], []
    for res in args.resolutions:
        t0 = time.perf_counter()
        ours(res).at(pts)
        t_first = time.perf_counter() - t0
        t_map, m = best_of(lambda: ours(res), repeat=5)
        t_all, T = best_of(lambda: ours(res).at(pts), repeat=5)
        t_np, B = best_of(lambda: numpy_baseline(strands, LIGHT, args.kappa, res), repeat=2)

        def err(x):
            d = x - ref
            return float(np.abs(d).max()), float(np.sqrt(np.mean(d**2)))

        (e_max, e_rms), (b_max, b_rms) = err(T), err(B)
        d32 = float(np.abs(LightOrientedMap(m.frame, m.origin, m.spacing, m.density,
                                            m.transmittance.astype(np.float32).astype(np.float64), m.kappa).at(pts) - T).max())
        d16 = float(np.abs(LightOrientedMap(m.frame, m.origin, m.spacing, m.density,
                                            m.transmittance.astype(np.float16).astype(np.float64), m.kappa).at(pts) - T).max())
        rec = {"resolution": res, "grid": "×".join(map(str, m.shape)), "hairlut_s": t_all, "hairlut_map_s": t_map,
               "hairlut_first_s": t_first, "numpy_s": t_np, "speedup": t_np / t_all, "max": e_max, "rms": e_rms,
               "numpy_max": b_max, "numpy_rms": b_rms, "vs_numpy_max": float(np.abs(T - B).max()),
               "vs_numpy_rms": float(np.sqrt(np.mean((T - B) ** 2))), "float32_max": d32, "float16_max": d16}
        out.append(rec)
        rows.append({**rec, "hairlut_ms": t_all * 1e3, "numpy_ms": t_np * 1e3})

    print()
    print(table(rows, [("resolution", "N", "d"), ("grid", "light grid", "s"), ("hairlut_ms", "hairlut (ms)", ".1f"),
                       ("numpy_ms", "NumPy (ms)", ".0f"), ("speedup", "speed-up", ".0f"),
                       ("max", "max ΔT", ".3f"), ("rms", "RMS ΔT", ".4f"), ("numpy_max", "NumPy max ΔT", ".3f"),
                       ("numpy_rms", "NumPy RMS ΔT", ".4f"), ("vs_numpy_rms", "RMS vs NumPy", ".4f")]))
    print(f"\nΔT against the NumPy ray march at {args.reference} cells; hairlut time = map + query at "
          f"{strands.n_points} vertices (map alone: "
          + ", ".join(f"{r['hairlut_map_s'] * 1e3:.1f} ms" for r in out) + "; first call: "
          + ", ".join(f"{r['hairlut_first_s']:.2f} s" for r in out) + ")")
    print("storage error of the transmittance grid (max |ΔT| at vertices): float32 "
          + ", ".join(f"{r['float32_max']:.1e}" for r in out) + "; float16 " + ", ".join(f"{r['float16_max']:.1e}" for r in out))
    path = save("light_oriented", {
        "jax": jax.__version__, "device": str(jax.devices()[0]), "groom": source,
        "strands": strands.n_strands, "vertices": strands.n_points, "light": LIGHT.tolist(), "kappa": args.kappa,
        "reference": {"resolution": args.reference, "step_cells": 0.25, "time_s": t_ref},
        "results": out,
    })
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
