"""Variants of the maps part's accuracy study that ``hairlut bench`` does not run (issue 12).

    python -m benchmarks.map_variants --scene tables/scenes/sintel-groom.toml [--only direct] [--satf-features basic
        moments] [--satf-views 32 64] [--satf-k 1 4] [--satf-count N] [--scene-knob views=128] [--default-only]
    python -m benchmarks.map_variants --convergence      # the truth at level 1 against one more refinement
    python -m benchmarks.map_variants --grid-study 16 32 64   # direct maps per density grid

The study and its truth are ``hairlut.bench.map_accuracy_study`` and ``hairlut.bench.map_truth`` (their docstrings
say what is traced and measured); the bench part runs the study with its defaults on Sintel (quick: two-clusters,
no SATF).  Here: any method alone, SATF databases of other feature sets, view grids, record counts and k, a chosen
knob of the first scene row, the scene rows at the file's own knobs only; ``--convergence``: the truth's own error
(level 1 against level 2: 8 rays, 4× grid, 4× steps); ``--grid-study``: the direct method on n × n density grids
(2n steps, and the scene's own steps) against the truth, trace seconds with their ratio to the first row (the same
run, so the ratio holds under a shared machine's load).  The scene table's layouts per light grid are
``benchmarks.scene_layouts``.  Prints a table and writes JSON (``--json OUT``, else results/map_*.json).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from hairlut.bench import map_accuracy_study, map_angles, map_errors, map_scene, map_truth

from ._common import ROOT, emit, table


def convergence(args) -> dict:
    """The truth's own error: level 1 against level 2 (texel re, α and coverage rel-L2)."""
    _, rows1, maps1, s1 = map_truth(args.scene, False, 1, cache=args.truth_cache)
    _, rows2, maps2, s2 = map_truth(args.scene, False, 2)
    rec = {"scene": str(args.scene), "level1_s": s1, "level2_s": s2, **map_errors(maps1, maps2, rows1, rows2)}
    print(f"\n## Truth convergence of {args.scene.name}: (4 rays, 2× grid, 2× steps) against (8 rays, 4× grid, 4× steps)\n")
    print(
        table(
            [rec],
            [
                ("re_rel_l2", "re rel-L2", ".4f"),
                ("alpha_rel_l2", "α rel-L2", ".4f"),
                ("coverage_rel_l2", "coverage rel-L2", ".4f"),
                ("alpha_bias", "mean-α bias", "+.4f"),
                ("level1_s", "level 1 s", ".1f"),
                ("level2_s", "level 2 s", ".1f"),
            ],
        )
    )
    emit(f"map_truth_{args.scene.stem}", rec, args.json)
    return rec


