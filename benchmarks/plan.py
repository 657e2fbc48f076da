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
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import save, table  # noqa: E402

from hairlut.scene import bake, plan  # noqa: E402
from hairlut.recipes import load_toml  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "tables" / "scenes"


def _bytes(paths) -> int:
    return sum(Path(p).stat().st_size for p in paths)


def needed_only(scene: Path, cache: Path) -> dict:
    t0 = time.perf_counter()
    p = plan(scene, cache)
    t_plan = time.perf_counter() - t0
    done = bake(p)
    t_bake = time.perf_counter() - t0 - t_plan
    again = plan(scene, cache)
    steps = {s.name: s for s in p.steps}
    return {"scene": scene.name, "plan_s": t_plan, "bake_s": t_bake,
            "estimate_s": sum(s.seconds for s in p.steps if s.action == "bake"),
            "bytes": _bytes(d["path"] for d in done.values()),
            "baked": ", ".join(sorted(done)), "skipped": ", ".join(s.name for s in p.steps if s.action == "skip"),
            "rebake_after_replan": sum(s.action == "bake" for s in again.steps),
            "per_step": {k: {"estimate_s": steps[k].seconds, "actual_s": v["seconds"]} for k, v in done.items()},
            "hrir_db": done["hrir_db"]["path"]}


def full_bake(folder: Path, quick: bool) -> dict:
    """Everything, for any scene: the generic database, the paper's SH tables with the sky, transmittance."""
    from hairlut.envlight import sky_light
    from hairlut.geometry import Strands
    from hairlut.hrir import bake as bake_hrir
    from hairlut.shadows import transmittance, voxelize
    from hairlut.shtables import bake_sh, write_sh_tables

    hrir = load_toml(ROOT / "tables" / "hrir-default.toml")
    if quick:
        hrir["sectors"]["count"] = 128
    times = {}
    t0 = time.perf_counter()
    bake_hrir(hrir, folder / "hrir.h5")
    times["hrir_db"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    sh = load_toml(ROOT / "tables" / "sh-paper.toml")
    res = bake_sh(sh, sky_light(sh["bands"]["light_specular"] - 1))
    write_sh_tables(folder / "sh.h5", res["tables"], res["info"], res["dense"], res["light"])
    times["sh_tables"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    rng = np.random.default_rng(0)
    pts = np.cumsum(rng.normal(0, 0.01, (300, 16, 3)), axis=1).astype(np.float32)
    transmittance(voxelize(Strands.from_padded(pts), 32), kappa=0.5, stride=2)
    times["transmittance"] = time.perf_counter() - t0
    return {"seconds": times, "bytes": _bytes([folder / "hrir.h5", folder / "sh.h5"]), "hrir_db": folder / "hrir.h5"}


def coverage(scene: Path, db_paths: dict) -> dict:
    """Nearest-record distance of the scene's sector features, in the scene features' std."""
    from hairlut.hrir import load_hrir_db
    from hairlut.scene import resolve_scene
    from hairlut.synth import prepare

    raw = load_toml(scene)
    raw.pop("environment", None)  # the features do not depend on the light
    out, sc = {}, resolve_scene(raw, scene.parent, source=str(scene))
    for name, path in db_paths.items():
        db = load_hrir_db(path)
        f = prepare(sc, db).frames.features
        std = np.where(f.std(0) > 0, f.std(0), 1.0)
        d = np.sqrt((((f[:, None, :] - db.features[None, :, :]) / std) ** 2).sum(-1)).min(1)
        out[name] = (float(np.median(d)), float(np.quantile(d, 0.9)))
    return out


def demo_runs(folder: Path) -> dict:
    exe = Path(sys.executable).with_name("hairlut")
    cmd = [str(exe), "demo", "--out", str(folder / "out"), "--cache", str(folder / "cache"), "--no-progress"]
    env = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = str(folder / "xdg")  # a fresh compilation cache: cold means cold
    out = {}
    for run in ("cold", "warm"):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True, cwd=ROOT, env=env)
        out[run] = time.perf_counter() - t0
    return out


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
            r = needed_only(SCENES / name, tmp / f"cache-{name}")
            rows.append(r)
            cov[name] = coverage(SCENES / name, {"needed": r.pop("hrir_db"), "full": full["hrir_db"]})
        full_s = sum(full["seconds"].values())
        for r in rows:
            r["time_ratio"] = r["bake_s"] / full_s
            r["bytes_ratio"] = r["bytes"] / full["bytes"]
            (r["nn_needed_med"], r["nn_needed_p90"]), (r["nn_full_med"], r["nn_full_p90"]) = \
                cov[r["scene"]]["needed"], cov[r["scene"]]["full"]
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
