"""The built-in demo: plan, bake (through the table cache) and synthesise example scenes.

For each scene file: :func:`hairlut.plan.plan` decides what it needs and why,
:func:`hairlut.plan.bake` bakes what the cache lacks (a second run reuses everything),
:func:`hairlut.synth.synthesize` renders every cluster (SATF maps, lighting, s-maps,
blending, and the environment light through the SH tables with voxel SH self-shadowing
when the scene has one), and the EXR/PNG outputs land in ``out_dir/<scene>/``.  A scene with a
groom is also rendered through its camera with the layered model and with the strand render
(``hairlut.render.layered_vs_strands``, at :data:`STRANDS_LEVEL`, with that level's change to the next
measured at :data:`PROBE_SIZE` pixels and stored in strands.exr), side by side with the FLIP map
in ``out_dir/<scene>/camera/side_by_side.png``.  The strand-render frames (the probe's two levels and the
camera's frame) are kept in the table cache (``hairlut.render.cached_frame``, keyed by the scene, the camera, the level and the
code), so a warm run renders only the layered frame and compares it afresh; the report then says the strand render was
reused and keeps the times of the run that rendered it.  The
report keeps the plan, what was baked or reused, the times and accuracy figures: the
SATF lookup's self-check at stored records, the SH tables' Chebyshev tail and specular
truncation error, and the fraction of texels whose environment term rang below zero.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from .assets import write_exr
from .envlight import SKY, sky_radiance

#: The strand render's level in the demo (2^ℓ × 2^ℓ samples per pixel, 2^(ℓ+1) steps per crossing): a fixed,
#: stated level, not the converged one, to keep the demo's run time reasonable on a 2-core CPU (at 768 × 768 on
#: Sintel each level costs about 8× the one before).  How far it is from converged is measured beside it
#: (:func:`strands_probe`) and stored in strands.exr.
STRANDS_LEVEL = 0
#: The frame's longer side at which :func:`strands_probe` renders the demo's level and the next one.
PROBE_SIZE = 128


def sky(height: int = 128) -> dict[str, np.ndarray]:
    """The built-in procedural sky (:func:`hairlut.envlight.sky_radiance`) as EXR channels."""
    rgb = sky_radiance(height)
    return {c: rgb[..., k].astype(np.float32) for k, c in enumerate("RGB")}


def _hrir_self_check(path) -> float:
    """SATF query (k = 1) at stored records and grid angles against the records themselves."""
    from .hrir import HRIRDB

    db = HRIRDB.load(path)
    n = min(len(db.features), 64)
    re, _, _, _ = db.query(db.features[:n], db.theta_v[1 % len(db.theta_v)], db.theta_l[2 % len(db.theta_l)], k=1)
    return float(np.abs(re - db.reflectance[:n, 1 % len(db.theta_v), 2 % len(db.theta_l)]).max())


def _sh_figures(path) -> dict:
    from .assets import open_table

    with open_table(path, "sh_tables") as f:
        keys = ("chebyshev_tail", "chebyshev_nodes", "specular_truncation_error")
        return {k: float(f.attrs[k]) for k in keys if k in f.attrs}


def strands_probe(scene, level: int = STRANDS_LEVEL, size: int = PROBE_SIZE, *, cache=None) -> dict:
    """How far the strand render's ``level`` is from converged: the scene's camera (same framing) at ``size``
    pixels on its longer side, rendered at ``level`` and ``level`` + 1 (``hairlut.render.render_strands``), and
    the change between them (RMSE of premultiplied RGB and of α: what a convergence bound is compared with).
    ``cache``: a table cache folder that keeps the two levels between runs (``hairlut.render.cached_frame``);
    ``cpu_seconds`` is then the run's that rendered them, and ``cache`` says ``reused`` or ``rendered``."""
    from .render import cached_frame, render_strands, scene_strands
    from .scene import make_camera

    cfg = scene.config["camera"]
    w, h = cfg["resolution"]
    small = [size, max(1, round(size * h / w))] if w >= h else [max(1, round(size * w / h)), size]
    levels = [level, level + 1]

    def probe():
        strands = scene_strands(scene)
        cam = make_camera({**cfg, "resolution": small}, np.concatenate([s.points for s in strands]))
        t0 = time.process_time()
        f = render_strands(scene, cam, levels=levels, strands=strands)
        f.info["cpu_seconds"] = time.process_time() - t0
        return f

    # the camera's table and the size determine the fitted camera (with the scene's strands, in the scene's record)
    f = (
        probe()
        if cache is None
        else cached_frame(
            scene, {"what": "convergence probe", "camera": {**cfg, "resolution": small}, "levels": levels}, probe, cache
        )
    )
    return {
        "level": level,
        "next_level": level + 1,
        "resolution": small,
        "change_to_next": f.info["levels"][-1]["change_from_previous"],
        "cpu_seconds": f.info["cpu_seconds"],
        "cache": f.info.get("cache", {}).get("status"),
    }


