"""Part ``render``: camera frames of the layered model per map method and of the strand-level
reference at each convergence level, against the finest level (``benchmarks/render.py``, run as
a subprocess: FLIP mean error, frame time)."""

from __future__ import annotations

from ._figure import Figure
from ._parts import Context
from ._scripts import ROOT, run_script, script_missing

PART = "render"


def unavailable() -> str | None:
    return script_missing("render.py")


def run(ctx: Context) -> list[Figure]:
    scenes = ["tables/scenes/sintel-groom.toml"] if ctx.quick else ["tables/scenes/sintel-groom.toml",
                                                                      "tables/scenes/ratboy-groom.toml"]
    args = [a for s in scenes for a in ("--scene", str(ROOT / s))] + (["--quick"] if ctx.quick else [])
    doc = run_script("render.py", args, ctx.workdir / "render.json", timeout=900 if ctx.quick else 1500)
    rows = doc.get("rows", doc.get("records", []))
    levels = sorted(int(r["method"][len("reference L"):]) for r in rows if r["method"].startswith("reference L"))
    figs = []
    for r in rows:
        if r.get("scene") == "paper-scale" or r.get("frame_ms") is None:
            continue
        method = r["method"]
        truth = method == f"reference L{levels[-1]}" if levels else False
        figs.append(Figure(PART, f"{r['scene']}: frame against the finest reference level", method, r["frame_ms"] / 1e3,
                           None if truth else r.get("flip_mean"), "FLIP mean",
                           {k: r[k] for k in ("spp", "steps", "triangles") if r.get(k) is not None},
                           baseline=levels != [] and method == f"reference L{levels[0]}", paper=method == "layered satf",
                           extra={k: r.get(k) for k in ("rgb_rmse", "rgb_rmse_8x8", "alpha_bias", "maps_ms", "cpu_ms")}))
    ctx.note(PART, f"benchmarks/render.py {' '.join(a if not a.startswith(str(ROOT)) else a[len(str(ROOT)) + 1:] for a in args)}; "
                   "the finest reference level is the truth (its error is 0 by definition); layered times are the "
                   "rasteriser's, maps excluded; the baseline is the coarsest reference level")
    return figs
