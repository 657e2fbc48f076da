"""SATF lookup accuracy: lookups against directly traced HRIRs of held-out sectors.

    python -m benchmarks.satf_accuracy [--quick] [--sections 123] [--db hrir_db.h5]

1. Databases of N random sectors (two feature sets: the paper's (ρ_st, ρ_s, ρ_t) and
   the richer "moments" set) are queried with the features of held-out sectors
   (another seed, never in any database) at grid angles, so only the feature
   lookup is measured; the truth is those sectors traced directly with the same
   tracer.  Error: RMS of re and α over pixels, relative ‖Δ‖/‖truth‖, and the
   relative error of each sector's pixel-mean α (its coverage).
2. The paper's uniformity shortcut (eq 6, k_threshold = 1) against always
   fetching two HRIRs (k_threshold = 0), and always one (∞), on the procedural
   example scene: re-map error against k_threshold = 0 and frame time.
3. The whole synthesised re-/α-map of a `.tfx` scene (tables/scenes/sintel-groom.toml)
   against directly traced sectors.  The scene is prepared by ``hairlut.synth.prepare``
   and its maps built by ``build_maps`` (SATF: feature kNN + angle-grid interpolation,
   the scene's k, k_threshold 0 and 1).  The truth traces every sector of the scene's own
   clusters with the bake's tracer (``trace_sectors``, the database's trace and Phong
   settings, density grid and pixel count) at that sector's exact θv and θl
   (``sector_angles``), its image line spanning the same extent R the texels read
   (``SectorFrames.extent``), and patches those HRIRs with the same per-texel sweep
   (``texels`` + ``sweep_kernel``, eq 7, two HRIRs per HSV).  So the k_threshold = 0 row
   differs from the truth only in SATF lookup vs direct tracing; the k_threshold = 1 row
   adds the eq 6 shortcut (an averaged sector has no geometry to trace, so the truth is
   always the two-HRIR sweep).  Errors over all texels (and lights): RMS, max |Δ|,
   ‖Δ‖/‖truth‖ of re and α, and the signed relative error of the mean α (coverage).
   NN dist (z): the median distance of a scene sector's features to the nearest record,
   in the database's standard deviations (how well its feature set covers the scene).
   Databases: ones whose sector space the planner fits to the scene (``scene_space``; two sizes,
   both feature sets) and section 1's generic one; or the file given by ``--db``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from hairlut.hrir import HRIRDB, bake

from ._common import RESULTS, best_of, save, table

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "tables" / "scenes" / "sintel-groom.toml"
TRACE = {"angles": {"views": 16, "lights": 16}, "trace": {"pixels": 32, "steps": 48}}


# sintel-groom's sectors: ≤ 9 strands, strand radius 0.04–0.12 √area, B/A 0.17–0.23 or its
# inverse (the same shapes, turned), three tracks of a quarter of the radius, s_u = 8
def scene_space() -> dict:
    """The sector space the planner fits to the scene's own sectors (``hairlut.plan.restricted_space``)."""
    from hairlut.hrir import resolve_recipe
    from hairlut.scene import load_scene, restricted_space, scene_sectors

    return restricted_space(scene_sectors(load_scene(SCENE)), resolve_recipe({})["sectors"]["space"])


def recipe(count, seed, features, space=None):
    return {"sectors": {"count": count, "seed": seed, "features": features, **({"space": space} if space else {})}, **TRACE}


