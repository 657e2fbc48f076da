"""SATF lookup accuracy: lookups against directly traced HRIRs of held-out sectors.

    python benchmarks/satf_accuracy.py [--quick]

1. Databases of N random sectors (two feature sets: the paper's (ρ_st, ρ_s, ρ_t) and
   the richer "moments" set) are queried with the features of held-out sectors
   (another seed, never in any database) at grid angles, so only the feature
   lookup is measured; the truth is those sectors traced directly with the same
   tracer.  Error: RMS of re and α over pixels, relative ‖Δ‖/‖truth‖, and the
   relative error of each sector's pixel-mean α (its coverage).
2. The paper's uniformity shortcut (eq 6, k_threshold = 1) against always
   fetching two HRIRs (k_threshold = 0), and always one (∞), on the procedural
   example scene: re-map error against k_threshold = 0 and frame time.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import best_of, save, table  # noqa: E402

from hairlut.hrir import HRIRDB, bake  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TRACE = {"angles": {"views": 16, "lights": 16}, "trace": {"pixels": 32, "steps": 48}}


def recipe(count, seed, features):
    return {"sectors": {"count": count, "seed": seed, "features": features}, **TRACE}


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
                rows.append({
                    "features": features, "n": n, "k": k, "bake_s": bake_s, "query_ms": sec * 1e3,
                    "re_rms": float(np.sqrt(np.mean((re - ref_re) ** 2))),
                    "re_rel": float(np.linalg.norm(re - ref_re) / np.linalg.norm(ref_re)),
                    "a_rms": float(np.sqrt(np.mean((a - ref_a) ** 2))),
                    "a_rel": float(np.linalg.norm(a - ref_a) / np.linalg.norm(ref_a)),
                    # coverage level: each sector's pixel-mean opacity, which the features summarise
                    "a_mean_rel": float(np.linalg.norm(a.mean(-1) - ref_a.mean(-1)) / np.linalg.norm(ref_a.mean(-1))),
                })
    return rows


def uniformity_rows(db_path: Path):
    from hairlut.synth import load_scene, prepare, render
    from hairlut.synth._scene import resolve_scene
    from hairlut.recipes import load_toml

    scene_file = ROOT / "tables" / "scenes" / "two-clusters.toml"
    base = load_toml(scene_file)
    results = {}
    for name, thr in (("always two fetches (k_threshold = 0)", 0.0), ("eq 6 shortcut (k_threshold = 1)", 1.0),
                      ("always one fetch (k_threshold = ∞)", float("inf"))):
        given = {**base, "material": {**base.get("material", {}), "k_threshold": thr}}
        prepared = prepare(resolve_scene(given, scene_file.parent, source=str(scene_file)), str(db_path))
        render(prepared)
        sec, res = best_of(lambda: render(prepared), repeat=3)
        results[name] = (sec, res)
    ref = results["always two fetches (k_threshold = 0)"][1]
    rows = []
    for name, (sec, res) in results.items():
        d = np.concatenate([(c.re - r.re).ravel() for c, r in zip(res.clusters, ref.clusters)])
        uni = float(np.mean([c.uniform_fraction for c in res.clusters]))
        rows.append({"mode": name, "ms": sec * 1e3, "uniform": uni, "re_rms": float(np.sqrt(np.mean(d**2))),
                     "re_max": float(np.abs(d).max())})
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller databases")
    args = ap.parse_args(argv)
    sizes = (64, 256) if args.quick else (64, 256, 1024)
    with tempfile.TemporaryDirectory() as tmp:
        rows = lookup_rows(Path(tmp), sizes, 128)
        print("\n## SATF lookups of 128 held-out sectors (16 views × 16 lights × 32 px), truth = direct trace\n")
        print(table(rows, [("features", "features", "s"), ("n", "DB sectors", "d"), ("k", "k", "d"),
                           ("query_ms", "query ms", ".1f"), ("re_rms", "re RMS", ".2e"), ("re_rel", "re rel", ".3f"),
                           ("a_rms", "α RMS", ".2e"), ("a_rel", "α rel", ".3f"), ("a_mean_rel", "mean-α rel", ".3f")]))
        urows = uniformity_rows(Path(tmp) / f"db-basic-{sizes[-1]}.h5")
        print("\n## Uniformity shortcut (eq 6) on tables/scenes/two-clusters.toml; error against two fetches\n")
        print(table(urows, [("mode", "mode", "s"), ("ms", "frame ms", ".1f"), ("uniform", "uniform HSVs", ".2f"),
                            ("re_rms", "re-map RMS", ".2e"), ("re_max", "re-map max", ".2e")]))
    save("satf_accuracy", {"lookup": rows, "uniformity": urows})


if __name__ == "__main__":
    main()
