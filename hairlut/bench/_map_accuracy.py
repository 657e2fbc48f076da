"""The maps part's accuracy study: every map method's texel maps against a converged truth (issue 12).

The scene is prepared once per method through the public API (``hairlut.synth.prepare`` with ``[render] method``
set; the scene table baked through ``hairlut.bake.registry``, the SATF database through the planner's recipe).
**Truth** (:func:`map_truth`): every sector traced at its exact θv, θl by the direct kernel with the tracer's
shadow-grid lookup at 4 rays per pixel, 2× the density grid and 2× the steps, swept into texels by the same eq 7
(``sweep_sectors``, two sectors per HSV; satf eqs 6–7).  Per method and knob (:func:`map_accuracy_study`): texel
re and α rel-L2 (‖Δ‖/‖truth‖ over all texels and lights), per-sector coverage rel-L2 (each sector's pixel-mean α;
direct and scene, whose rows are per sector), the signed mean-α bias, the frame time of the maps (best of 3
after a warm-up, at the scene's size), the bake seconds and bytes.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import numpy as np

#: The scene table's knobs of the full run's extra scene rows (after the scene file's own).
SCENE_ROWS = (
    dict(views=32, terms=4, shading_pixels=8, precision="float16"),
    dict(views=128, terms=4, shading_pixels=8, precision="float16"),
    dict(views=64, terms=2, shading_pixels=8, precision="float16"),
    dict(views=64, terms=4, shading_pixels=1, precision="float16"),
    dict(views=64, terms=4, shading_pixels=64, precision="float32"),
)
MAP_KNOBS = ("views", "terms", "shading_pixels", "precision")


def map_scene(path: Path, hrir: dict | None = None, **render):
    """The scene file with ``render`` keys over its own and ``hrir`` ({section: {key: value}}) over its
    ``[tables.hrir]`` (the SATF database's recipe).  With ``method`` given, the file's own map knobs are
    dropped (the rows here give every knob their method reads; another method's would be refused)."""
    from hairlut.recipes import load_toml
    from hairlut.scene import resolve_scene

    path = Path(path)
    given = load_toml(path)
    if "method" in render:
        knobs = ("rays", *MAP_KNOBS)
        given = {**given, "render": {k: v for k, v in given.get("render", {}).items() if k not in knobs}}
    tables = dict(given.get("tables", {}))
    if hrir:
        own = tables.get("hrir", {})
        tables["hrir"] = {**own, **{k: {**own.get(k, {}), **v} for k, v in hrir.items()}}
    return resolve_scene(
        {**given, "tables": tables, "render": {**given.get("render", {}), **render}}, path.parent, source=str(path)
    )


def map_angles(prep, sc, view=None, lights=None):
    """Each sector's θv (S,), θl (S, L) and (cos θv, sin θv) (S, 2), as the frame computes them."""
    from hairlut.synth import params_kernel

    f32 = lambda x: np.asarray(x, np.float32)  # noqa: E731
    view, lights = sc.view if view is None else view, sc.lights if lights is None else lights
    tv, tl, cs, _, _ = params_kernel(prep.index, f32(view), f32(lights), f32(0.0), n_v=1, n_l=1)
    return tv, tl, cs


def _rows(prepared, view, lights):
    """Per-sector rows (α (S, P), re (S, L, P)) of a prepared direct/scene method."""
    from hairlut.march import direct_sector_maps
    from hairlut.scenemaps import fetch_kernel

    tv, tl, _ = map_angles(prepared, prepared.scene, view, lights)
    src = prepared.maps
    if src.method == "direct":
        return direct_sector_maps(src.density, src.geometry, np.asarray(tv, np.float64), np.asarray(tl, np.float64), src.recipe)
    a, r = fetch_kernel(*src.device, tv, tl)
    return np.asarray(a), np.asarray(r)


def map_truth(scene_path: Path, quick: bool, level: int = 1, cache: Path | None = None):
    """(direct-prepared scene, converged rows (α, re), texel maps (re, α), seconds to trace them) of the module
    docstring's truth.  ``level`` 1: 4 rays per pixel (2 when ``quick``), 2× grid, 2× steps; level 2 (one more
    refinement, to check the first is converged): 8 rays, 4× grid, 4× steps.  ``cache``: an .npz that keeps the
    traced truth for later runs (reused only when the scene file, the recipe and the refinement are the same)."""
    import jax.numpy as jnp

    from hairlut.march import direct_sector_maps, scene_sector_inputs
    from hairlut.planner import direct_recipe
    from hairlut.synth import prepare, sweep_sectors

    sc = map_scene(scene_path, method="direct", rays=1)
    prep = prepare(sc)
    rec = direct_recipe(sc)
    m = 2**level
    fine = {**rec, "sectors": {**rec["sectors"], "grid": [m * g for g in rec["sectors"]["grid"]]}}
    parts = [scene_sector_inputs(pc.table, fine, extent=pc.frames.extent) for pc in prep.clusters]
    dens, geom = np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    tv, tl, cs = map_angles(prep, sc)
    key = {
        "recipe": fine,
        "rays": 2 if quick else 2 * m,
        "steps": m * rec["trace"]["steps"],
        "groom": str(sc.groom_path),
        "scene": Path(scene_path).read_text(),
    }
    if cache is not None and Path(cache).exists():
        z = np.load(cache, allow_pickle=False)
        if str(z["key"]) == json.dumps(key, sort_keys=True, default=str):
            return prep, (z["a"], z["r"]), (z["re_t"], z["a_t"]), float(z["secs"])
    t0 = time.perf_counter()
    a, r = direct_sector_maps(
        dens,
        geom,
        np.asarray(tv, np.float64),
        np.asarray(tl, np.float64),
        fine,
        rays=2 if quick else 2 * m,
        n_steps=m * rec["trace"]["steps"],
        shadow_lookup="grid",
    )
    secs = time.perf_counter() - t0
    re_t, a_t = (np.asarray(x) for x in sweep_sectors(prep.index, jnp.asarray(a), jnp.asarray(r), cs))
    if cache is not None:
        cache = Path(cache)
        cache.parent.mkdir(parents=True, exist_ok=True)
        with open(cache.with_suffix(".tmp.npz"), "wb") as f:
            np.savez(f, a=a, r=r, re_t=re_t, a_t=a_t, secs=secs, key=json.dumps(key, sort_keys=True, default=str))
        cache.with_suffix(".tmp.npz").replace(cache)
    return prep, (a, r), (re_t, a_t), secs


def _rel(x, ref) -> float:
    return float(np.linalg.norm(np.asarray(x) - ref) / max(np.linalg.norm(ref), 1e-30))


def map_errors(maps, t_maps, rows=None, t_rows=None) -> dict:
    """Texel re and α rel-L2, the signed mean-α bias of ``maps`` (re, α) against ``t_maps``, and, given per-sector
    ``rows`` (α, …) and ``t_rows``, the coverage rel-L2 of each sector's pixel-mean α (else None)."""
    (re, a), (re_t, a_t) = maps, t_maps
    out = {
        "re_rel_l2": _rel(re, re_t),
        "alpha_rel_l2": _rel(a, a_t),
        "alpha_bias": float((np.mean(a) - np.mean(a_t)) / np.mean(a_t)),
        "coverage_rel_l2": None,
    }
    if rows is not None:
        out["coverage_rel_l2"] = _rel(rows[0].mean(-1), t_rows[0].mean(-1))
    return out


def maps_frame_ms(prepared) -> tuple[float, tuple]:
    """(best of 3 warm maps-stage times in ms, the frame's texel maps (re, α)) of a prepared scene."""
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


def _satf_rows(scene: Path, tmp: Path, t_maps, t_rows, features, views_list, ks, count, say) -> list[dict]:
    """The SATF lookup per feature set, view grid and k: one database bake per view grid (the planner's recipe,
    timed, ``count`` records over the planner's when given); the other feature sets index the same records
    (``hairlut.hrir.reindex``: the file their own bake would write; bake seconds = the bake's plus the re-index's);
    per k the frame's maps and each sector's own looked-up row at its exact angles (the coverage column)."""
    from hairlut.bake import registry
    from hairlut.hrir import reindex
    from hairlut.planner import plan
    from hairlut.synth import prepare

    out = []
    for views in views_list:
        hrir = {"sectors": {"features": "basic"}, "angles": {"views": views}}
        if count:
            hrir["sectors"]["count"] = count
        sc = map_scene(scene, hrir, method="satf")
        p = plan(sc, tmp / "cache")
        step = p.step("hrir_db")
        t0 = time.perf_counter()
        base, _ = registry.ensure("hrir_db", step.recipe, p.cache_dir)
        base_s = time.perf_counter() - t0
        for feats in features:
            t0 = time.perf_counter()
            path = base if feats == "basic" else reindex(base, tmp / f"hrir-{feats}-{views}.h5", feats)
            bake_s = base_s + time.perf_counter() - t0
            for k in ks:
                pr = prepare(map_scene(scene, hrir, method="satf", neighbours=k), str(path))
                ms, maps = maps_frame_ms(pr)
                tv, tl, _ = map_angles(pr, pr.scene)
                _, a, _, _ = pr.db.query(pr.frames.features, np.asarray(tv), np.asarray(tl)[:, 0], k=k)
                rows = (a * pr.frames.occupied[:, None],)
                out.append(
                    {
                        "method": "satf",
                        "features": feats,
                        "views": views,
                        "k": k,
                        "knobs": f"{feats}, {step.recipe['sectors']['count']} records, {views} views, k={k}",
                        "frame_ms": ms,
                        "bake_s": bake_s,
                        "bytes": Path(path).stat().st_size,
                        "prepare_s": sum(pr.seconds.values()),
                        **map_errors(maps, t_maps, rows, t_rows),
                    }
                )
                say(f"maps: satf {out[-1]['knobs']}: re rel-L2 {out[-1]['re_rel_l2']:.3f}")
    return out


def map_accuracy_study(
    scene,
    quick: bool = False,
    *,
    methods=("direct", "scene", "satf"),
    first_knobs=None,
    default_only: bool = False,
    satf_features=("basic",),
    satf_views=(32,),
    satf_k=(4,),
    satf_count: int | None = None,
    truth_cache: Path | None = None,
    progress=None,
) -> dict:
    """Every map method of ``methods`` on ``scene`` against :func:`map_truth` (module docstring): ``direct`` at
    1 and 2 rays per pixel (2 only when ``quick``); ``scene`` at the file's own knobs (``first_knobs`` over them)
    and, unless ``quick`` or ``default_only``, the :data:`SCENE_ROWS`; ``satf`` per feature set, view grid and k.
    Returns ``{"scene", "truth_seconds", "quick", "records"}``; each record has ``method``, ``knobs`` (text),
    ``re_rel_l2``, ``alpha_rel_l2``, ``coverage_rel_l2``, ``alpha_bias``, ``frame_ms``, ``bake_s`` and ``bytes``."""
    from hairlut.bake import registry
    from hairlut.planner import scene_maps_recipe, scene_table_layout
    from hairlut.synth import prepare

    say = progress or (lambda message: None)
    scene = Path(scene)
    _, t_rows, t_maps, truth_s = map_truth(scene, quick, cache=truth_cache)
    say(f"maps: truth of {scene.name} traced in {truth_s:.1f} s")
    records = []
    for rays in ((2,) if quick else (1, 2)) if "direct" in methods else ():
        pr = prepare(map_scene(scene, method="direct", rays=rays))
        ms, maps = maps_frame_ms(pr)
        rows = _rows(pr, pr.scene.view, pr.scene.lights)
        records.append(
            {
                "method": "direct",
                "knobs": f"rays={rays}",
                "frame_ms": ms,
                "bake_s": 0.0,
                "bytes": 0,
                **map_errors(maps, t_maps, rows, t_rows),
            }
        )
        say(f"maps: direct rays={rays}: re rel-L2 {records[-1]['re_rel_l2']:.3f}")
    own = map_scene(scene).config["render"]
    layout = {c.key.removeprefix("render."): c.value for c in scene_table_layout(map_scene(scene, method="scene"))}
    first = {**{k: layout.get(k, own[k]) for k in MAP_KNOBS}, **(first_knobs or {})}
    knobs = [first] if "scene" in methods else []
    if not (quick or default_only) and knobs:
        knobs += [dict(k) for k in SCENE_ROWS]
    with tempfile.TemporaryDirectory(prefix="hairlut-maps-") as tmp:
        for k in knobs:
            sc = map_scene(scene, method="scene", rays=2, **k)
            t0 = time.perf_counter()
            rep = registry.bake("scene_maps", scene_maps_recipe(sc), Path(tmp) / "maps.h5", scene=sc)
            bake_s = time.perf_counter() - t0
            pr = prepare(sc, maps=rep["out"])
            ms, maps = maps_frame_ms(pr)
            rows = _rows(pr, sc.view, sc.lights)
            records.append(
                {
                    "method": "scene",
                    "knobs": ", ".join(f"{a}={b}" for a, b in k.items()),
                    "frame_ms": ms,
                    "bake_s": bake_s,
                    "bytes": rep["bytes"],
                    **map_errors(maps, t_maps, rows, t_rows),
                }
            )
            say(f"maps: scene {records[-1]['knobs']}: re rel-L2 {records[-1]['re_rel_l2']:.3f}")
        if "satf" in methods:
            records += _satf_rows(scene, Path(tmp), t_maps, t_rows, satf_features, satf_views, satf_k, satf_count, say)
    return {"scene": scene.name, "truth_seconds": truth_s, "quick": quick, "records": records}
