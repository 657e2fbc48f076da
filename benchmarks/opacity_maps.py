"""Opacity shadow maps (kim thesis §6.2, Table 6-1): build the maps and shadow every strand vertex.

On the Sintel groom (tables/grooms/sintel_lite.tfx), for a few (slices, resolution) settings, times
- hairlut: ``opacity_shadow_maps`` (one jitted scatter-add + cumulative sum) and ``.at`` on every
  vertex, float64, best of the timed runs after a warm-up (first call, with compilation, too);
- a straightforward NumPy version of the paper's procedure (``hairlut.bench.numpy_opacity_maps``):
  the same pieces and grid, vertices bucketed by slice, then per slice Ω_i = Ω_{i-1} + np.add.at of
  that slice's pieces and a bilinear + depth-linear lookup of that slice's vertices.
Errors are |Δτ| at the vertices against a many-slice, high-resolution hairlut reference; against
a reference with as many slices at the setting's own resolution ("slices only": the error of
the depth interpolation alone); and between hairlut and NumPy at the same setting (the same
discretisation: should be ~0).
The measurements are ``hairlut.bench.opacity_maps_study``; this script prints a table and writes
benchmarks/results/opacity_maps.json.

Usage: python -m benchmarks.opacity_maps [--kappa 0.05] [--quick]
"""

from __future__ import annotations

import argparse

from hairlut.bench import opacity_maps_study

from ._common import save, table


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kappa", type=float, default=0.05, help="extinction per unit hair length (width 1)")
    ap.add_argument("--quick", action="store_true", help="two small settings and a smaller reference")
    args = ap.parse_args(argv)
    d = opacity_maps_study(args.kappa, quick=args.quick)
    ref = d["reference"]
    print(
        f"{d['groom']}: {d['strands']} strands, {d['vertices']} vertices; light {d['light']}, "
        f"κ = {d['kappa']}; reference {ref['n_slices']} slices × {ref['resolution']} texels"
    )
    print()
    print(
        table(
            d["rows"],
            [
                ("setting", "slices × res", "s"),
                ("maps", "Ω maps", "s"),
                ("t_jax", "hairlut (ms)", ".2f"),
                ("t_first", "first call (ms)", ".0f"),
                ("t_np", "NumPy (ms)", ".2f"),
                ("speedup", "NumPy / hairlut", ".1f"),
                ("max_jax", "max |Δτ| ref", ".3f"),
                ("rms_jax", "RMS |Δτ| ref", ".4f"),
                ("max_np", "NumPy max |Δτ| ref", ".3f"),
                ("rms_np", "NumPy RMS |Δτ| ref", ".4f"),
                ("max_depth", "max |Δτ| slices only", ".3f"),
                ("rms_depth", "RMS |Δτ| slices only", ".4f"),
                ("max_cross", "max |τ_hairlut − τ_NumPy|", ".1e"),
                ("mean_tau", "mean τ", ".3f"),
            ],
        )
    )
    print(
        f"\ntimes: maps + τ at every vertex, best of {d['repeat']} runs after a warm-up. The reference shares the "
        "method, so 'ref' errors are discretisation differences (slices, texel filter width, pieces); finer texels "
        "resolve single strands (a strand shadows its own vertices more), so they do not converge to zero with "
        "resolution."
    )
    print(f"\nwrote {save('opacity_maps', d)}")


if __name__ == "__main__":
    main()
