"""Part ``render``: camera frames of the layered model per map method and of the strand-level reference at each
convergence level, against the finest level (:func:`render_study`: FLIP mean error, frame time; issue 13).

Per scene: the reference at each level (``hairlut.render.render_strands(levels=[ℓ])``: 2^ℓ × 2^ℓ samples per
pixel, 2^(ℓ+1) steps per crossing); the finest is the truth every other row is compared with
(``hairlut.render.compare``: FLIP mean, mean-α bias, α outside the truth's silhouette, RGB RMSE, RGB RMSE after
8 × 8 block averaging).  Then the
layered model (``render_layered``) for each ``[render] method`` that can run here: ``direct`` always; ``satf``
when the scene's hrir_db is in the table cache; ``scene`` when its scene_maps table is.  ``frame_ms``: the
layered rasteriser's warm time (maps excluded; ``maps_ms`` beside it) or the reference level's wall time.  Two
diagnostic rows separate the causes of a layered row's error: the reference of only the strand segments inside
the sectors' volume (``hairlut.render.inside_clusters``: what the cluster fit leaves out) against the truth, and
each layered row against that inside-only reference (what the layered model itself loses); ``direct`` also runs
with the in-plane α as the maps give it (no 1/sin ψ lengthening).

Sizes (:data:`RUNS`): the full run renders the Sintel groom at 128 × 128, levels 0–2 (level 2: 16 samples
per pixel, 8 steps per crossing, the truth of levels 0 and 1), and the ten-times-denser Ratboy crest at 128 × 128,
level 0 only: the reference's shadow grids (spacing 4 r̄ / 2^ℓ over the hair's bounds, whatever the frame size)
hold 1 G nodes at its level 1 (about 8 GB on host and device) and 7.6 G at level 2 (refused by the memory budget);
Sintel's level 3 needs 0.4 G nodes (about 3 GB) and several minutes.  ``--quick`` renders Sintel at 32 × 32, levels
0 and 1."""

from __future__ import annotations

import copy
import time
from pathlib import Path

from ._figure import Figure
from ._parts import Context, example

PART = "render"
SINTEL, RATBOY = "scenes/sintel-groom.toml", "scenes/ratboy-groom.toml"
#: (example scene, square resolution, reference levels: the last is the truth) per run size.
RUNS = {"quick": [(SINTEL, 32, (0, 1))], "full": [(SINTEL, 128, (0, 1, 2)), (RATBOY, 128, (0,))]}


def with_config(sc, **sections):
    """The scene ``sc`` with each of ``sections`` ({key: value} per section) over its own, resolved again.  A
    ``render.method`` other than auto drops the knobs of the scene's own method that the chosen one does not read
    (it would refuse them); the groom and environment paths stay where the scene file put them."""
    from hairlut.scene import MAP_KEYS, MAP_KNOBS, resolve_scene

    cfg = copy.deepcopy(sc.raw if hasattr(sc, "raw") else sc.config)
    for sec, kv in sections.items():
        cfg.setdefault(sec, {}).update(kv)
    method = cfg.get("render", {}).get("method", "auto")
    if method != "auto":
        for key in set(MAP_KNOBS) - set(MAP_KEYS[method]):
            cfg["render"].pop(key, None)
    if sc.groom_path is not None:  # relative paths were resolved next to the scene file: keep them absolute
        cfg["groom"]["path"] = str(Path(sc.groom_path).resolve())
    env = sc.config.get("environment") or {}
    if env.get("map") and "environment" in cfg:
        cfg["environment"]["map"] = env["map"]
    return resolve_scene(cfg, Path(sc.source).parent if str(sc.source).endswith(".toml") else None)


def _methods_here(sc, say) -> dict:
    """{method: kwargs for render_layered} of the map methods whose tables are in the cache (direct needs none)."""
    from hairlut.planner import find_assets

    out = {"direct": {}}
    for m in ("satf", "scene"):
        try:
            found = find_assets(with_config(sc, render={"method": m}))
        except Exception as exc:
            say(f"render: layered {m} skipped ({str(exc).splitlines()[0][:100]})")
            continue
        kw = {"db": found.get("hrir_db"), "maps": found.get("scene_maps"), "sh": found.get("sh_tables")}
        out[m] = {k: str(v) for k, v in kw.items() if v is not None}
    return out


def _row(scene, method, frame_ms, cpu_ms, figs, **extra):
    return {
        "scene": Path(scene).stem,
        "method": method,
        "frame_ms": frame_ms,
        "cpu_ms": cpu_ms,
        "flip_mean": figs.get("flip_mean"),
        "alpha_bias": figs.get("alpha_bias"),
        "alpha_bias_relative": figs.get("alpha_bias_relative"),
        "alpha_outside": figs.get("alpha_outside"),
        "rgb_rmse": figs.get("rgb_rmse"),
        "rgb_rmse_8x8": figs.get("rgb_rmse_8x8"),
        **extra,
    }