def lookup_rows(tmp: Path, sizes, n_test: int):
    rows = []
    rng = np.random.default_rng(1)
    for features in ("basic", "moments"):
        bake(recipe(n_test, 987_654, features), tmp / f"test-{features}.h5")
        truth = HRIRDB.load(tmp / f"test-{features}.h5")
        v = rng.integers(0, 16, n_test)
        l = rng.integers(0, 16, n_test)
        ref_re = truth.reflectance[np.arange(n_test), v, l]
        ref_a = truth.alpha[np.arange(n_test), v]
        for n in sizes:
            path = tmp / f"db-{features}-{n}.h5"
            start = time.perf_counter()
            bake(recipe(n, 0, features), path)
            bake_s = time.perf_counter() - start
            db = HRIRDB.load(path)
            for k in (1, 4):
                re, a, _, _ = db.query(truth.features, truth.theta_v[v], truth.theta_l[l], k=k)
                sec, _ = best_of(lambda: db.query(truth.features, truth.theta_v[v], truth.theta_l[l], k=k), repeat=3)
                rows.append(
                    {
                        "features": features,
                        "n": n,
                        "k": k,
                        "bake_s": bake_s,
                        "query_ms": sec * 1e3,
                        "re_rms": float(np.sqrt(np.mean((re - ref_re) ** 2))),
                        "re_rel": float(np.linalg.norm(re - ref_re) / np.linalg.norm(ref_re)),
                        "a_rms": float(np.sqrt(np.mean((a - ref_a) ** 2))),
                        "a_rel": float(np.linalg.norm(a - ref_a) / np.linalg.norm(ref_a)),
                        # coverage level: each sector's pixel-mean opacity, which the features summarise
                        "a_mean_rel": float(np.linalg.norm(a.mean(-1) - ref_a.mean(-1)) / np.linalg.norm(ref_a.mean(-1))),
                    }
                )
    return rows


def uniformity_rows(db_path: Path):
    from hairlut.recipes import load_toml
    from hairlut.scene import resolve_scene
    from hairlut.synth import prepare, render_view

    scene_file = ROOT / "tables" / "scenes" / "two-clusters.toml"
    base = load_toml(scene_file)
    results = {}
    for name, thr in (
        ("always two fetches (k_threshold = 0)", 0.0),
        ("eq 6 shortcut (k_threshold = 1)", 1.0),
        ("always one fetch (k_threshold = ∞)", float("inf")),
    ):
        given = {**base, "material": {**base.get("material", {}), "k_threshold": thr}}
        prepared = prepare(resolve_scene(given, scene_file.parent, source=str(scene_file)), str(db_path))
        render_view(prepared)
        sec, res = best_of(lambda: render_view(prepared), repeat=3)
        results[name] = (sec, res)
    ref = results["always two fetches (k_threshold = 0)"][1]
    rows = []
    for name, (sec, res) in results.items():
        d = np.concatenate([(c.re - r.re).ravel() for c, r in zip(res.clusters, ref.clusters)])
        uni = float(np.mean([c.uniform_fraction for c in res.clusters]))
        rows.append(
            {
                "mode": name,
                "ms": sec * 1e3,
                "uniform": uni,
                "re_rms": float(np.sqrt(np.mean(d**2))),
                "re_max": float(np.abs(d).max()),
            }
        )
    return rows


def _scene_truth(prepared, db):
    """Directly traced (α (N, P), re (N, Lt, P)) of every sector of ``prepared`` at its own θv, θl,
    with ``db``'s density grid, trace and Phong settings; the seconds; the number traced (empty
    sectors are exactly 0 and skipped)."""
    from hairlut.geometry.density import sector_density
    from hairlut.hrir import trace_sectors
    from hairlut.march import GEOM, sector_geometry
    from hairlut.synth import sector_angles

    rec = db.recipe
    start = time.perf_counter()
    sp = sector_angles(prepared.frames, prepared.scene.view, prepared.scene.lights)
    dens, geom = [], []
    for pc in prepared.clusters:
        tb = pc.table
        splats = tb.splats()
        dens.append(sector_density(splats, tuple(rec["sectors"]["grid"]), density_scale=rec["sectors"]["density_scale"]))
        (a, b), du = tb.half_axes.T, tb.u_range[:, 1] - tb.u_range[:, 0]
        m = splats.mask
        r = np.where(m.any(1), (splats.radius * m).sum(1) / np.maximum(m.sum(1), 1), np.median(tb.crossing_radius))
        # metric (A x, B y) ellipse scaled by 1/A: the tracer's (1, B/A) ellipse, same angles
        params = {
            "phase": tb.twist + tb.u_range[:, 0],
            "s_u": 2 * np.pi / du,
            "v_range": tb.v_range,
            "aspect": b / a,
            "radius_rel": r / np.sqrt(splats.sector_areas()),
        }
        g = sector_geometry(
            params, kappa=rec["trace"]["extinction"], n_pix=rec["trace"]["pixels"], smooth_ratio=rec["trace"]["smooth_ratio"]
        )
        ext = pc.frames.extent / a  # the extent the texels' pixel coordinates use
        g[:, GEOM.index("sigma_px")] *= g[:, GEOM.index("extent")] / ext
        g[:, GEOM.index("extent")] = ext
        geom.append(g)
    dens, geom = np.concatenate(dens), np.concatenate(geom)
    N, Lt, P = len(dens), sp.theta_l.shape[1], rec["trace"]["pixels"]
    alpha, re = np.zeros((N, P), np.float32), np.zeros((N, Lt, P), np.float32)
    live = np.flatnonzero(dens.reshape(N, -1).max(1) > 0)
    for i in live:
        a, r = trace_sectors(dens[i : i + 1], geom[i : i + 1], rec, views=sp.theta_v[i : i + 1], lights=sp.theta_l[i])
        alpha[i], re[i] = a[0, 0], r[0, 0]
    return alpha, re, time.perf_counter() - start, live.size


