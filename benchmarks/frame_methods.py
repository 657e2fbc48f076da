"""The online frame per ``[render] method`` on the paper-scale model (issue 12): wall and CPU time.

    python -m benchmarks.frame_methods [--methods direct scene] [--reads pair track] [--shading-pixels Q] [--quick]

The model is ``hairlut.bench.ring_model`` (the paper's human model: 17 clusters × 3 layers, s_t = 64, s_u = 16,
64² texels per layer; ``--quick``: 2 clusters, s_t = 16, 32², 100 strands), the frame ``hairlut.synth.render_view``, best
of 10 frames after a warm-up (2 for ``direct``), wall and process CPU time: ``direct`` traces every sector each
frame; ``scene`` fetches from a scene table of the model's real shape (its live sectors, the default layout or
``--shading-pixels`` bins) whose *contents* are synthetic (a paper-scale bake takes hours on this CPU: the fetch's
cost does not depend on the values); bytes are the kind's uncompressed estimate.  The frame against its NumPy
implementation, and per shadow method, is the maps part of ``hairlut bench`` (``hairlut.bench.online_frame_study``).
Prints a table and writes results/online_frame_map_methods.json.
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

from hairlut.bench import ring_model

from ._common import save, table


def cpu_timed(fn):
    """(wall s, process CPU s, result) of fn(): CPU time counts every thread, the measure on a shared machine."""
    c0, w0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.perf_counter() - w0, time.process_time() - c0, out


def _synthetic_maps(sc, live):
    """A scene table of ``sc``'s real shape (rows for ``live`` sectors; every sector when None) with random
    contents, and its recipe."""
    from hairlut.geometry import ClusterGeometry, build_sectors
    from hairlut.planner import scene_maps_recipe
    from hairlut.scene import scene_clusters
    from hairlut.scenemaps import SceneMaps

    recipe = scene_maps_recipe(sc)
    t, P = recipe["table"], recipe["hrir"]["trace"]["pixels"]
    rng = np.random.default_rng(0)
    if live is None:  # direct not run: every sector live (an upper bound of the fetch's work)
        live = np.ones(
            sum(
                build_sectors(ClusterGeometry(spec), st, np.zeros(st.n_strands, np.int64)).n_sectors
                for spec, st in scene_clusters(sc)
            ),
            bool,
        )
    n = int(live.sum())
    row = np.full(live.size, -1, np.int32)
    row[live] = np.arange(n, dtype=np.int32)
    maps = SceneMaps(
        rng.random((n, t["views"] // 2, P)).astype(t["dtype"]),
        (0.1 * rng.random((n, t["views"] // t["ratio_step"], t["shading_pixels"], 2 * t["terms"] + 1))).astype(t["dtype"]),
        row,
        recipe,
    )
    return maps, recipe, live


def map_methods(args, runs: int = 10) -> list[dict]:
    """Frame time per ``[render] method`` and ``layer_reads`` on the model (module docstring)."""
    from hairlut.scene import resolve_scene
    from hairlut.scenemaps import BAKER
    from hairlut.synth import prepare, render_view

    base = ring_model(args.clusters, args.s_t, args.s_u, args.res, args.strands)
    rows, live = [], None
    knobs = {"shading_pixels": args.shading_pixels} if args.shading_pixels else {}
    for method, reads in ((m, r) for m in args.methods for r in args.reads):
        sc = resolve_scene(
            {**base, "render": {**base["render"], "method": method, "layer_reads": reads, **(knobs if method == "scene" else {})}}
        )
        maps = None
        if method == "scene":
            maps, recipe, live = _synthetic_maps(sc, live)
        t0 = time.perf_counter()
        prep = prepare(sc, maps=maps)
        t_prep = time.perf_counter() - t0
        if method == "direct":
            d = prep.maps.density
            live = d.reshape(len(d), -1).max(axis=1) > 0
        render_view(prep)  # warm-up: compiles
        frames = [cpu_timed(lambda: render_view(prep)) for _ in range(runs if method == "scene" else 2)]
        sec, cpu = (np.array([f[i] for f in frames]) for i in (0, 1))
        best = frames[int(np.argmin(sec))][2]
        extra = {}
        if method == "scene":  # the maps stage alone (params, fetch, sweep), CPU time, best of the runs
            view, lights = prep.scene.view, prep.scene.lights
            stage = [
                cpu_timed(lambda: jax.block_until_ready(prep.maps.view(prep.index, view, lights)[:2]))[1] for _ in range(runs)
            ]
            extra["maps_cpu"] = 1e3 * min(stage)
            nbytes, secs = BAKER.estimate(recipe, sectors=live.size, live=int(live.sum()))
            extra.update(table_bytes_estimate=nbytes, bake_s_estimate=secs)
        rows.append(
            {
                "method": method,
                "reads": reads,
                "sectors": int(live.size),
                "live": int(live.sum()),
                "prepare_s": t_prep,
                "ms": 1e3 * sec.min(),
                "cpu_ms": 1e3 * cpu.min(),
                "maps": 1e3 * best.stats["seconds"]["maps"],
                **extra,
            }
        )
        print(rows[-1], flush=True)
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--clusters", type=int, default=17)
    ap.add_argument("--s-t", type=int, default=64)
    ap.add_argument("--s-u", type=int, default=16)
    ap.add_argument("--res", type=int, default=64, help="texels per layer side")
    ap.add_argument("--strands", type=int, default=400, help="strands per cluster")
    ap.add_argument("--quick", action="store_true", help="2 clusters, s_t = 16 (a smoke run)")
    ap.add_argument(
        "--methods",
        nargs="+",
        default=["direct", "scene"],
        choices=["direct", "scene"],
        help="which (scene alone counts every sector live)",
    )
    ap.add_argument(
        "--reads", nargs="+", default=["pair"], choices=["pair", "track"], help="[render] layer_reads, each timed in the same run"
    )
    ap.add_argument(
        "--shading-pixels", type=int, default=0, help="the scene table's re/α pixel bins (default: the scene default)"
    )
    args = ap.parse_args(argv)
    if args.quick:
        args.clusters, args.s_t, args.res, args.strands = 2, 16, 32, 100
    rows = map_methods(args)
    print(
        table(
            rows,
            [
                ("method", "[render] method", "s"),
                ("reads", "layer_reads", "s"),
                ("sectors", "sectors", "d"),
                ("live", "live", "d"),
                ("prepare_s", "prepare s", ".1f"),
                ("ms", "frame ms", ".1f"),
                ("cpu_ms", "frame CPU ms", ".1f"),
                ("maps", "maps ms", ".1f"),
                ("maps_cpu", "maps CPU ms", ".1f"),
            ],
        )
    )
    print("(best of the timed frames; CPU ms: process CPU time, every thread; maps CPU ms: the maps stage alone)")
    save("online_frame_map_methods", {"device": str(jax.devices()[0]), "args": vars(args), "rows": rows})


if __name__ == "__main__":
    main()
