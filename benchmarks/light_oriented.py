"""Light-oriented shadow map (bertails §2–3) against a per-vertex NumPy ray march.

    python -m benchmarks.light_oriented [--resolutions 32 64 128] [--reference 256] [--kappa 0.05] [--quick]
    python -m benchmarks.light_oriented --footprints [64 128 256 512 1024]

On the Sintel groom (tables/grooms/sintel_lite.tfx), for each resolution N:
- hairlut: ``light_oriented_map`` (jitted, float64: density + transmittance in the light
  frame) plus ``.at`` at every strand vertex; best of 5 warm runs (first call reported too);
- NumPy baseline: ``voxelize`` (world-aligned grid, N cells along the longest side) and a
  ray march from every vertex toward the light, trilinear density samples every half cell,
  T = exp(−κ Σ ρ Δt); best of 2 runs.
Errors are max and RMS |ΔT| over the vertices against the NumPy ray march at ``--reference``
cells (step a quarter cell).  "vs NumPy" is hairlut against the baseline at the same N.
The storage lines give the error that float32 / float16 storage of the transmittance grid adds.

``--footprints``: instead, the ``shadows`` bench part's maps against its strand-level reference at
footprints σ = extent / d (``hairlut.bench.footprint_study``): RMS and mean signed ΔT per map and σ,
and the reference's τ split into each point's own strand and the others; writes light_footprints.json.

The measurements are ``hairlut.bench.light_oriented_study``; this script prints them and writes
benchmarks/results/light_oriented.json.
"""

from __future__ import annotations

import argparse

from hairlut.bench import footprint_study, light_oriented_study

from ._common import save, table


def footprints(divisors) -> None:
    d = footprint_study(divisors)
    print(
        f"{d['groom']}: {d['points']} vertices (every second), κ = {d['kappa']}; RMS |ΔT| (mean signed ΔT) "
        f"against the strand-level reference at σ = extent / d, extent {d['extent']:.3g}\n"
    )
    rows = [
        {
            "map": k,
            "cell": f"extent/{d['extent'] / r['cell']:.0f}",
            **{f"d{x}": f"{e:.4f} ({b:+.3f})" for x, e, b in zip(d["divisors"], r["rms"], r["bias"])},
        }
        for k, r in d["maps"].items()
    ]
    print(table(rows, [("map", "map", "s"), ("cell", "cell", "s"), *[(f"d{x}", f"σ = 1/{x}", "s") for x in d["divisors"]]]))
    print(
        "\nreference mean τ = −ln T, own strand / other strands: "
        + "; ".join(f"1/{x}: {o:.3f} / {r:.3f}" for x, o, r in zip(d["divisors"], d["tau_own"], d["tau_others"]))
    )
    print(f"\nwrote {save('light_footprints', d)}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolutions", type=int, nargs="+", default=[32, 64, 128])
    ap.add_argument("--reference", type=int, default=256)
    ap.add_argument("--kappa", type=float, default=0.05, help="fibre blocking width (scene units)")
    ap.add_argument("--quick", action="store_true", help="resolutions 32 64, reference 128")
    ap.add_argument(
        "--footprints",
        type=int,
        nargs="*",
        metavar="D",
        help="the shadows part's maps against the strand reference at σ = extent / D (default 64 … 1024)",
    )
    args = ap.parse_args(argv)
    if args.footprints is not None:
        return footprints(args.footprints or [64, 128, 256, 512, 1024])
    if args.quick:
        args.resolutions, args.reference = [32, 64], 128
    d = light_oriented_study(args.resolutions, args.reference, args.kappa)
    out, ref = d["results"], d["reference"]
    print(
        f"groom: {d['groom']}: {d['strands']} strands, {d['vertices']} vertices, length {d['length']:.1f}; "
        f"light {[round(x, 3) for x in d['light']]}, κ = {d['kappa']}"
    )
    print(
        f"reference: NumPy ray march at {ref['resolution']} cells, quarter-cell steps ({ref['time_s']:.1f} s); "
        f"T at vertices: min {ref['min_T']:.3f}, mean {ref['mean_T']:.3f}"
    )
    rows = [{**r, "hairlut_ms": r["hairlut_s"] * 1e3, "numpy_ms": r["numpy_s"] * 1e3} for r in out]
    print()
    print(
        table(
            rows,
            [
                ("resolution", "N", "d"),
                ("grid", "light grid", "s"),
                ("hairlut_ms", "hairlut (ms)", ".1f"),
                ("numpy_ms", "NumPy (ms)", ".0f"),
                ("speedup", "speed-up", ".0f"),
                ("max", "max ΔT", ".3f"),
                ("rms", "RMS ΔT", ".4f"),
                ("numpy_max", "NumPy max ΔT", ".3f"),
                ("numpy_rms", "NumPy RMS ΔT", ".4f"),
                ("vs_numpy_rms", "RMS vs NumPy", ".4f"),
            ],
        )
    )
    print(
        f"\nΔT against the NumPy ray march at {ref['resolution']} cells; hairlut time = map + query at "
        f"{d['vertices']} vertices (map alone: "
        + ", ".join(f"{r['hairlut_map_s'] * 1e3:.1f} ms" for r in out)
        + "; first call: "
        + ", ".join(f"{r['hairlut_first_s']:.2f} s" for r in out)
        + ")"
    )
    print(
        "storage error of the transmittance grid (max |ΔT| at vertices): float32 "
        + ", ".join(f"{r['float32_max']:.1e}" for r in out)
        + "; float16 "
        + ", ".join(f"{r['float16_max']:.1e}" for r in out)
    )
    print(f"\nwrote {save('light_oriented', d)}")


if __name__ == "__main__":
    main()