def _truth_maps(prepared, sp, tx, alpha, re):
    """re (C, K, Lt, n_t, n_u) and α (C, K, n_t, n_u) of traced sector HRIRs by eq 7 (two per HSV)."""
    import jax.numpy as jnp

    from hairlut.synth import sweep_kernel

    top, bot = prepared.table.hsv_sectors.T
    args = (re[top], re[bot], alpha[top], alpha[bot], tx.hsv.ravel(), tx.gamma.ravel(), tx.pix_top.ravel(), tx.pix_bot.ravel())
    r, a = sweep_kernel(*(jnp.asarray(x, jnp.int32 if x.dtype.kind == "i" else jnp.float32) for x in args))
    return np.moveaxis(np.asarray(r).reshape(tx.hsv.shape + (-1,)), -1, 2), np.asarray(a).reshape(tx.hsv.shape)


def _map_errors(re, a, re_t, a_t) -> dict:
    dr, da = re - re_t, a - a_t
    return {
        "re_rms": float(np.sqrt(np.mean(dr**2))),
        "re_max": float(np.abs(dr).max()),
        "re_rel": float(np.linalg.norm(dr) / np.linalg.norm(re_t)),
        "a_rms": float(np.sqrt(np.mean(da**2))),
        "a_max": float(np.abs(da).max()),
        "a_rel": float(np.linalg.norm(da) / np.linalg.norm(a_t)),
        "a_mean_rel": float((a.mean() - a_t.mean()) / a_t.mean()),
    }