def render_study(path, levels=(0, 1, 2), resolution: int | None = None, progress=None) -> list[dict]:
    """The rows of the module docstring for the scene file ``path`` at ``resolution``² (the scene's camera when
    None), ``levels`` of the reference (the last is the truth).  Each row: ``scene``, ``method``, ``frame_ms``,
    ``cpu_ms``, ``flip_mean``, ``alpha_bias``, ``alpha_bias_relative``, ``alpha_outside``, ``rgb_rmse``, ``rgb_rmse_8x8``,
    ``resolution`` and what the method adds (``spp``, ``steps``, ``maps_ms``, ``triangles``, …)."""
    from hairlut.render import compare, inside_clusters, render_layered, render_strands
    from hairlut.scene import load_scene, scene_clusters

    say = progress or (lambda message: None)
    levels = sorted(levels)
    sc = load_scene(path)
    if resolution:
        sc = with_config(sc, camera={"resolution": [resolution, resolution]})
    refs = {}
    for lv in levels:
        t0, c0 = time.perf_counter(), time.process_time()
        refs[lv] = render_strands(sc, levels=[lv])
        refs[lv].info["wall_ms"] = 1e3 * (time.perf_counter() - t0)
        refs[lv].info["cpu_ms"] = 1e3 * (time.process_time() - c0)
        say(f"render: {Path(path).stem} reference level {lv}: {refs[lv].info['wall_ms'] / 1e3:.1f} s")
    truth = refs[max(levels)]
    rows = []
    for lv in levels:
        f = refs[lv]
        figs = (
            compare(f, truth)[0]
            if lv != max(levels)
            else {
                "flip_mean": 0.0,
                "alpha_bias": 0.0,
                "rgb_rmse": 0.0,
                "rgb_rmse_8x8": 0.0,
                "alpha_bias_relative": 0.0,
                "alpha_outside": 0.0,
            }
        )
        last = f.info["levels"][-1]
        rows.append(
            _row(
                path,
                f"reference L{lv}",
                f.info["wall_ms"],
                f.info["cpu_ms"],
                figs,
                spp=last.get("samples_per_pixel"),
                steps=last.get("steps_per_crossing"),
            )
        )
    # what the cluster fit leaves out: the reference of only the strand segments inside the sectors' volume
    t0 = time.perf_counter()
    kept, fractions = inside_clusters(scene_clusters(sc))
    inside = render_strands(sc, camera=truth.camera, levels=[max(levels)], strands=kept)
    rows.append(
        _row(
            path,
            f"reference L{max(levels)}, strands inside the sectors",
            1e3 * (time.perf_counter() - t0),
            None,
            compare(inside, truth)[0],
            length_fractions=fractions,
        )
    )
    for method, kw in _methods_here(sc, say).items():
        for oblique in (True, False) if method == "direct" else (True,):
            name = f"layered {method}" + ("" if oblique else " (in-plane α)")
            try:
                c0 = time.process_time()
                f = render_layered(
                    with_config(sc, render={"method": method}), camera=truth.camera, repeat=2, oblique=oblique, **kw
                )
                cpu = time.process_time() - c0
            except Exception as exc:
                say(f"render: {name} failed ({str(exc).splitlines()[0][:120]})")
                continue
            sec = f.info["seconds"]
            rows.append(
                _row(
                    path,
                    name,
                    1e3 * sec["raster"],
                    None,
                    compare(f, truth)[0],
                    maps_ms=1e3 * sec["maps"],
                    shade_ms=1e3 * sec["shade"],
                    triangles=f.info["triangles"],
                    total_cpu_s=cpu,
                )
            )
            own = compare(f, inside)[0]  # against the strands the sectors hold: the layered model's own loss
            rows.append(_row(path, f"{name} vs inside-only reference", None, None, own))
    return [{**r, "resolution": resolution} for r in rows]


def _figures(rows: list[dict], levels: tuple[int, ...]) -> list[Figure]:
    figs = []
    truth, coarse = f"reference L{max(levels)}", f"reference L{min(levels)}"
    for r in rows:
        if r.get("frame_ms") is None:
            continue
        method = r["method"]
        ms = r["frame_ms"] + (r.get("maps_ms") or 0.0)  # a layered frame: its maps (made per frame) and the raster
        figs.append(
            Figure(
                PART,
                f"{r['scene']}: frame against the finest reference level",
                method,
                ms / 1e3,
                None if method == truth else r.get("flip_mean"),
                "FLIP mean",
                {k: r[k] for k in ("spp", "steps", "triangles", "resolution") if r.get(k) is not None},
                baseline=method == coarse,
                paper=method == "layered satf",
                extra={
                    k: r.get(k)
                    for k in ("rgb_rmse", "rgb_rmse_8x8", "alpha_bias", "alpha_outside", "maps_ms", "frame_ms", "cpu_ms")
                },
            )
        )
    return figs


def run(ctx: Context) -> list[Figure]:
    figs, shown = [], []
    for scene, resolution, levels in RUNS["quick" if ctx.quick else "full"]:
        figs += _figures(render_study(example(scene), levels, resolution, ctx.progress), levels)
        shown.append(f"{Path(scene).stem} at {resolution} × {resolution}, levels {', '.join(map(str, levels))}")
    ctx.note(
        PART,
        f"{'; '.join(shown)}; the finest reference level is the truth (its error is 0 by "
        "definition); a layered frame's time is its maps plus the raster (maps_ms and the raster alone are in "
        "results.json); the baseline is the coarsest reference level",
    )
    return figs
