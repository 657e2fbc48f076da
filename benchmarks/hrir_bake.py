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

The measurements are ``hairlut.bench.hrir_bake_study``; this script prints them.

Usage: python -m benchmarks.hrir_bake [--quick]
"""

from __future__ import annotations

import argparse

from hairlut.bench import hrir_bake_study

from ._common import save, table


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer sectors (a smoke run)")
    args = ap.parse_args(argv)
    payload = hrir_bake_study(quick=args.quick)
    r, thr = payload["recipe"], payload["throughput"]
    V, L = r["angles"]["views"], r["angles"]["lights"]
    print(
        f"## HRIRs per second, default recipe ({V} views x {L} lights x {r['trace']['pixels']} px, "
        f"{r['trace']['steps']} steps, grid {r['sectors']['grid']}; {payload['device']}); "
        "NumPy rows and errors without self-shadowing\n"
    )
    print(
        table(
            thr["rows"],
            [
                ("what", "", "s"),
                ("rate", "HRIRs/s", ",.0f"),
                ("sectors", "sectors/s", ".3f"),
                ("ratio", "tracer speed-up", ".0f"),
                ("err", "mean |err| vs 4x ref", ".2e"),
                ("errmax", "max |err| vs 4x ref", ".2e"),
            ],
        )
    )
    print(
        f"\nequal error: same discretisation; float32 tracer vs float64 loop max |diff| = {thr['float32_vs_float64']:.1e}, "
        f"literal vs shared loop {thr['literal_vs_shared']:.1e}"
    )
    print(
        f"default DB ({thr['default_db_sectors']} sectors) baked end to end in {thr['default_db_seconds']:.1f} s "
        "(target <= 120 s)\n"
    )
    print(f"## Run time against error ({payload['n_err']} sectors; reference: grid x4, steps x4, 4 rays/pixel)\n")
    print(
        table(
            payload["error_table"],
            [
                ("grid", "grid", "d"),
                ("steps", "steps", "d"),
                ("rays", "rays/px", "d"),
                ("ms", "ms/sector", ".1f"),
                ("mean", "mean |err|", ".2e"),
                ("p99", "p99 |err|", ".2e"),
                ("max", "max |err|", ".2e"),
                ("default", "", "s"),
            ],
        )
    )
    print(f"\n## In-plane self-shadowing ({payload['n_err']} sectors)\n")
    print(
        table(
            payload["shadow"],
            [
                ("mode", "", "s"),
                ("ms", "ms/sector", ".1f"),
                ("db", "s per 512 sectors", ".1f"),
                ("mean", "mean |change| of re", ".2e"),
                ("max", "max |change| of re", ".2e"),
            ],
        )
    )
    f16 = payload["float16_error"]
    print(
        f"\nfloat16 storage adds max |err|: alpha {f16['alpha']:.1e}, reflectance {f16['reflectance']:.1e} "
        f"(float32 storage adds 0)"
    )
    print(f"\nwrote {save('hrir_bake', payload)}")


if __name__ == "__main__":
    main()
