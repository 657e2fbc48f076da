"""Part ``picture``: the layered render with the defaults against the converged strand render, on grooms nobody
tuned (issue 26, deliverable 5).

Every groom (:data:`GROOMS`: the vendored Sintel and Ratboy grooms and the procedural curly, parted and crop grooms of
:mod:`hairlut.bench._grooms`) is seen from three cameras (:data:`hairlut.bench._grooms.VIEWS`) through a scene that
gives only the groom, the camera, one light and nothing else (:func:`hairlut.bench._grooms.scene_text`): every other
knob is the planner's.  Per groom and camera (:func:`picture_study`):

* ``cold_s``: the plan, its bakes and the first layered frame in a process that has not seen the groom (the cluster
  fit, the scene table, the compile);
* ``frame_ms``: a warm frame of the same camera (the maps, the shading and the raster);
* against the strand render converged to :data:`BOUND` (``hairlut.render.render_strands``; kept in the table cache by
  ``hairlut.render.cached_frame``): FLIP, the mean-α bias, the colour per unit α (the luminance of the premultiplied
  RGB over α, frame-averaged, as a ratio to the strand render's) and the α outside the strands' silhouette.

Each groom and camera is one table whose baseline is the paper's own knobs (4 clusters, eq 7's pair reads, eq 12's
s-map, eq 13 × the HRIR's re).  On the first camera of the first groom the table also holds the settings the planner
considered (half and twice its cluster count, two and four layer shells, pair reads, the s-map), so the plot shows FLIP against frame time for
each of them."""

from __future__ import annotations

import time
from pathlib import Path

from ._figure import Figure
from ._parts import Context, example

PART = "picture"
#: The strand render's convergence bound (the RMSE change of one more refinement level).
BOUND = 0.02
#: The paper's own knobs: the baseline of every table.
PAPER = {
    "groom": {"clusters": 4},
    "render": {"layer_reads": "pair"},
    "shadows": {"method": "smap"},
    "material": {"reflectance": "hrir"},
}
#: groom → (a generator in ``_grooms`` or an example file, the strand render's deepest level).  Ratboy's strand
#: render needs ~8 GB at level 1 (its shadow grids follow the hair's bounds), so it stays at level 0.
GROOMS = {
    "sintel": ("grooms/sintel_lite.tfx", 3),
    "ratboy": ("grooms/ratboy_mohawk.tfx", 0),
    "curly": ("curly", 3),
    "parted": ("parted", 3),
    "crop": ("crop", 3),
}
#: (grooms, views, square resolution, sizes of the generated grooms) per run size.
RUNS = {
    "quick": (("crop",), ("front",), 32, {"crop": {"n_strands": 120}}),
    "full": (tuple(GROOMS), ("front", "side", "back"), 128, {}),
}


def groom_file(name: str, workdir: Path, sizes: dict) -> Path:
    """The groom file of ``name``: the vendored example, or the procedural groom written under ``workdir``."""
    from . import _grooms

    source, _ = GROOMS[name]
    if "/" in source:
        return example(source)
    return _grooms.write_groom(workdir, name, _grooms.KINDS[source](seed=0, **sizes.get(name, {})), formats=("hair",))["hair"]


def _scene(groom_file: Path, view: str, resolution: int, folder: Path, **sections):
    from hairlut.scene import resolve_scene

    from . import _grooms

    cfg = {
        "groom": {"path": str(groom_file), **sections.pop("groom", {})},
        "camera": {"view": list(_grooms.VIEWS[view]), "resolution": [resolution, resolution]},
        "lights": {"directions": [list(_grooms.LIGHT)]},
    }
    for sec, kv in sections.items():
        cfg.setdefault(sec, {}).update(kv)
    return resolve_scene(cfg, folder, source=f"{groom_file.stem}-{view}")


def _layered(sc, repeat: int = 3) -> tuple:
    """(frame, cold seconds: plan + bakes + the first frame, warm frame ms: maps + shading + raster)."""
    from hairlut.planner import bake, plan, scene_assets
    from hairlut.render import render_layered
    from hairlut.synth import prepare

    t0 = time.perf_counter()
    bake(plan(sc))
    db, sh, maps = scene_assets(sc)
    prep = prepare(sc, db, sh, maps)
    first = render_layered(sc, prepared=prep, repeat=1)
    cold = time.perf_counter() - t0
    frame = render_layered(sc, prepared=prep, repeat=repeat)
    sec = frame.info["seconds"]
    return frame, first, cold, 1e3 * (sec["maps"] + sec["shade"] + sec["raster"])


