"""Part ``render``: camera frames of the layered model per map method and of the strand-level
reference at each convergence level, against the finest level (``benchmarks/render.py``, run as
a subprocess: FLIP mean error, frame time)."""

from __future__ import annotations

import re

from ._figure import Figure
from ._parts import Context
from ._scripts import ROOT, run_script, script_missing

PART = "render"
LEVEL = re.compile(r"reference L(\d+)")


def unavailable() -> str | None:
    return script_missing("render.py")


def run(ctx: Context) -> list[Figure]:
    scenes = ["tables/scenes/sintel-groom.toml"] if ctx.quick else ["tables/scenes/sintel-groom.toml",
                                                                      "tables/scenes/ratboy-groom.toml"]
    args = [a for s in scenes for a in ("--scene", str(ROOT / s))] + (["--resolution", "32", "--levels", "0", "1"]
                                                                      if ctx.quick else [])
    doc = run_script("render.py", args, ctx.workdir / "render.json", timeout=900 if ctx.quick else 1500)
    rows = doc.get("rows", doc.get("records", []))
    levels = sorted(int(m.group(1)) for r in rows if (m := LEVEL.fullmatch(r["method"])))
    figs = []
    for r in rows:
        if r.get("scene") == "paper-scale" or r.get("frame_ms") is None:
            continue
        method = r["method"]
        truth = method == f"reference L{levels[-1]}" if levels else False
        ms = r["frame_ms"] + (r.get("maps_ms") or 0.0)  # a layered frame: its maps (made per frame) and the raster
        figs.append(Figure(PART, f"{r['scene']}: frame against the finest reference level", method, ms / 1e3,
                           None if truth else r.get("flip_mean"), "FLIP mean",
                           {k: r[k] for k in ("spp", "steps", "triangles") if r.get(k) is not None},
                           baseline=bool(levels) and method == f"reference L{levels[0]}", paper=method == "layered satf",
                           extra={k: r.get(k) for k in ("rgb_rmse", "rgb_rmse_8x8", "alpha_bias", "maps_ms", "frame_ms",
                                                        "cpu_ms")}))
    shown = " ".join(a[len(str(ROOT)) + 1:] if a.startswith(str(ROOT)) else a for a in args)
    ctx.note(PART, f"benchmarks/render.py {shown}; the finest reference level is the truth (its error is 0 by definition); "
                   "a layered frame's time is its maps plus the raster (maps_ms and the raster alone are in "
                   "results.json); the baseline is the coarsest reference level")
    return figs
