"""Part ``render``: camera frames of the layered model per map method and of the strand render at
each convergence level, against the finest level (``benchmarks/render.py``, run as
a subprocess per scene: FLIP mean error, frame time).

Sizes (:data:`RUNS`): the full run renders the Sintel groom at 128 × 128, levels 0–2 (level 2: 16 samples
per pixel, 8 steps per crossing, the truth of levels 0 and 1), and the ten-times-denser Ratboy crest at 128 × 128,
level 0 only: the strand render's shadow grids (spacing 4 r̄ / 2^ℓ over the hair's bounds, whatever the frame size)
hold 1 G nodes at its level 1 (about 8 GB on host and device) and 7.6 G at level 2 (refused by the memory budget);
Sintel's level 3 needs 0.4 G nodes (about 3 GB) and several minutes.  ``--quick`` renders Sintel at 32 × 32, levels
0 and 1."""

from __future__ import annotations

from ._figure import Figure
from ._parts import Context
from ._scripts import ROOT, run_script, script_missing

PART = "render"
SINTEL, RATBOY = "tables/scenes/sintel-groom.toml", "tables/scenes/ratboy-groom.toml"
#: (scene, square resolution, strand render levels: the last is the truth) per run size.
RUNS = {"quick": [(SINTEL, 32, (0, 1))], "full": [(SINTEL, 128, (0, 1, 2)), (RATBOY, 128, (0,))]}


def unavailable() -> str | None:
    return script_missing("render.py")


def _figures(rows: list[dict], levels: tuple[int, ...]) -> list[Figure]:
    figs = []
    truth, coarse = f"strands L{max(levels)}", f"strands L{min(levels)}"
    for r in rows:
        if r.get("scene") == "paper-scale" or r.get("frame_ms") is None:
            continue
        method = r["method"]
        ms = r["frame_ms"] + (r.get("maps_ms") or 0.0)  # a layered frame: its maps (made per frame) and the raster
        figs.append(Figure(PART, f"{r['scene']}: frame against the strand render's finest level", method, ms / 1e3,
                           None if method == truth else r.get("flip_mean"), "FLIP mean",
                           {k: r[k] for k in ("spp", "steps", "triangles", "resolution") if r.get(k) is not None},
                           baseline=method == coarse, paper=method == "layered satf",
                           extra={k: r.get(k) for k in ("rgb_rmse", "rgb_rmse_8x8", "alpha_bias", "maps_ms", "frame_ms",
                                                        "cpu_ms")}))
    return figs


def run(ctx: Context) -> list[Figure]:
    figs, shown = [], []
    for scene, resolution, levels in RUNS["quick" if ctx.quick else "full"]:
        args = ["--scene", str(ROOT / scene), "--resolution", str(resolution), "--levels", *map(str, levels)]
        doc = run_script("render.py", args, ctx.workdir / "render.json", timeout=900 if ctx.quick else 1500)
        rows = doc.get("rows", doc.get("records", []))
        figs += _figures(rows, levels)
        shown.append(f"--scene {scene} --resolution {resolution} --levels {' '.join(map(str, levels))}")
    ctx.note(PART, f"benchmarks/render.py {'; '.join(shown)}; the strand render's finest level is the truth (its error is 0 by "
                   "definition); a layered frame's time is its maps plus the raster (maps_ms and the raster alone are in "
                   "results.json); the baseline is the strand render's coarsest level")
    return figs
