"""Part ``plan``: the planner's needed-only bake against the full bake a user without a planner
would run, and how well each database covers the scene it serves.

For each example scene, in an empty cache: ``hairlut.plan`` → ``bake`` (needed only), then the
scene re-planned (nothing re-baked).  The full bake: the default HRIR database
(tables/hrir-default.toml, the generic sector space), the paper's SH tables (tables/sh-paper.toml:
dense grids) with the sky light and the voxel SH transmittance.  Coverage ("error"): the median
distance from a scene sector's features to the nearest database record, in the scene features'
standard deviations.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..planner import bake, plan
from ..recipes import load_toml
from ._figure import Figure
from ._parts import Context, example

PART = "plan"


def _bytes(paths) -> int:
    return sum(Path(p).stat().st_size for p in paths)


def needed_only_bake(scene: Path, cache: Path) -> dict:
    """Plan and bake what ``scene`` needs into an empty ``cache``: times, estimates, bytes, what was baked and
    skipped, and what a second plan would re-bake."""
    t0 = time.perf_counter()
    p = plan(scene, cache)
    t_plan = time.perf_counter() - t0
    done = bake(p)
    t_bake = time.perf_counter() - t0 - t_plan
    again = plan(scene, cache)
    steps = {s.name: s for s in p.steps}
    return {
        "scene": scene.name,
        "plan_s": t_plan,
        "bake_s": t_bake,
        "estimate_s": sum(s.seconds for s in p.steps if s.action == "bake"),
        "bytes": _bytes(d["path"] for d in done.values()),
        "baked": ", ".join(sorted(done)),
        "skipped": ", ".join(s.name for s in p.steps if s.action == "skip"),
        "rebake_after_replan": sum(s.action == "bake" for s in again.steps),
        "per_step": {k: {"estimate_s": steps[k].seconds, "actual_s": v["seconds"]} for k, v in done.items()},
        "hrir_db": done["hrir_db"]["path"] if "hrir_db" in done else None,
    }


def full_bake(folder: Path, quick: bool) -> dict:
    """Everything, for any scene: the generic database (128 sectors when ``quick``), the paper's SH
    tables with the sky light, the voxel SH transmittance."""
    from hairlut.envlight import sky_light
    from hairlut.geometry import Strands
    from hairlut.hrir import bake as bake_hrir
    from hairlut.shadows import transmittance, voxelize
    from hairlut.shtables import bake_sh, write_sh_tables

    hrir = load_toml(example("hrir-default.toml"))
    if quick:
        hrir["sectors"]["count"] = 128
    times = {}
    t0 = time.perf_counter()
    bake_hrir(hrir, folder / "hrir.h5")
    times["hrir_db"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    sh = load_toml(example("sh-paper.toml"))
    res = bake_sh(sh, sky_light(sh["bands"]["light_specular"] - 1))
    write_sh_tables(folder / "sh.h5", res["tables"], res["info"], res["dense"], res["light"])
    times["sh_tables"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    rng = np.random.default_rng(0)
    pts = np.cumsum(rng.normal(0, 0.01, (300, 16, 3)), axis=1).astype(np.float32)
    transmittance(voxelize(Strands.from_padded(pts), 32), kappa=0.5, stride=2)
    times["transmittance"] = time.perf_counter() - t0
    return {"seconds": times, "bytes": _bytes([folder / "hrir.h5", folder / "sh.h5"]), "hrir_db": folder / "hrir.h5"}


def database_coverage(scene: Path, db_paths: dict) -> dict:
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


def run(ctx: Context) -> list[Figure]:
    names = ["two-clusters.toml"] if ctx.quick else ["two-clusters.toml", "sky-clusters.toml", "sintel-groom.toml"]
    (ctx.workdir / "plan-full").mkdir(parents=True, exist_ok=True)
    full = full_bake(ctx.workdir / "plan-full", ctx.quick)
    full_s = sum(full["seconds"].values())
    figs = []
    for name in names:
        scene = example(f"scenes/{name}")
        r = needed_only_bake(scene, ctx.workdir / f"plan-cache-{name}")
        dbs = {"full": full["hrir_db"], **({"needed": r["hrir_db"]} if r["hrir_db"] else {})}
        cov = database_coverage(scene, dbs)
        table = f"{name}: needed-only bake against the full bake"
        err = "median NN feature distance (σ)"
        figs.append(
            Figure(
                PART,
                table,
                "full bake (no planner)",
                full_s,
                cov["full"][0],
                err,
                {"bytes": full["bytes"]},
                baseline=True,
                extra={"p90": cov["full"][1], **full["seconds"]},
            )
        )
        figs.append(
            Figure(
                PART,
                table,
                f"needed only: {r['baked'] or 'nothing'}",
                r["bake_s"],
                cov["needed"][0] if "needed" in cov else None,
                err,
                {"bytes": r["bytes"], "skipped": r["skipped"]},
                extra={
                    "p90": cov["needed"][1] if "needed" in cov else None,
                    "plan_s": r["plan_s"],
                    "estimate_s": r["estimate_s"],
                    "rebake_after_replan": r["rebake_after_replan"],
                },
            )
        )
        if "needed" not in cov:
            ctx.note(
                PART,
                f"{name}: the plan bakes no HRIR database (its map method needs none), so its coverage is "
                "not defined; the full bake's database coverage of the scene is shown for scale",
            )
    ctx.note(
        PART,
        "full bake: "
        + ", ".join(f"{k} {v:.1f} s" for k, v in full["seconds"].items())
        + (" (the generic database cut to 128 sectors in a quick run)" if ctx.quick else "")
        + "; error: the median distance from the scene's sector features to the nearest database record",
    )
    return figs
