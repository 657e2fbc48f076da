"""Map accuracy per method (issue 12): direct, scene and satf maps against a converged truth.

    python benchmarks/map_accuracy.py --scene tables/scenes/sintel-groom.toml [--json OUT] [--quick]

The scene is prepared once per method through the public API (``hairlut.synth.prepare`` with
``[render] method`` set; the scene table baked through ``hairlut.bake.registry``, the SATF database
through the planner's recipe).  **Truth**: every sector traced at its exact θv, θl by the direct
kernel with the tracer's shadow-grid lookup at 4 rays per pixel, 2× the density grid and 2× the
steps, swept into texels by the same eq 7 (``sweep_sectors``, two sectors per HSV).  Per method and
knob: texel re and α rel-L2 (‖Δ‖/‖truth‖ over all texels and lights), per-sector coverage rel-L2
(each sector's pixel-mean α; direct and scene, whose rows are per sector), the signed mean-α bias,
the frame time of the maps (best of 3 after a warm-up, at the scene's size), the bake seconds and
bytes.  JSON records: ``method``, ``re_rel_l2``, ``alpha_rel_l2``, ``coverage_rel_l2``, ``frame_ms``,
``bake_s``, ``bytes`` and the knobs.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import emit, table  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _scene(path: Path, hrir=None, **render):
    """The scene file with ``render`` keys over its own and ``hrir`` ({section: {key: value}}) over its
    ``[tables.hrir]`` (the SATF database's recipe).  With ``method`` given, the file's own map knobs are
    dropped (the rows here give every knob their method reads; another method's would be refused)."""
    from hairlut.recipes import load_toml
    from hairlut.scene import resolve_scene

    given = load_toml(path)
    if "method" in render:
        knobs = ("rays", "views", "terms", "shading_pixels", "precision")
        given = {**given, "render": {k: v for k, v in given.get("render", {}).items() if k not in knobs}}
    tables = dict(given.get("tables", {}))
    if hrir:
        own = tables.get("hrir", {})
        tables["hrir"] = {**own, **{k: {**own.get(k, {}), **v} for k, v in hrir.items()}}
    return resolve_scene({**given, "tables": tables, "render": {**given.get("render", {}), **render}}, path.parent,
                         source=str(path))


def _rows(prepared, view, lights):
    """Per-sector rows (α (S, P), re (S, L, P)) and texel maps of a prepared direct/scene method."""
    from hairlut.scenemaps import fetch_kernel
    from hairlut.march import direct_sector_maps

    tv, tl, cs = _angles(prepared, prepared.scene, view, lights)
    src = prepared.maps
    if src.method == "direct":
        return direct_sector_maps(src.density, src.geometry, np.asarray(tv, np.float64), np.asarray(tl, np.float64),
                                  src.recipe), (tv, tl, cs)
    a, r = fetch_kernel(*src.device, tv, tl)
    return (np.asarray(a), np.asarray(r)), (tv, tl, cs)


def truth(scene_path: Path, quick: bool, level: int = 1, cache: Path | None = None):
    """Converged rows and texel maps (module docstring) and the direct-prepared scene they index.
    ``level`` 1: 4 rays per pixel, 2× grid, 2× steps; level 2 (one more refinement, to check the
    first is converged): 8 rays, 4× grid, 4× steps.  ``cache``: an .npz that keeps the traced truth
    for later runs (reused only when the scene file, the recipe and the refinement are the same)."""
    import jax.numpy as jnp
    from hairlut.planner import direct_recipe
    from hairlut.synth import prepare, sweep_sectors
    from hairlut.march import direct_sector_maps, scene_sector_inputs

    sc = _scene(scene_path, method="direct", rays=1)
    prep = prepare(sc)
    rec = direct_recipe(sc)
    m = 2 ** level
    fine = {**rec, "sectors": {**rec["sectors"], "grid": [m * g for g in rec["sectors"]["grid"]]}}
    parts = [scene_sector_inputs(pc.table, fine, extent=pc.frames.extent) for pc in prep.clusters]
    dens, geom = np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    tv, tl, cs = _angles(prep, sc)
    key = {"recipe": fine, "rays": 2 if quick else 2 * m, "steps": m * rec["trace"]["steps"],
           "groom": str(sc.groom_path), "scene": Path(scene_path).read_text()}
    if cache is not None and cache.exists():
        z = np.load(cache, allow_pickle=False)
        if str(z["key"]) == json.dumps(key, sort_keys=True, default=str):
            print(f"truth from {cache}", flush=True)
            return prep, (z["a"], z["r"]), (z["re_t"], z["a_t"]), float(z["secs"])
    t0 = time.perf_counter()
    a, r = direct_sector_maps(dens, geom, np.asarray(tv, np.float64), np.asarray(tl, np.float64), fine,
                              rays=2 if quick else 2 * m, n_steps=m * rec["trace"]["steps"], shadow_lookup="grid")
    secs = time.perf_counter() - t0
    re_t, a_t = (np.asarray(x) for x in sweep_sectors(prep.index, jnp.asarray(a), jnp.asarray(r), cs))
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        with open(cache.with_suffix(".tmp.npz"), "wb") as f:
            np.savez(f, a=a, r=r, re_t=re_t, a_t=a_t, secs=secs, key=json.dumps(key, sort_keys=True, default=str))
        cache.with_suffix(".tmp.npz").replace(cache)
    return prep, (a, r), (re_t, a_t), secs


def _angles(prep, sc, view=None, lights=None):
    """Each sector's θv (S,), θl (S, L) and (cos θv, sin θv) (S, 2), as the frame computes them."""
    from hairlut.synth import params_kernel

    f32 = lambda x: np.asarray(x, np.float32)  # noqa: E731
    view, lights = sc.view if view is None else view, sc.lights if lights is None else lights
    tv, tl, cs, _, _ = params_kernel(prep.index, f32(view), f32(lights), f32(0.0), n_v=1, n_l=1)
    return tv, tl, cs


def rel(x, ref) -> float:
    return float(np.linalg.norm(np.asarray(x) - ref) / max(np.linalg.norm(ref), 1e-30))


def errors_of(maps, t_maps, rows=None, t_rows=None) -> dict:
    (re, a), (re_t, a_t) = maps, t_maps
    out = {"re_rel_l2": rel(re, re_t), "alpha_rel_l2": rel(a, a_t),
           "alpha_bias": float((np.mean(a) - np.mean(a_t)) / np.mean(a_t)), "coverage_rel_l2": None}
    if rows is not None:
        out["coverage_rel_l2"] = rel(rows[0].mean(-1), t_rows[0].mean(-1))
    return out


def frame_ms(prepared) -> tuple[float, tuple]:
    from hairlut.synth import render_clusters

    sc = prepared.scene
    render_clusters(prepared, sc.view, sc.lights, sc.light_colors)  # compile
    best = []
    for _ in range(3):
        t = {}
        res = render_clusters(prepared, sc.view, sc.lights, sc.light_colors, t)
        best.append(t["maps"])
    maps = (np.stack([c.re for c in res]), np.stack([c.alpha for c in res]))
    return 1e3 * min(best), maps


def convergence(args) -> dict:
    """The truth's own error: level 1 against level 2 (texel re, α and coverage rel-L2)."""
    _, rows1, maps1, s1 = truth(args.scene, False, 1, cache=args.truth_cache)
    _, rows2, maps2, s2 = truth(args.scene, False, 2)
    rec = {"scene": str(args.scene), "level1_s": s1, "level2_s": s2,
           **{k: v for k, v in errors_of(maps1, maps2, rows1, rows2).items()}}
    print(f"\n## Truth convergence of {args.scene.name}: (4 rays, 2× grid, 2× steps) against (8 rays, 4× grid, 4× steps)\n")
    print(table([rec], [("re_rel_l2", "re rel-L2", ".4f"), ("alpha_rel_l2", "α rel-L2", ".4f"),
                        ("coverage_rel_l2", "coverage rel-L2", ".4f"), ("alpha_bias", "mean-α bias", "+.4f"),
                        ("level1_s", "level 1 s", ".1f"), ("level2_s", "level 2 s", ".1f")]))
    emit(f"map_truth_{args.scene.stem}", rec, args.json)
    return rec


def grid_study(args) -> list[dict]:
    """The direct method at several sector density grids and step counts (``--grid-study``: n × n grids with 2n
    steps, plus n × n at the scene's own steps) against the truth of the scene's own recipe; trace seconds
    with their ratio to the first row (the same run, so the ratio holds under a shared machine's load)."""
    from hairlut.planner import direct_recipe
    from hairlut.synth import sweep_sectors
    from hairlut.march import direct_sector_maps, scene_sector_inputs

    prep, t_rows, t_maps, truth_s = truth(args.scene, args.quick, cache=args.truth_cache)
    sc = prep.scene
    rec = direct_recipe(_scene(args.scene, method="direct"))
    tv, tl, cs = _angles(prep, sc)
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
            records.append({"method": "direct", "grid": n, "steps": steps, "rays": rec["trace"]["rays_per_pixel"],
                            "trace_s": secs, **errors_of(maps, t_maps, (a, re), t_rows)})
            records[-1]["trace_ratio"] = secs / records[0]["trace_s"]
            print(records[-1], flush=True)
    print(f"\n## Direct maps of {args.scene.name} per density grid against the truth ({truth_s:.1f} s to trace)\n")
    print(table(records, [("grid", "grid", "d"), ("steps", "steps", "d"), ("re_rel_l2", "re rel-L2", ".3f"),
                          ("alpha_rel_l2", "α rel-L2", ".3f"), ("coverage_rel_l2", "coverage rel-L2", ".3f"),
                          ("alpha_bias", "mean-α bias", "+.3f"), ("trace_s", "trace s", ".1f"),
                          ("trace_ratio", "× first row", ".2f")]))
    payload = {"scene": str(args.scene), "truth_seconds": truth_s, "records": records}
    emit(f"map_grid_{args.scene.stem}", payload, args.json)
    return records


def satf_rows(args, tmp: Path, t_maps, t_rows) -> list[dict]:
    """The SATF lookup per feature set, view grid and k (``--satf-features``, ``--satf-views``, ``--satf-k``;
    ``--satf-count`` records, else the planner's): one database bake per view grid (the planner's recipe, timed);
    the other feature sets index the same records (``hairlut.hrir.reindex``: the file their own bake would
    write; bake seconds = the bake's plus the re-index's); per k the frame's maps and each sector's own
    looked-up row at its exact angles (the coverage column)."""
    from hairlut.bake import registry
    from hairlut.hrir import reindex
    from hairlut.planner import plan
    from hairlut.synth import prepare

    out = []
    for views in args.satf_views:
        hrir = {"sectors": {"features": "basic"}, "angles": {"views": views}}
        if args.satf_count:
            hrir["sectors"]["count"] = args.satf_count
        sc = _scene(args.scene, hrir, method="satf")
        p = plan(sc, tmp / "cache")
        step = p.step("hrir_db")
        t0 = time.perf_counter()
        base, _ = registry.ensure("hrir_db", step.recipe, p.cache_dir)
        base_s = time.perf_counter() - t0
        for feats in args.satf_features:
            t0 = time.perf_counter()
            path = base if feats == "basic" else reindex(base, tmp / f"hrir-{feats}-{views}.h5", feats)
            bake_s = base_s + time.perf_counter() - t0
            for k in args.satf_k:
                pr = prepare(_scene(args.scene, hrir, method="satf", neighbours=k), str(path))
                ms, maps = frame_ms(pr)
                tv, tl, _ = _angles(pr, pr.scene)
                _, a, _, _ = pr.db.query(pr.frames.features, np.asarray(tv), np.asarray(tl)[:, 0], k=k)
                rows = (a * pr.frames.occupied[:, None],)
                out.append({"method": "satf", "features": feats, "views": views, "k": k,
                            "knobs": f"{feats}, {step.recipe['sectors']['count']} records, {views} views, k={k}",
                            "frame_ms": ms, "bake_s": bake_s, "bytes": Path(path).stat().st_size,
                            "prepare_s": sum(pr.seconds.values()), **errors_of(maps, t_maps, rows, t_rows)})
                print(out[-1], flush=True)
    return out


def main(argv=None):
    from hairlut.bake import registry
    from hairlut.planner import scene_maps_recipe
    from hairlut.synth import prepare

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, default=ROOT / "tables" / "scenes" / "sintel-groom.toml")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--quick", action="store_true", help="fewer knobs; a 2-ray truth")
    ap.add_argument("--no-satf", action="store_true", help="skip the SATF rows (their database bake)")
    ap.add_argument("--default-only", action="store_true", help="the scene method at the scene's own knobs only")
    ap.add_argument("--convergence", action="store_true",
                    help="only check the truth: level 1 against one more refinement (8 rays, 4× grid, 4× steps)")
    ap.add_argument("--grid-study", type=int, nargs="+", metavar="N",
                    help="only the direct method on N × N density grids (2N steps, and the scene's own steps)")
    ap.add_argument("--truth-cache", type=Path,
                    help="keep the traced truth in this .npz and reuse it while the scene and recipe are unchanged")
    ap.add_argument("--scene-knob", dest="scene_knobs", action="append", metavar="KEY=VALUE",
                    help="the first scene row's knob (views, terms, shading_pixels, precision) over the scene's own")
    ap.add_argument("--only", choices=("direct", "scene", "satf"), action="append",
                    help="run only these methods (repeatable)")
    ap.add_argument("--satf-features", nargs="+", default=["basic"], choices=("basic", "moments", "projection"),
                    help="SATF rows: the database's feature sets (sectors.features)")
    ap.add_argument("--satf-views", nargs="+", type=int, default=[32], help="SATF rows: view grids (angles.views)")
    ap.add_argument("--satf-k", nargs="+", type=int, default=[4], help="SATF rows: k of the lookup")
    ap.add_argument("--satf-count", type=int, help="SATF rows: records (sectors.count) over the planner's")
    ap.add_argument("--scene-layouts", action="store_true",
                    help="only the scene table's layouts (terms, bins, dtype) per light grid, the groom traced once per "
                         "grid (benchmarks/scene_layouts.py; same truth and record keys)")
    ap.add_argument("--layout-lights", dest="lights", type=int, nargs="+", default=[16, 9, 5],
                    help="with --scene-layouts: the bake's light grids L")
    args = ap.parse_args(argv)
    if args.convergence:
        return convergence(args)
    if args.scene_layouts:
        from scene_layouts import layouts

        return layouts(args)
    if args.grid_study:
        return grid_study(args)
    prep_t, t_rows, t_maps, truth_s = truth(args.scene, args.quick, cache=args.truth_cache)
    records = []
    want = set(args.only or ("direct", "scene", "satf")) - ({"satf"} if args.no_satf else set())
    for rays in ((2,) if args.quick else (1, 2)) if "direct" in want else ():
        pr = prepare(_scene(args.scene, method="direct", rays=rays))
        ms, maps = frame_ms(pr)
        rows, _ = _rows(pr, pr.scene.view, pr.scene.lights)
        records.append({"method": "direct", "knobs": f"rays={rays}", "frame_ms": ms, "bake_s": 0.0, "bytes": 0,
                        **errors_of(maps, t_maps, rows, t_rows)})
        print(records[-1], flush=True)
    own = _scene(args.scene).config["render"]
    first = {k: own[k] for k in ("views", "terms", "shading_pixels", "precision")}
    for item in args.scene_knobs or ():
        key, _, value = item.partition("=")
        if key not in first:
            ap.error(f"--scene-knob {item!r}: the key must be one of {', '.join(first)}")
        first[key] = value if key == "precision" else int(value)
    knobs = [first] if "scene" in want else []
    if not (args.quick or args.default_only) and knobs:
        knobs += [dict(views=32, terms=4, shading_pixels=8, precision="float16"),
                  dict(views=128, terms=4, shading_pixels=8, precision="float16"),
                  dict(views=64, terms=2, shading_pixels=8, precision="float16"),
                  dict(views=64, terms=4, shading_pixels=1, precision="float16"),
                  dict(views=64, terms=4, shading_pixels=64, precision="float32")]
    with tempfile.TemporaryDirectory() as tmp:
        for k in knobs:
            sc = _scene(args.scene, method="scene", rays=2, **k)
            t0 = time.perf_counter()
            rep = registry.bake("scene_maps", scene_maps_recipe(sc), Path(tmp) / "maps.h5", scene=sc)
            bake_s = time.perf_counter() - t0
            pr = prepare(sc, maps=rep["out"])
            ms, maps = frame_ms(pr)
            rows, _ = _rows(pr, sc.view, sc.lights)
            records.append({"method": "scene", "knobs": ", ".join(f"{a}={b}" for a, b in k.items()), "frame_ms": ms,
                            "bake_s": bake_s, "bytes": rep["bytes"], **errors_of(maps, t_maps, rows, t_rows)})
            print(records[-1], flush=True)
        if "satf" in want:
            records += satf_rows(args, Path(tmp), t_maps, t_rows)
    print(f"\n## Map accuracy of {args.scene.name} against a converged truth ({truth_s:.1f} s to trace)\n")
    print(table(records, [("method", "method", "s"), ("knobs", "knobs", "s"), ("re_rel_l2", "re rel-L2", ".3f"),
                          ("alpha_rel_l2", "α rel-L2", ".3f"), ("coverage_rel_l2", "coverage rel-L2", ".3f"),
                          ("alpha_bias", "mean-α bias", "+.3f"), ("frame_ms", "maps ms", ".1f"),
                          ("bake_s", "bake s", ".1f"), ("bytes", "bytes", "d")]))
    payload = {"scene": str(args.scene), "truth_seconds": truth_s, "quick": args.quick, "records": records}
    emit(f"map_accuracy_{args.scene.stem}", payload, args.json)


if __name__ == "__main__":
    main()
