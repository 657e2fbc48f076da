"""The paper-scale scene table baked end to end on this machine (issue 12's "baked in ≤ 5 min on the CPU").

    python -m benchmarks.scene_bake [--clusters 17] [--processes 2] [--baseline-rows 64] [--json OUT]

Builds the paper model (``hairlut.bench.ring_model``: 17 clusters × 3 layers, s_t = 64, s_u = 16: 53,040 sectors, 400
strands per cluster) as a scene whose ``render.method`` is ``scene``, and bakes its ``scene_maps`` table the way a
user on this machine would: ``--processes`` shard processes (``hairlut.scenemaps.bake(..., shard="K/N")``, what
``hairlut bake scene_maps --shard K/N`` runs; each pinned to its own core unless ``--no-pin``), then
``hairlut.bake.registry.merge`` of their shard files into one asset.  The wall clock runs from the first process's start
to the merged file (each process builds the scene's sector inputs, compiles and writes its shard: all counted).

Beside it, in the same run and on the same machine: the straightforward baseline, the reference tracer
(``hairlut.march.trace_view_grid``: every view and light per pixel, dense) and the bake's own path
(``hairlut.march.bake_view_grid``) on ``--baseline-rows`` of the model's rows in one process, their CPU seconds per
1,000 rows and the baseline's projection to the whole table on ``--processes`` cores (its full run would take
many times the target).  Records: ``path``, ``rows``, ``wall_s``, ``cpu_s``, ``cpu_s_per_1000``, ``bytes``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ._common import ROOT, emit, table

TARGET_S = 300.0


def _scene(clusters: int):
    from hairlut.bench import ring_model
    from hairlut.planner import scene_maps_recipe
    from hairlut.scene import resolve_scene

    base = ring_model(clusters, 64, 16, 64, 400)
    sc = resolve_scene({**base, "render": {**base["render"], "method": "scene"}})
    return sc, scene_maps_recipe(sc)


def worker(args) -> None:
    """One shard process: its rows of the table, timed; one JSON line on stdout."""
    if args.pin is not None:
        os.sched_setaffinity(0, {args.pin})
    c0, t0 = time.process_time(), time.perf_counter()
    from hairlut.scenemaps import bake

    sc, recipe = _scene(args.clusters)
    rep = bake(recipe, args.out, shard=args.worker, scene=sc)
    print(
        json.dumps(
            {
                "shard": args.worker,
                "rows": rep["units"],
                "live": rep["total_units"],
                "wall_s": time.perf_counter() - t0,
                "cpu_s": time.process_time() - c0,
            }
        ),
        flush=True,
    )


def baseline(args, n: int) -> list[dict]:
    """The reference tracer and the bake's path on ``args.baseline_rows`` rows, warm, in this process."""
    from hairlut.march import bake_view_grid, trace_view_grid
    from hairlut.scenemaps import compress, hrir_recipe, ratio_terms, scene_inputs

    sc, recipe = _scene(args.clusters)
    dens, geom = scene_inputs(sc, recipe)
    live = np.flatnonzero(dens.reshape(len(dens), -1).max(axis=1) > 0)
    pick = live[np.linspace(0, live.size - 1, args.baseline_rows).astype(np.int64)]
    t, full = recipe["table"], hrir_recipe(recipe)
    V, L, Q, K, step = t["views"], t["lights"], t["shading_pixels"], t["terms"], t["ratio_step"]

    def reference():
        a, re = trace_view_grid(dens[pick], geom[pick], full, views=V, lights=L)
        return compress(a, re, V, K, Q, step)[:2]

    def bake_path():
        half, ab, rb = bake_view_grid(
            dens[pick], geom[pick], full, views=V, lights=L, ratio_step=step, bins=Q, alpha_grid=t["alpha_grid"]
        )
        return half, ratio_terms(ab, rb, V, K, step)

    out = []
    for name, fn in (("reference tracer (trace_view_grid), dense", reference), ("bake path (bake_view_grid)", bake_path)):
        fn()  # compiled on the timed shapes
        c0, t0 = time.process_time(), time.perf_counter()
        arrays = fn()
        cpu = time.process_time() - c0
        out.append(
            {
                "path": name,
                "rows": int(pick.size),
                "wall_s": time.perf_counter() - t0,
                "cpu_s": cpu,
                "cpu_s_per_1000": 1000 * cpu / pick.size,
                "arrays": arrays,
                "projected_s": cpu / pick.size * n / args.processes,
            }
        )
    rel = lambda x, y: float(np.linalg.norm(x - y) / np.linalg.norm(y))  # noqa: E731
    out[1]["alpha_rel"], out[1]["terms_rel"] = (rel(x, y) for x, y in zip(out[1]["arrays"], out[0]["arrays"]))
    for r in out:
        del r["arrays"]
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clusters", type=int, default=17, help="clusters of the paper model (17: paper scale)")
    ap.add_argument("--processes", type=int, default=2, help="shard processes (one per core)")
    ap.add_argument("--no-pin", action="store_true", help="do not pin each shard process to its own core")
    ap.add_argument("--baseline-rows", type=int, default=64, help="rows for the same-run baseline (0: none)")
    ap.add_argument("--keep", type=Path, help="keep the merged table here")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--pin", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        return worker(args)

    from hairlut.bake.registry import merge

    cores = sorted(os.sched_getaffinity(0))
    with tempfile.TemporaryDirectory() as tmp:
        shards = [Path(tmp) / f"s{k}.h5" for k in range(args.processes)]
        t0 = time.perf_counter()
        procs = [
            subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "benchmarks.scene_bake",
                    "--worker",
                    f"{k}/{args.processes}",
                    "--out",
                    str(s),
                    "--clusters",
                    str(args.clusters),
                ]
                + ([] if args.no_pin else ["--pin", str(cores[k % len(cores)])]),
                stdout=subprocess.PIPE,
                text=True,
                cwd=ROOT,
            )
            for k, s in enumerate(shards)
        ]
        reports = []
        for p in procs:
            out, _ = p.communicate()
            if p.returncode:
                raise SystemExit(f"a shard process failed (exit {p.returncode})")
            reports.append(json.loads(out.strip().splitlines()[-1]))
        merged = Path(args.keep or Path(tmp) / "scene_maps.h5")
        t1 = time.perf_counter()
        merge([str(s) for s in shards], merged)
        end = time.perf_counter()
        size = merged.stat().st_size
    live = reports[0]["total_units"]
    records = [
        {
            "path": f"end to end: {args.processes} shard processes + merge",
            "rows": live,
            "wall_s": end - t0,
            "cpu_s": sum(r["cpu_s"] for r in reports),
            "cpu_s_per_1000": 1000 * sum(r["cpu_s"] for r in reports) / live,
            "bytes": size,
            "merge_s": end - t1,
            "shards": reports,
            "within_target": end - t0 <= TARGET_S,
        }
    ]
    if args.baseline_rows:
        records += baseline(args, live)
    print(f"\n## Scene table of the paper model ({args.clusters} clusters, {live} live rows), baked end to end\n")
    print(
        table(
            records,
            [
                ("path", "path", "s"),
                ("rows", "rows", "d"),
                ("wall_s", "wall s", ".1f"),
                ("cpu_s_per_1000", "CPU-s / 1,000 rows", ".1f"),
                ("projected_s", f"projected s on {args.processes} cores", ".0f"),
                ("bytes", "bytes on disk", ",d"),
                ("alpha_rel", "α rel-L2 vs reference", ".1e"),
                ("terms_rel", "terms rel-L2 vs reference", ".1e"),
            ],
        )
    )
    print(
        f"\nend to end {end - t0:.0f} s against the {TARGET_S:.0f} s target "
        f"({'within' if end - t0 <= TARGET_S else 'OVER'}); merge {end - t1:.1f} s; file {size / 1e6:.0f} MB"
    )
    emit("scene_bake", {"records": records, "target_s": TARGET_S}, args.json)
    return records


if __name__ == "__main__":
    main()