def run_scene(scene_path, out_dir, cache_root=None, progress=None) -> dict:
    """Plan, bake (through the cache) and synthesise one scene; its report."""
    from .bake.cache import cache_dir
    from .planner import bake, plan
    from .synth import prepare, render_view, write_outputs

    t0 = time.perf_counter()
    p = plan(scene_path, cache_root)
    t1 = time.perf_counter()
    assets = bake(p, progress)
    t2 = time.perf_counter()
    db, sh, maps = (assets.get(k, {}).get("path") for k in ("hrir_db", "sh_tables", "scene_maps"))
    prepared = prepare(p.scene, db, sh, maps)  # the map method auto picked (plan's map_method); reused by the camera
    result = render_view(prepared)
    t3 = time.perf_counter()
    files = write_outputs(result, out_dir)
    t4 = time.perf_counter()
    camera = None
    if p.scene.groom_path is not None:  # a real groom: the layered model beside its strand render
        from .render import layered_vs_strands

        cache = cache_dir(cache_root)  # the strand-render frames are kept beside the tables (hairlut.render.cached_frame)
        probe = strands_probe(p.scene, cache=cache)
        camera = layered_vs_strands(
            p.scene,
            Path(out_dir) / "camera",
            prepared=prepared,
            level=STRANDS_LEVEL,
            strands_info={"convergence_probe": probe},
            cache=cache,
        )
    accuracy = {"hrir_query_self_check": _hrir_self_check(assets["hrir_db"]["path"])} if "hrir_db" in assets else {}
    if "sh_tables" in assets:
        accuracy.update(_sh_figures(assets["sh_tables"]["path"]))
    if "environment_clamped" in result.stats:
        accuracy["environment_clamped_fraction"] = result.stats["environment_clamped"]
    return {
        "scene": str(scene_path),
        "plan": p.to_json()["steps"],
        "assets": assets,
        "files": files,
        "stats": result.stats,
        "accuracy": accuracy,
        "camera": camera,
        "seconds": {
            "plan": t1 - t0,
            "bake": t2 - t1,
            "synth": t3 - t2,
            "write": t4 - t3,
            **({"camera": time.perf_counter() - t4} if camera else {}),
        },
    }


def run(out_dir: str | os.PathLike, scenes, cache_root=None, progress=None) -> dict:
    """The demo: for each scene file, plan → bake (cached) → synthesise → EXR/PNG under
    ``out_dir/<scene name>/``; also the built-in sky as ``sky.exr``.  Returns the report."""
    out = Path(out_dir)
    start = time.perf_counter()
    env = write_exr(out / "sky.exr", sky(), recipe=SKY, kind="envmap")
    reports = [run_scene(s, out / Path(s).stem, cache_root, progress) for s in scenes]
    return {"scenes": reports, "sky": str(env), "total_seconds": time.perf_counter() - start}
