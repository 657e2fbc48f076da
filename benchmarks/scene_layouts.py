"""Scene-table layouts (issue 12): accuracy, bytes and bake rate per layout, each groom traced once per light grid.

    python -m benchmarks.scene_layouts --scene tables/scenes/sintel-groom.toml [--lights 16 9 5] [--json OUT]
    python -m benchmarks.scene_layouts --paper-subset 64 [--fast 128 1 0] [--json OUT]  # bake CPU, paper-scale model
    python -m benchmarks.scene_layouts --scene SCENE.toml --bake 0 0 0 --bake 128 1 0  # the bake's knobs' accuracy

A ``scene_maps`` table's α and re rows are functions of the traced grid alone; its layout (Fourier terms
K, shading bins Q, storage dtype, the ratio's view step) only compresses them (``hairlut.scenemaps.compress``).  So per light
grid L this traces the groom's non-empty sectors once (``hairlut.march.trace_view_grid`` on the scene's
V views, what the bake runs), then, for each layout with 2K + 1 ≤ L, compresses, casts, writes the table
(``hairlut.assets.write_table``: chunked gzip + shuffle, the bytes on disk) and fetches it with the
scene method's own frame (``MapSource.frame``) against the converged truth of ``hairlut.bench.map_truth`` (the maps part's).  The
records carry map_accuracy's keys (``method``, ``re_rel_l2``, ``alpha_rel_l2``, ``coverage_rel_l2``,
``frame_ms``, ``bake_s``, ``bytes``) plus ``terms``, ``shading_pixels``, ``dtype``, ``lights``, the
uncompressed ``raw_bytes``, ``sectors_per_s`` of the trace and the paper-scale projections of the size
(``paper_mb``, ``paper_raw_mb``: this groom's bytes per row × the paper model's non-empty sectors) and, with ``--paper-subset``,
of the bake time (a measured subset of the paper model's own sectors, its own trace settings).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from hairlut.bench import map_angles, map_errors, map_scene, map_truth, ring_model

from ._common import ROOT, emit, table

#: (terms K, shading bins Q, dtype, ratio_step) measured for every light grid that resolves K.
LAYOUTS = [
    (4, 16, "float16", 1),
    (4, 8, "float16", 1),
    (4, 8, "float32", 1),
    (3, 8, "float16", 1),
    (2, 16, "float16", 1),
    (2, 8, "float16", 1),
    (4, 4, "float16", 1),
    (2, 4, "float16", 1),
    (1, 16, "float16", 1),
    (1, 8, "float16", 1),
    (2, 16, "float16", 2),
    (2, 16, "float16", 4),
    (2, 8, "float16", 2),
]
#: Non-empty sectors of the paper-scale model (``hairlut.bench.ring_model``: 17 clusters × 3 layers, s_t = 64,
#: s_u = 16: 53,040 sectors, 52,888 of them holding strands).
PAPER_LIVE = 52888


def _write(path: Path, recipe: dict, half, coef, row) -> int:
    from hairlut.assets import Axis, Variable, write_table

    n, h, P = half.shape
    V, Q, T = coef.shape[1:]
    axes = [
        Axis("sector", np.arange(n), "1", "table row"),
        Axis("view_half", np.arange(h), "1", "view"),
        Axis("view", np.arange(V), "1", "view"),
        Axis("pixel", np.arange(P), "1", "pixel"),
        Axis("bin", np.arange(Q), "1", "bin"),
        Axis("term", np.arange(T), "1", "term"),
        Axis("scene_sector", np.arange(len(row)), "1", "scene sector"),
    ]
    write_table(
        path,
        "scene_maps",
        recipe,
        axes,
        [
            Variable("alpha", half, ("sector", "view_half", "pixel"), "1", "α"),
            Variable("ratio", coef, ("sector", "view", "bin", "term"), "1", "re/α terms"),
            Variable("row", row, ("scene_sector",), "1", "table row"),
        ],
    )
    return path.stat().st_size


def _frame(src, ix, sc, runs: int = 3):
    src.view(ix, sc.view, sc.lights)
    best, out = np.inf, None
    for _ in range(runs):
        t0 = time.perf_counter()
        out = src.view(ix, sc.view, sc.lights)
        out[0].block_until_ready()
        best = min(best, time.perf_counter() - t0)
    return 1e3 * best, (np.asarray(out[0]), np.asarray(out[1]))


def layouts(args) -> list[dict]:
    import jax.numpy as jnp

    from hairlut.march import bake_view_grid, trace_view_grid
    from hairlut.planner import scene_maps_recipe
    from hairlut.scenemaps import SceneMaps, compress, fetch_kernel, hrir_recipe, ratio_terms, scene_inputs
    from hairlut.synth import MapSource

    prep, t_rows, t_maps, truth_s = map_truth(args.scene, False, cache=args.truth_cache)
    ix = prep.index
    own = map_scene(args.scene).config["render"]  # --bake: the scene file's own layout (map_accuracy's first scene row)
    sc = map_scene(
        args.scene,
        method="scene",
        rays=2,
        **({k: own[k] for k in ("views", "terms", "shading_pixels", "precision")} if args.bake else {}),
    )
    recipe = scene_maps_recipe(sc)
    V = recipe["table"]["views"]
    dens, geom = scene_inputs(sc, recipe)
    live = np.flatnonzero(dens.reshape(len(dens), -1).max(axis=1) > 0)
    row = np.full(len(dens), -1, np.int32)
    row[live] = np.arange(live.size, dtype=np.int32)
    full = hrir_recipe(recipe)
    tv, tl, _ = map_angles(prep, prep.scene)
    records = []
    t = recipe["table"]
    # --bake: the scene's own layout only, computed by bake_view_grid at each (alpha_grid, shade_rays, shade_steps)
    runs = [(L, None) for L in args.lights] if not args.bake else [(t["lights"], kw) for kw in args.bake]
    with tempfile.TemporaryDirectory() as tmp:
        for L, knobs in runs:
            t0 = time.perf_counter()
            if knobs is None:
                a, re = trace_view_grid(dens[live], geom[live], full, views=V, lights=L)
                layouts_here = LAYOUTS
            else:
                ag, sr, sk = knobs
                half_b, ab, rb = bake_view_grid(
                    dens[live],
                    geom[live],
                    full,
                    views=V,
                    lights=L,
                    ratio_step=t["ratio_step"],
                    bins=t["shading_pixels"],
                    alpha_grid=ag,
                    shade_rays=sr or None,
                    shade_steps=sk or None,
                )
                layouts_here = [(t["terms"], t["shading_pixels"], t["dtype"], t["ratio_step"])]
            trace_s = time.perf_counter() - t0
            print(
                f"traced {live.size} rows on {V} views × {L} lights in {trace_s:.1f} s"
                + (f" (bake_view_grid alpha_grid={ag}, shade_rays={sr}, shade_steps={sk})" if knobs else ""),
                flush=True,
            )
            for K, Q, dt, step in layouts_here:
                if 2 * K + 1 > L or full["trace"]["pixels"] % Q:
                    continue
                t1 = time.perf_counter()
                if knobs is None:
                    half, coef, _ = compress(a, re, V, K, Q, step)
                else:
                    half, coef = np.asarray(half_b, np.float64), ratio_terms(ab, rb, V, K, step)
                half, coef = half.astype(dt), coef.astype(dt)
                comp_s = time.perf_counter() - t1
                rec = {
                    **recipe,
                    "table": {**recipe["table"], "lights": L, "terms": K, "shading_pixels": Q, "dtype": dt, "ratio_step": step},
                }
                disk = _write(Path(tmp) / "t.h5", rec, half, coef, row)
                maps = SceneMaps(half, coef, row, rec)
                dev = (jnp.asarray(half), jnp.asarray(coef), jnp.asarray(row))
                ms, maps_out = _frame(MapSource("scene", "", maps.pixels, maps=maps, device=dev), ix, prep.scene)
                ra, rr = fetch_kernel(*dev, tv, tl)
                raw = half.nbytes + coef.nbytes + row.nbytes
                records.append(
                    {
                        "method": "scene",
                        "knobs": f"views={V}, lights={L}, terms={K}, shading_pixels={Q}, {dt}, "
                        f"ratio_step={step}" + (f", alpha_grid={ag}, shade_rays={sr}, shade_steps={sk}" if knobs else ""),
                        "bake_knobs": " ".join(map(str, knobs)) if knobs else None,
                        "views": V,
                        "lights": L,
                        "terms": K,
                        "shading_pixels": Q,
                        "dtype": dt,
                        "ratio_step": step,
                        "frame_ms": ms,
                        "bake_s": trace_s + comp_s,
                        "bytes": disk,
                        "raw_bytes": raw,
                        "sectors_per_s": live.size / trace_s,
                        "paper_mb": disk / live.size * PAPER_LIVE / 1e6,
                        "paper_raw_mb": (half.nbytes + coef.nbytes) / live.size * PAPER_LIVE / 1e6,
                        **map_errors(maps_out, t_maps, (np.asarray(ra), np.asarray(rr)), t_rows),
                    }
                )
                print(records[-1], flush=True)
    print(
        f"\n## Scene-table layouts of {args.scene.name} ({live.size} of {len(dens)} sectors live) against the "
        f"converged truth ({truth_s:.1f} s to trace)\n"
    )
    print(
        table(
            records,
            [
                ("lights", "L", "d"),
                ("bake_knobs", "alpha_grid, shade_rays, shade_steps", "s"),
                ("terms", "K", "d"),
                ("shading_pixels", "Q", "d"),
                ("dtype", "dtype", "s"),
                ("ratio_step", "ratio step", "d"),
                ("re_rel_l2", "re", ".3f"),
                ("alpha_rel_l2", "α", ".3f"),
                ("coverage_rel_l2", "coverage", ".3f"),
                ("alpha_bias", "mean-α bias", "+.3f"),
                ("frame_ms", "maps ms", ".1f"),
                ("bytes", "bytes on disk", "d"),
                ("paper_mb", "paper-scale MB (disk)", ".0f"),
                ("paper_raw_mb", "paper-scale MB (raw)", ".0f"),
                ("sectors_per_s", "rows/s", ".2f"),
            ],
        )
    )
    emit(f"scene_layouts_{args.scene.stem}", {"scene": str(args.scene), "truth_seconds": truth_s, "records": records}, args.json)
    return records


def paper_subset(args) -> list[dict]:
    """Bake CPU time on ``--paper-subset`` N of the paper model's own non-empty sectors (evenly spread), per light grid:
    the reference tracer (``trace_view_grid`` then ``compress``) and the bake's own path (``bake_view_grid`` then
    ``ratio_terms``) at the recipe's knobs and each ``--fast`` setting, in the same run (warm: compiled on the timed
    shapes first), with their differences from the reference and the projected paper-scale bake; also how many
    of the model's sectors are live and how many are exact duplicates (density and geometry bytes)."""
    import hashlib

    from hairlut.march import bake_view_grid, trace_view_grid
    from hairlut.planner import scene_maps_recipe
    from hairlut.scene import resolve_scene
    from hairlut.scenemaps import compress, hrir_recipe, ratio_terms, scene_inputs

    base = ring_model(17, 64, 16, 64, 400)
    sc = resolve_scene({**base, "render": {**base["render"], "method": "scene"}})
    recipe = scene_maps_recipe(sc)
    full = hrir_recipe(recipe)
    dens, geom = scene_inputs(sc, recipe)
    live = np.flatnonzero(dens.reshape(len(dens), -1).max(axis=1) > 0)
    unique = len({hashlib.sha256(dens[i].tobytes() + geom[i].tobytes()).digest() for i in live})
    print(f"paper model: {len(dens)} sectors, {live.size} live, {unique} distinct live (density + geometry bytes)")
    pick = live[np.linspace(0, live.size - 1, args.paper_subset).astype(np.int64)]
    t = recipe["table"]
    V, Q, K, step = t["views"], t["shading_pixels"], t["terms"], t["ratio_step"]
    settings = [dict(alpha_grid=t["alpha_grid"], shade_rays=t["shade_rays"], shade_steps=t["shade_steps"])]
    settings += [dict(zip(("alpha_grid", "shade_rays", "shade_steps"), f)) for f in args.fast]

    def cpu(fn):
        fn()  # compile on the timed shapes
        c0, t0 = time.process_time(), time.perf_counter()
        out = fn()
        return out, time.process_time() - c0, time.perf_counter() - t0

    rel = lambda x, y: float(np.linalg.norm(x - y) / np.linalg.norm(y))  # noqa: E731
    records = []
    for L in args.lights:
        (a, re), c_ref, w_ref = cpu(lambda: trace_view_grid(dens[pick], geom[pick], full, views=V, lights=L))
        half_ref, coef_ref, _ = compress(a, re, V, K, Q, step)
        rows = [("reference (trace_view_grid)", c_ref, w_ref, 0.0, 0.0)]
        for j, kw in enumerate(settings):
            (half, ab, rb), c, w = cpu(
                lambda: bake_view_grid(
                    dens[pick],
                    geom[pick],
                    full,
                    views=V,
                    lights=L,
                    ratio_step=step,
                    bins=Q,
                    **{k: v or None for k, v in kw.items() if k in ("shade_rays", "shade_steps")},
                    alpha_grid=kw["alpha_grid"],
                )
            )
            coef = ratio_terms(ab, rb, V, K, step)
            rows.append((", ".join(f"{k}={v}" for k, v in kw.items()), c, w, rel(half, half_ref), rel(coef, coef_ref)))
            if j == 0:  # the recipe's own table: bytes on disk per row (gzip) × the live sectors
                with tempfile.TemporaryDirectory() as tmp:
                    disk = _write(
                        Path(tmp) / "t.h5",
                        recipe,
                        half.astype(t["dtype"]),
                        coef.astype(t["dtype"]),
                        np.arange(pick.size, dtype=np.int32),
                    )
                print(
                    f"paper-scale table ({t['dtype']}, {Q} bins, ratio_step {step}): {disk / pick.size * live.size / 1e6:.0f} MB "
                    f"on disk (this subset's bytes per row × {live.size}), "
                    f"{(half.size + coef.size) * np.dtype(t['dtype']).itemsize / pick.size * live.size / 1e6:.0f} MB raw",
                    flush=True,
                )
        for name, c, w, ea, er in rows:
            records.append(
                {
                    "lights": L,
                    "path": name,
                    "rows": int(pick.size),
                    "cpu_s": c,
                    "wall_s": w,
                    "cpu_s_per_1000": 1000 * c / pick.size,
                    "speedup": c_ref / c,
                    "alpha_rel": ea,
                    "ratio_rel": er,
                    "paper_live": int(live.size),
                    "paper_unique": unique,
                    "paper_bake_cpu_min": live.size * c / pick.size / 60,
                    "paper_bake_min_2_cores": live.size * c / pick.size / 60 / 2,
                }
            )
            print(records[-1], flush=True)
    print(
        f"\n## Scene-table bake CPU on {pick.size} of the paper model's {live.size} non-empty sectors "
        f"({unique} distinct; grid {full['sectors']['grid']}, {full['trace']['steps']} steps, {full['trace']['pixels']} px, "
        f"{full['trace']['rays_per_pixel']} rays, {V} views, ratio_step {step}, {Q} bins)\n"
    )
    print(
        table(
            records,
            [
                ("lights", "L", "d"),
                ("path", "path", "s"),
                ("cpu_s_per_1000", "CPU-s / 1000 live", ".1f"),
                ("speedup", "× (same run)", ".1f"),
                ("alpha_rel", "α rel-L2 vs ref", ".4f"),
                ("ratio_rel", "terms rel-L2 vs ref", ".4f"),
                ("paper_bake_cpu_min", "paper-scale CPU-min", ".1f"),
                ("paper_bake_min_2_cores", "paper-scale min on 2 cores", ".1f"),
            ],
        )
    )
    emit("scene_bake_rate_paper", {"records": records}, args.json)
    return records


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, default=ROOT / "tables" / "scenes" / "sintel-groom.toml")
    ap.add_argument("--lights", type=int, nargs="+", default=[16, 9, 5], help="light grids L of the bake")
    ap.add_argument(
        "--truth-cache",
        type=Path,
        help="keep the traced truth in this .npz and reuse it while the scene and recipe are unchanged",
    )
    ap.add_argument("--paper-subset", type=int, metavar="N", help="only the bake rate on N paper-model sectors")
    ap.add_argument(
        "--fast",
        type=int,
        nargs=3,
        action="append",
        default=[],
        metavar=("ALPHA_GRID", "RAYS", "STEPS"),
        help="with --paper-subset: also time bake_view_grid at these table.alpha_grid, shade_rays, shade_steps",
    )
    ap.add_argument(
        "--bake",
        type=int,
        nargs=3,
        action="append",
        default=[],
        metavar=("ALPHA_GRID", "RAYS", "STEPS"),
        help="without --paper-subset: only the scene's own layout, baked by bake_view_grid at these "
        "table.alpha_grid, shade_rays, shade_steps (0: the trace's), against the converged truth (repeatable)",
    )
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    return paper_subset(args) if args.paper_subset else layouts(args)


if __name__ == "__main__":
    main()