def grid_study(args) -> list[dict]:
    """The direct method at several sector density grids and step counts against the truth of the scene's own
    recipe (module docstring)."""
    from hairlut.march import direct_sector_maps, scene_sector_inputs
    from hairlut.planner import direct_recipe
    from hairlut.synth import sweep_sectors

    prep, t_rows, t_maps, truth_s = map_truth(args.scene, args.quick, cache=args.truth_cache)
    rec = direct_recipe(map_scene(args.scene, method="direct"))
    tv, tl, cs = map_angles(prep, prep.scene)
    tv, tl = np.asarray(tv, np.float64), np.asarray(tl, np.float64)
    records = []
    for n in args.grid_study:
        for steps in sorted({2 * n, rec["trace"]["steps"]}):
            r = {**rec, "sectors": {**rec["sectors"], "grid": [n, n]}, "trace": {**rec["trace"], "steps": steps}}
            parts = [scene_sector_inputs(pc.table, r, extent=pc.frames.extent) for pc in prep.clusters]
            dens, geom = np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
            t0 = time.perf_counter()
            a, re = direct_sector_maps(dens, geom, tv, tl, r)
            secs = time.perf_counter() - t0
            maps = tuple(np.asarray(x) for x in sweep_sectors(prep.index, a, re, cs))
            records.append(
                {
                    "method": "direct",
                    "grid": n,
                    "steps": steps,
                    "rays": rec["trace"]["rays_per_pixel"],
                    "trace_s": secs,
                    **map_errors(maps, t_maps, (a, re), t_rows),
                }
            )
            records[-1]["trace_ratio"] = secs / records[0]["trace_s"]
            print(records[-1], flush=True)
    print(f"\n## Direct maps of {args.scene.name} per density grid against the truth ({truth_s:.1f} s to trace)\n")
    print(
        table(
            records,
            [
                ("grid", "grid", "d"),
                ("steps", "steps", "d"),
                ("re_rel_l2", "re rel-L2", ".3f"),
                ("alpha_rel_l2", "α rel-L2", ".3f"),
                ("coverage_rel_l2", "coverage rel-L2", ".3f"),
                ("alpha_bias", "mean-α bias", "+.3f"),
                ("trace_s", "trace s", ".1f"),
                ("trace_ratio", "× first row", ".2f"),
            ],
        )
    )
    emit(f"map_grid_{args.scene.stem}", {"scene": str(args.scene), "truth_seconds": truth_s, "records": records}, args.json)
    return records


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, default=ROOT / "tables" / "scenes" / "sintel-groom.toml")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--quick", action="store_true", help="fewer knobs; a 2-ray truth")
    ap.add_argument("--default-only", action="store_true", help="the scene method at the scene's own knobs only")
    ap.add_argument(
        "--convergence",
        action="store_true",
        help="only check the truth: level 1 against one more refinement (8 rays, 4× grid, 4× steps)",
    )
    ap.add_argument(
        "--grid-study",
        type=int,
        nargs="+",
        metavar="N",
        help="only the direct method on N × N density grids (2N steps, and the scene's own steps)",
    )
    ap.add_argument(
        "--truth-cache",
        type=Path,
        help="keep the traced truth in this .npz and reuse it while the scene and recipe are unchanged",
    )
    ap.add_argument(
        "--scene-knob",
        dest="scene_knobs",
        action="append",
        metavar="KEY=VALUE",
        help="the first scene row's knob (views, terms, shading_pixels, precision) over the scene's own",
    )
    ap.add_argument("--only", choices=("direct", "scene", "satf"), action="append", help="run only these methods (repeatable)")
    ap.add_argument(
        "--satf-features",
        nargs="+",
        default=["basic"],
        choices=("basic", "moments", "projection"),
        help="SATF rows: the database's feature sets (sectors.features)",
    )
    ap.add_argument("--satf-views", nargs="+", type=int, default=[32], help="SATF rows: view grids (angles.views)")
    ap.add_argument("--satf-k", nargs="+", type=int, default=[4], help="SATF rows: k of the lookup")
    ap.add_argument("--satf-count", type=int, help="SATF rows: records (sectors.count) over the planner's")
    args = ap.parse_args(argv)
    if args.convergence:
        return convergence(args)
    if args.grid_study:
        return grid_study(args)
    first = {}
    for item in args.scene_knobs or ():
        key, _, value = item.partition("=")
        if key not in ("views", "terms", "shading_pixels", "precision"):
            ap.error(f"--scene-knob {item!r}: the key must be one of views, terms, shading_pixels, precision")
        first[key] = value if key == "precision" else int(value)
    doc = map_accuracy_study(
        args.scene,
        args.quick,
        methods=tuple(args.only or ("direct", "scene", "satf")),
        first_knobs=first,
        default_only=args.default_only,
        satf_features=args.satf_features,
        satf_views=args.satf_views,
        satf_k=args.satf_k,
        satf_count=args.satf_count,
        truth_cache=args.truth_cache,
        progress=print,
    )
    print(f"\n## Map accuracy of {args.scene.name} against a converged truth ({doc['truth_seconds']:.1f} s to trace)\n")
    print(
        table(
            doc["records"],
            [
                ("method", "method", "s"),
                ("knobs", "knobs", "s"),
                ("re_rel_l2", "re rel-L2", ".3f"),
                ("alpha_rel_l2", "α rel-L2", ".3f"),
                ("coverage_rel_l2", "coverage rel-L2", ".3f"),
                ("alpha_bias", "mean-α bias", "+.3f"),
                ("frame_ms", "maps ms", ".1f"),
                ("bake_s", "bake s", ".1f"),
                ("bytes", "bytes", "d"),
            ],
        )
    )
    emit(f"map_accuracy_{args.scene.stem}", doc, args.json)
    return doc


if __name__ == "__main__":
    main()
