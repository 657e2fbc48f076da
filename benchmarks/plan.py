"""Planner savings: the needed-only bake against a full bake, and the cold against the warm demo.

    python benchmarks/plan.py [--quick] [--skip-demo]

1. For each example scene, in an empty cache: ``hairlut.plan`` → ``bake`` (needed only),
   its wall time and bytes on disk, with the planner's estimates beside them; then the
   same scene re-planned (everything reused, nothing baked).
2. The full bake a user without a planner would run for any scene: the default HRIR
   database (tables/hrir-default.toml, the generic sector space), the paper's SH tables
   (tables/sh-paper.toml: dense grids) with the sky light, and the voxel SH transmittance.
3. How well each database covers the scene it serves: the median and 90th-percentile
   distance from a scene sector's features to the nearest database record, in the scene
   features' standard deviations (the same units for both databases).
4. ``hairlut demo`` as a subprocess with an empty table cache and an empty JAX compilation
   cache (cold), then again (warm).

The measurements live in ``hairlut.bench`` (part ``plan`` of ``hairlut bench``); this script prints them.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import save, table  # noqa: E402

from hairlut.bench import database_coverage, demo_runs, full_bake, needed_only_bake  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "tables" / "scenes"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two scenes, a 128-sector full database")
    ap.add_argument("--skip-demo", action="store_true", help="skip the cold and warm demo runs")
    args = ap.parse_args(argv)
    names = ["two-clusters.toml", "sky-clusters.toml"]
    if not args.quick and (ROOT.parent / "shared" / "data" / "hair" / "sintel_lite.tfx").is_file():
        names.append("sintel-groom.toml")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "full").mkdir()
        full = full_bake(tmp / "full", args.quick)
        rows, cov = [], {}
        for name in names:
            r = needed_only_bake(SCENES / name, tmp / f"cache-{name}")
            rows.append(r)
            needed = r.pop("hrir_db")  # None when the scene's map method needs no database
            cov[name] = database_coverage(SCENES / name, {"full": full["hrir_db"], **({"needed": needed} if needed else {})})
        full_s = sum(full["seconds"].values())
        for r in rows:
            r["time_ratio"] = r["bake_s"] / full_s
            r["bytes_ratio"] = r["bytes"] / full["bytes"]
            (r["nn_needed_med"], r["nn_needed_p90"]), (r["nn_full_med"], r["nn_full_p90"]) = \
                cov[r["scene"]].get("needed", (None, None)), cov[r["scene"]]["full"]
        demo = None if args.skip_demo else demo_runs(tmp / "demo")
    print(f"full bake (any scene): {full_s:.1f} s (" + ", ".join(f"{k} {v:.1f} s" for k, v in full["seconds"].items())
          + f"), {full['bytes'] / 2**20:.1f} MiB\n")
    print(table(rows, [("scene", "scene", "s"), ("baked", "baked", "s"), ("skipped", "skipped", "s"),
                       ("plan_s", "plan s", ".1f"), ("bake_s", "bake s", ".1f"), ("estimate_s", "estimated s", ".1f"),
                       ("time_ratio", "× full time", ".2f"), ("bytes", "bytes", ",d"), ("bytes_ratio", "× full bytes", ".2f"),
                       ("rebake_after_replan", "re-bakes when re-planned", "d"),
                       ("nn_needed_med", "NN dist needed (median)", ".2f"), ("nn_needed_p90", "(p90)", ".2f"),
                       ("nn_full_med", "NN dist full (median)", ".2f"), ("nn_full_p90", "(p90)", ".2f")]))
    if demo:
        print(f"\nhairlut demo: cold {demo['cold']:.1f} s, warm {demo['warm']:.1f} s")
    path = save("plan", {"args": vars(args), "full": {k: v for k, v in full.items() if k != "hrir_db"}, "scenes": rows,
                         "demo": demo})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