def _strands(sc, camera, max_level: int):
    from hairlut.render import cached_frame, render_strands

    record = {"what": "strands converged", "camera": camera.to_json(), "bound": BOUND, "max_level": max_level}
    return cached_frame(sc, record, lambda: render_strands(sc, camera, bound=BOUND, max_level=max_level))


def picture_study(grooms, views, resolution: int, workdir, *, sizes=None, considered: bool = True, progress=None) -> list[dict]:
    """The rows of the module docstring: one per groom, camera and setting (``defaults``, ``paper`` and, for the first
    groom and camera when ``considered``, the alternatives the planner weighed)."""
    from hairlut.planner import choices
    from hairlut.render import compare

    say = progress or (lambda message: None)
    workdir = Path(workdir)
    rows = []
    for gi, name in enumerate(grooms):
        groom = groom_file(name, workdir, sizes or {})
        for vi, view in enumerate(views):
            default = _scene(groom, view, resolution, workdir)
            chosen = {c.key: c.value for c in choices(default)}
            settings = {"defaults": {}, "paper": PAPER}
            if considered and gi == 0 and vi == 0:
                n = chosen["groom.clusters"]
                settings |= {
                    f"{max(n // 2, 1)} clusters": {"groom": {"clusters": max(n // 2, 1)}},
                    f"{2 * n} clusters": {"groom": {"clusters": 2 * n}},
                    "2 shells": {"groom": {"layer_radii": [0.5, 1.0]}},
                    "4 shells": {"groom": {"layer_radii": [0.25, 0.5, 0.75, 1.0]}},
                    "pair reads": {"render": {"layer_reads": "pair"}},
                    "s-map shadows": {"shadows": {"method": "smap"}},
                }
            truth = None
            for label, over in settings.items():
                sc = default if not over else _scene(groom, view, resolution, workdir, **{k: dict(v) for k, v in over.items()})
                frame, first, cold, warm_ms = _layered(sc)
                if truth is None:
                    t0 = time.perf_counter()
                    truth = _strands(default, frame.camera, GROOMS[name][1])
                    say(f"picture: {name} {view}: strand render {time.perf_counter() - t0:.0f} s")
                figs = compare(frame, truth)[0]
                rows.append(
                    {
                        "groom": name,
                        "view": view,
                        "setting": label,
                        "knobs": chosen if label == "defaults" else over,
                        "cold_s": cold,
                        "frame_ms": warm_ms,
                        "flip_mean": figs["flip_mean"],
                        "alpha_bias_relative": figs["alpha_bias_relative"],
                        "colour_per_alpha": figs["colour_per_alpha"],
                        "alpha_outside": figs["alpha_outside"],
                        "clusters": frame.info["clusters"],
                        "map_method": frame.info["map_method"],
                        "resolution": resolution,
                        "strands_converged": bool(truth.info.get("converged")),
                        "strands_level": truth.info["levels"][-1]["level"],
                    }
                )
                say(f"picture: {name} {view} {label}: FLIP {figs['flip_mean']:.3f}, cold {cold:.0f} s, frame {warm_ms:.0f} ms")
    return rows


def run(ctx: Context) -> list[Figure]:
    grooms, views, resolution, sizes = RUNS["quick" if ctx.quick else "full"]
    rows = picture_study(grooms, views, resolution, ctx.workdir, sizes=sizes, considered=not ctx.quick, progress=ctx.progress)
    figs = [
        Figure(
            PART,
            f"{r['groom']} {r['view']}: layered against the strand render converged to {BOUND}",
            r["setting"],
            r["frame_ms"] / 1e3,
            r["flip_mean"],
            "FLIP mean",
            {"clusters": r["clusters"], "resolution": r["resolution"]},
            baseline=r["setting"] == "paper",
            paper=r["setting"] == "paper",
            extra={
                k: r[k]
                for k in (
                    "alpha_bias_relative",
                    "colour_per_alpha",
                    "alpha_outside",
                    "cold_s",
                    "strands_converged",
                    "strands_level",
                )
            },
        )
        for r in rows
    ]
    ctx.note(
        PART,
        f"{', '.join(grooms)} from {', '.join(views)} at {resolution} × {resolution}, each scene giving only the groom, "
        f"the camera and one light; the truth is the strand render converged to {BOUND} (Ratboy: level 0, not converged: "
        "its level 1 needs ~8 GB); seconds: a warm frame (maps, shading, raster); cold_s: plan, bakes and the first "
        "frame; the baseline is the paper's knobs (4 clusters, pair reads, s-map, × re)",
    )
    return figs