def scene_rows(dbs):
    """Section 3 for each (label, path) of ``dbs``; see the module docstring."""
    from hairlut.assets import canonical_json
    from hairlut.scene import load_scene
    from hairlut.synth import build_maps, prepare, sector_angles, texels

    scene = load_scene(SCENE)
    rows, prepared, truths = [], {}, {}
    for label, path in dbs:
        db = HRIRDB.load(path)
        rec = db.recipe
        key = (tuple(db.stats.names), tuple(rec["sectors"]["grid"]), rec["sectors"]["density_scale"])
        if key not in prepared:  # the scene's sectors and features depend on the feature set and grid only
            prepared[key] = prepare(scene, db)
        pr = prepared[key]
        tkey = canonical_json({k: rec[k] for k in ("trace", "phong")}) + repr(key[1:])
        if tkey not in truths:
            truths[tkey] = _scene_truth(pr, db)
        alpha, re, trace_s, traced = truths[tkey]
        cfg = pr.scene.config["render"]
        sp = sector_angles(pr.frames, pr.scene.view, pr.scene.lights)
        tx = texels(pr.table, sp, pr.clusters[0].spec.n_layers, cfg["resolution"], db.alpha.shape[-1])
        re_t, a_t = _truth_maps(pr, sp, tx, alpha, re)
        std = np.where(db.stats.std > 0, db.stats.std, 1.0)
        z, zdb = (sp.features - db.stats.mean) / std, (db.features - db.stats.mean) / std
        nn = np.sqrt(((z[:, None] - zdb[None]) ** 2).sum(-1)).min(1)
        for thr in (0.0, 1.0):
            build_maps(db, pr.table, sp, tx, thr, cfg["neighbours"])  # compile
            sec, maps = best_of(lambda: build_maps(db, pr.table, sp, tx, thr, cfg["neighbours"]), repeat=3)
            rows.append(
                {
                    "db": label,
                    "n": len(db.features),
                    "k_threshold": thr,
                    "sectors": len(alpha),
                    "traced": traced,
                    "trace_s": trace_s,
                    "maps_ms": sec * 1e3,
                    "uniform": float(maps.uniform.mean()),
                    "nn_z_median": float(np.median(nn)),
                    **_map_errors(maps.re, maps.alpha, re_t, a_t),
                }
            )
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller databases")
    ap.add_argument("--db", type=Path, help="section 3: this hrir_db instead of baked ones")
    ap.add_argument("--sections", default="123", help="which sections to run, e.g. 3 (default 123)")
    args = ap.parse_args(argv)
    sizes = (64, 256) if args.quick else (64, 256, 1024)
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        generic = tmp / f"db-basic-{sizes[-1]}.h5"
        if "1" in args.sections:
            out["lookup"] = rows = lookup_rows(tmp, sizes, 128)
            print("\n## SATF lookups of 128 held-out sectors (16 views × 16 lights × 32 px), truth = direct trace\n")
            print(
                table(
                    rows,
                    [
                        ("features", "features", "s"),
                        ("n", "DB sectors", "d"),
                        ("k", "k", "d"),
                        ("query_ms", "query ms", ".1f"),
                        ("re_rms", "re RMS", ".2e"),
                        ("re_rel", "re rel", ".3f"),
                        ("a_rms", "α RMS", ".2e"),
                        ("a_rel", "α rel", ".3f"),
                        ("a_mean_rel", "mean-α rel", ".3f"),
                    ],
                )
            )
        if "2" in args.sections or ("3" in args.sections and not args.db):
            if not generic.exists():
                bake(recipe(sizes[-1], 0, "basic"), generic)
        if "2" in args.sections:
            out["uniformity"] = urows = uniformity_rows(generic)
            print("\n## Uniformity shortcut (eq 6) on tables/scenes/two-clusters.toml; error against two fetches\n")
            print(
                table(
                    urows,
                    [
                        ("mode", "mode", "s"),
                        ("ms", "frame ms", ".1f"),
                        ("uniform", "uniform HSVs", ".2f"),
                        ("re_rms", "re-map RMS", ".2e"),
                        ("re_max", "re-map max", ".2e"),
                    ],
                )
            )
        if "3" in args.sections:
            if args.db:
                dbs = [(args.db.name, args.db)]
            else:
                dbs, space = [], scene_space()
                for n, features in ((256, "basic"),) if args.quick else ((256, "basic"), (1024, "basic"), (1024, "moments")):
                    path = tmp / f"db-scene-{features}-{n}.h5"
                    bake(recipe(n, 0, features, space), path)
                    dbs.append((f"scene space, {features}", path))
                dbs.append(("generic, basic", generic))
            out["scene"] = srows = scene_rows(dbs)
            r0 = srows[0]
            print(
                f"\n## Whole re-/α-map of {SCENE.relative_to(ROOT)} against its {r0['sectors']} sectors traced "
                f"directly ({r0['traced']} non-empty, {r0['trace_s']:.1f} s)\n"
            )
            print(
                table(
                    srows,
                    [
                        ("db", "database", "s"),
                        ("n", "DB sectors", "d"),
                        ("k_threshold", "k_thr", ".0f"),
                        ("nn_z_median", "NN dist (z)", ".2f"),
                        ("uniform", "uniform HSVs", ".2f"),
                        ("maps_ms", "maps ms", ".1f"),
                        ("re_rms", "re RMS", ".2e"),
                        ("re_max", "re max", ".2e"),
                        ("re_rel", "re rel", ".3f"),
                        ("a_rms", "α RMS", ".2e"),
                        ("a_max", "α max", ".2e"),
                        ("a_rel", "α rel", ".3f"),
                        ("a_mean_rel", "mean-α rel", "+.3f"),
                    ],
                )
            )
    old = RESULTS / "satf_accuracy.json"
    if set(args.sections) != set("123") and old.exists():  # a partial run keeps the other sections' results
        out = {**{k: v for k, v in json.loads(old.read_text()).items() if k != "machine"}, **out}
    save("satf_accuracy", out)


if __name__ == "__main__":
    main()
