"""Online frame time (satf §6, Table 1): index, maps, lighting, shadow and blend of a whole model.

Builds procedural clusters around a head-sized ring (default: the paper's human model,
17 clusters × 3 layers, s_t = 64, s_u = 16: 52K HSVs), prepares the scene once (strands,
sectors, features, texel frames and the SATF neighbours: the view-independent index), then
times a frame after jit warm-up with ``hairlut.synth.render_view`` and with a plain NumPy
implementation of the same steps (eq 7 sweep, eqs 8–11 lighting, eqs 12–14) through the
reference lookup (``_maps.fetch``: a k-NN search per query; every sector is fetched, not only
those of non-uniform HSVs).  ``render_view``'s stages: "maps" (eq 6, the SATF fetches and the eq 7
sweep: three kernels) and "shade" (lighting, s-map, shading and blend: one kernel).
Then the shadow seam: the same frame for each ``[shadows] method`` (smap, light_oriented,
opacity_maps, none); the light-space maps are built once in ``prepare`` for the scene's
lights ("shadow build") and re-used each frame, and a frame with new lights rebuilds them
("relit frame").  Public API only.
Prints tables (best and median of the timed runs) and writes benchmarks/results/online_frame.json.

Usage: python benchmarks/online_frame.py [--db hrir.h5] [--clusters 17] [--quick]
       python benchmarks/online_frame.py --map-methods [--methods scene] [--reads pair track]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import save, table  # noqa: E402

from dataclasses import replace  # noqa: E402

from hairlut.scene import SHADOW_METHODS, resolve_scene, scene_clusters  # noqa: E402
from hairlut.synth import fetch, param_distance, prepare, prepare_shadows, render_view, sector_angles, texels, wrap  # noqa: E402


def model(n_clusters: int, s_t: int, s_u: int, res: int, strands: int, shadows: str = "smap") -> dict:
    clusters = []
    for c in range(n_clusters):
        a = 2 * np.pi * c / n_clusters
        root = [0.1 * np.cos(a), 0.1, 0.1 * np.sin(a)]
        mid = [0.13 * np.cos(a), -0.05, 0.13 * np.sin(a)]
        tip = [0.12 * np.cos(a + 0.2), -0.25, 0.12 * np.sin(a + 0.2)]
        clusters.append({"trajectory": [root, mid, tip], "half_axis_a": 0.02, "half_axis_b": 0.012,
                         "twist": [0.0, 0.5], "s_t": s_t, "s_u": s_u})
    return {"render": {"resolution": [res, res]}, "camera": {"view": [0.0, 0.3, 1.0]},
            "lights": {"directions": [[0.5, 0.8, 1.0]]}, "effects": {"noise": True},
            "strands": {"count": strands, "radius": 0.0015, "profile": "clumped", "spread": 0.25},
            "shadows": {"method": shadows}, "clusters": clusters}


def _sample(arr, pix):
    P = arr.shape[-1]
    f = np.clip(pix, 0.0, P - 1.0)
    i0 = np.clip(np.floor(f).astype(np.int64), 0, max(P - 2, 0))
    i1 = np.minimum(i0 + 1, P - 1)
    extra = arr.ndim - f.ndim  # trailing axes: (..., P) or (..., L, P)
    w = (f - i0).reshape(f.shape + (1,) * (extra - 1))
    g0 = np.take_along_axis(arr, i0.reshape(f.shape + (1,) * extra), -1)[..., 0]
    g1 = np.take_along_axis(arr, i1.reshape(f.shape + (1,) * extra), -1)[..., 0]
    return g0 + w * (g1 - g0)


def _sin(c):
    return np.sqrt(np.clip(1 - c * c, 0, 1))


def numpy_frame(prep) -> list[np.ndarray]:
    """The same frame in plain NumPy: maps (eqs 6–7), lighting (8–11), s-map, shading, blend (12–14)."""
    sc, db = prep.scene, prep.db
    m, fx = sc.material, sc.effects
    kd, ks1, ks2, p1, p2, s = (m[k] for k in ("kd", "ks_I", "ks_II", "p_I", "p_II", "shift"))
    scale, bias, amount = m["diffuse_scale"], m["diffuse_bias"], m["noise_amount"]
    hair = np.asarray(m["hair_color"])
    colours = [hair, np.asarray(m["spec_color_I"]), np.asarray(m["spec_color_II"]) * (hair if m["secondary_hair_tint"] else 1)]
    n_u, n_t = sc.config["render"]["resolution"]
    out = []
    for pc in prep.clusters:
        sp = sector_angles(pc.frames, sc.view, sc.lights)
        tx = texels(pc.table, sp, pc.spec.n_layers, (n_u, n_t), db.alpha.shape[-1])
        top, bot = pc.table.hsv_sectors[:, 0], pc.table.hsv_sectors[:, 1]
        d = param_distance(db, sp.features[top], sp.theta_v[top], sp.theta_l[top], sp.features[bot],
                           sp.theta_v[bot], sp.theta_l[bot])
        uni = d < m["k_threshold"]
        k = sc.config["render"]["neighbours"]
        re_s, a_s = fetch(db, sp.features, sp.theta_v, sp.theta_l, k)
        f = 0.5 * (sp.features[top] + sp.features[bot])
        tv = sp.theta_v[top] + 0.5 * wrap(sp.theta_v[bot] - sp.theta_v[top])
        tl = sp.theta_l[top] + 0.5 * wrap(sp.theta_l[bot] - sp.theta_l[top])
        re_u, a_u = fetch(db, f[uni], tv[uni], tl[uni], k)
        re1, re2, a1, a2 = re_s[top], re_s[bot], a_s[top], a_s[bot]
        re1[uni], re2[uni], a1[uni], a2[uni] = re_u, re_u, a_u, a_u
        h, g = tx.hsv, tx.gamma
        u = uni[h]
        x1, x2 = np.where(u, tx.pix_ave, tx.pix_top), np.where(u, tx.pix_ave, tx.pix_bot)
        re = (1 - g)[..., None] * _sample(re1[h], x1) + g[..., None] * _sample(re2[h], x2)  # (C, K, t, u, L)
        al = np.clip((1 - g) * _sample(a1[h], x1) + g * _sample(a2[h], x2), 0, 1)[0]
        t, n, v, ls = pc.tangent, pc.normal, sc.view, sc.lights
        cl = t @ ls.T
        light = np.zeros(t.shape[:-1] + (len(ls), 3))
        if fx["diffuse"]:
            light += kd * np.maximum(0, scale * _sin(cl) + bias)[..., None] * colours[0]
        for on, sh, p, ks, col, noisy in ((fx["primary"], s, p1, ks1, colours[1], False),
                                         (fx["secondary"], -s, p2, ks2, colours[2], fx["noise"])):
            if on:
                tt = t + sh * n
                tt /= np.linalg.norm(tt, axis=-1, keepdims=True)
                c1, c2 = tt @ ls.T, (tt @ v)[..., None]
                term = ks * np.maximum(0, _sin(c1) * _sin(c2) - c1 * c2) ** p
                if noisy:
                    term = term * (1 - amount * pc.noise)[..., None]
                light += term[..., None] * col
        light *= sc.light_colors
        outer = np.cumsum(al[::-1], 0)[::-1] - al
        tau = np.exp(-m["k_shadow"] * outer) if fx["shadow"] else np.ones_like(al)
        rgb = tau[..., None] * np.sum(light * re[0][..., None], axis=-2)
        keep = 1 - al
        above = np.concatenate([np.cumprod(keep[::-1], 0)[::-1][1:], np.ones_like(keep[:1])])
        final = np.asarray(sc.config["render"]["background"]) * np.prod(keep, 0)[..., None] + \
            np.sum(rgb * (al * above)[..., None], 0)
        out.append(final)
    return out


def shadow_methods(prep, args, runs: int = 10) -> list[dict]:
    """Frame time per shadow method on the prepared model: its maps built once for the scene's
    lights (as ``prepare`` does), then ``runs`` frames, then one frame under a new light."""
    strands = [s for _, s in scene_clusters(prep.scene)]
    points = np.stack([pc.position for pc in prep.clusters])
    rows = []
    for method in SHADOW_METHODS:
        sc = resolve_scene(model(args.clusters, args.s_t, args.s_u, args.res, args.strands, method))
        build = {}
        variant = replace(prep, scene=sc, shadows=prepare_shadows(sc, strands, points, build))
        render_view(variant)  # warm-up: compiles
        frames = [timed(lambda: render_view(variant)) for _ in range(runs)]
        sec = np.array([t for t, _ in frames])
        best = frames[int(np.argmin(sec))][1]
        render_view(variant, lights=[[0.4, 0.9, -0.5]])  # a first relight compiles what a new map size needs
        relit, _ = timed(lambda: render_view(variant, lights=[[-0.4, 0.9, 0.5]]))
        render_view(variant)  # back to the scene's lights (rebuilds the maps outside the timings)
        rows.append({"method": method, "build_s": build.get("shadows", 0.0), "ms": 1e3 * sec.min(),
                     "median": 1e3 * float(np.median(sec)), "shade": 1e3 * best.stats["seconds"]["shade"],
                     "relit_s": relit})
    return rows


def map_methods(args, runs: int = 10) -> list[dict]:
    """Frame time per ``[render] method`` on the model (issue 12), best of ``runs`` frames (2 for
    ``direct``), wall and CPU time: ``direct`` traces every sector each frame; ``scene`` fetches from a
    scene table of the model's real shape (its live sectors, the default layout or ``--shading-pixels``
    bins) whose *contents* are synthetic (a paper-scale bake takes hours on this CPU: the fetch's cost
    does not depend on the values); bytes are the kind's uncompressed estimate."""
    from hairlut.planner import scene_maps_recipe
    from hairlut.scenemaps import BAKER, SceneMaps

    from hairlut.geometry import ClusterGeometry, build_sectors

    base = model(args.clusters, args.s_t, args.s_u, args.res, args.strands)
    rows, live = [], None
    knobs = {"shading_pixels": args.shading_pixels} if args.shading_pixels else {}
    for method, reads in ((m, r) for m in args.methods for r in args.reads):
        sc = resolve_scene({**base, "render": {**base["render"], "method": method, "layer_reads": reads,
                                               **(knobs if method == "scene" else {})}})
        maps = None
        if method == "scene":
            recipe = scene_maps_recipe(sc)
            t, P = recipe["table"], recipe["hrir"]["trace"]["pixels"]
            rng = np.random.default_rng(0)
            if live is None:  # direct not run: every sector live (an upper bound of the fetch's work)
                live = np.ones(sum(build_sectors(ClusterGeometry(spec), st, np.zeros(st.n_strands, np.int64)).n_sectors
                                   for spec, st in scene_clusters(sc)), bool)
            n = int(live.sum())
            row = np.full(live.size, -1, np.int32)
            row[live] = np.arange(n, dtype=np.int32)
            maps = SceneMaps(rng.random((n, t["views"] // 2, P)).astype(t["dtype"]),
                             (0.1 * rng.random((n, t["views"] // t["ratio_step"], t["shading_pixels"],
                                               2 * t["terms"] + 1))).astype(t["dtype"]),
                             row, recipe)
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
            stage = [cpu_timed(lambda: jax.block_until_ready(prep.maps.view(prep.index, view, lights)[:2]))[1]
                    for _ in range(runs)]
            extra["maps_cpu"] = 1e3 * min(stage)
            nbytes, secs = BAKER.estimate(recipe, sectors=live.size, live=int(live.sum()))
            extra.update(table_bytes_estimate=nbytes, bake_s_estimate=secs)
        rows.append({"method": method, "reads": reads, "sectors": int(live.size), "live": int(live.sum()),
                     "prepare_s": t_prep, "ms": 1e3 * sec.min(), "cpu_ms": 1e3 * cpu.min(),
                     "maps": 1e3 * best.stats["seconds"]["maps"], **extra})
        print(rows[-1], flush=True)
    return rows


def cpu_timed(fn):
    """(wall s, process CPU s, result) of fn(): CPU time counts every thread, the measure on a shared machine."""
    c0, w0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.perf_counter() - w0, time.process_time() - c0, out


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def _small_db(folder: Path, quick: bool) -> Path:
    from hairlut.hrir import bake

    out = folder / "db.h5"
    n = 64 if quick else 256
    bake({"sectors": {"count": n, "grid": [16, 16]}, "angles": {"views": 16, "lights": 16},
          "trace": {"pixels": 32, "steps": 32, "self_shadow": False}}, out)
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", help="hrir_db file (default: bake a small one in a temporary folder)")
    ap.add_argument("--clusters", type=int, default=17)
    ap.add_argument("--s-t", type=int, default=64)
    ap.add_argument("--s-u", type=int, default=16)
    ap.add_argument("--res", type=int, default=64, help="texels per layer side")
    ap.add_argument("--strands", type=int, default=400, help="strands per cluster")
    ap.add_argument("--quick", action="store_true", help="2 clusters, s_t = 16 (a smoke run)")
    ap.add_argument("--map-methods", action="store_true",
                    help="only the frame time per [render] method (direct, scene) on the model")
    ap.add_argument("--methods", nargs="+", default=["direct", "scene"], choices=["direct", "scene"],
                    help="with --map-methods: which (scene alone counts every sector live)")
    ap.add_argument("--reads", nargs="+", default=["pair"], choices=["pair", "track"],
                    help="with --map-methods: [render] layer_reads, each timed in the same run")
    ap.add_argument("--shading-pixels", type=int, default=0,
                    help="with --map-methods: the scene table's re/α pixel bins (default: the scene default)")
    args = ap.parse_args(argv)
    if args.quick:
        args.clusters, args.s_t, args.res, args.strands = 2, 16, 32, 100
    if args.map_methods:
        rows = map_methods(args)
        print(table(rows, [("method", "[render] method", "s"), ("reads", "layer_reads", "s"), ("sectors", "sectors", "d"),
                           ("live", "live", "d"),
                           ("prepare_s", "prepare s", ".1f"), ("ms", "frame ms", ".1f"), ("cpu_ms", "frame CPU ms", ".1f"),
                           ("maps", "maps ms", ".1f"), ("maps_cpu", "maps CPU ms", ".1f")]))
        print("(best of the timed frames; CPU ms: process CPU time, every thread; maps CPU ms: the maps stage alone)")
        save("online_frame_map_methods", {"device": str(jax.devices()[0]), "args": vars(args), "rows": rows})
        return
    with tempfile.TemporaryDirectory() as tmp:
        db_path = Path(args.db) if args.db else _small_db(Path(tmp), args.quick)
        from hairlut.hrir import load_hrir_db

        db = load_hrir_db(db_path)
        sc = resolve_scene(model(args.clusters, args.s_t, args.s_u, args.res, args.strands))
        t0 = time.perf_counter()
        prep = prepare(sc, db)
        t_prep = time.perf_counter() - t0
    render_view(prep)  # warm-up: compiles
    jax_runs = []
    for _ in range(20):
        sec, res = timed(lambda: render_view(prep))
        jax_runs.append((sec, {k: v for k, v in res.stats["seconds"].items() if k not in ("strands", "index")}))
    numpy_frame(prep)
    np_runs = []
    for _ in range(3):
        sec, ref = timed(lambda: numpy_frame(prep))
        np_runs.append((sec, {}))
    err = max(float(np.abs(c.final[..., :3] - r).max()) for c, r in zip(res.clusters, ref))
    rows = []
    for name, runs in (("hairlut.synth.render_view (JAX)", jax_runs), ("NumPy", np_runs)):
        sec = np.array([t for t, _ in runs])
        rows.append({"impl": name, "runs": len(runs), "ms": 1e3 * sec.min(), "median": 1e3 * float(np.median(sec)),
                     **{k: 1e3 * v for k, v in runs[int(np.argmin(sec))][1].items()}})
    t_jax, t_np = rows[0]["ms"] / 1e3, rows[1]["ms"] / 1e3
    print(f"model: {res.stats['clusters']} clusters, {res.stats['layers']} layers, {res.stats['hsvs']} HSVs, "
          f"{args.res}x{args.res} texels per layer; DB {len(db.features)} sectors; prepare {t_prep:.1f} s "
          f"(strands {res.stats['seconds']['strands']:.1f} s, index {res.stats['seconds']['index']:.1f} s)")
    print(table(rows, [("impl", "frame", "s"), ("runs", "runs", "d"), ("ms", "best ms", ".1f"),
                       ("median", "median ms", ".1f"), ("maps", "maps ms", ".1f"),
                       ("shade", "lighting+shadow+blend ms", ".1f")]))
    print("(stage times are those of the best run)")
    print(f"max |JAX − NumPy| of the composite: {err:.2e}")
    shadow_rows = shadow_methods(prep, args)
    print(table(shadow_rows, [("method", "[shadows] method", "s"), ("build_s", "shadow build s", ".2f"),
                              ("ms", "best ms", ".1f"), ("median", "median ms", ".1f"), ("shade", "shade ms", ".1f"),
                              ("relit_s", "relit frame s", ".2f")]))
    print("(shadow build: the light-space maps for the scene's light, once per scene in prepare; relit frame: "
          "a frame under a new light, which rebuilds them)")
    path = save("online_frame", {"device": str(jax.devices()[0]), "args": vars(args), "stats": res.stats,
                                 "prepare_s": t_prep, "frame_ms": {"jax": 1e3 * t_jax, "numpy": 1e3 * t_np},
                                 "median_ms": {"jax": rows[0]["median"], "numpy": rows[1]["median"]},
                                 "max_abs_diff": err, "shadow_methods": shadow_rows})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
