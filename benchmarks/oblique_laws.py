"""The layered render's oblique law against the strand reference (issue 13): mean-α bias per law and groom.

Per scene: the strand reference at level 0 (``render_strands(levels=[0])``) with shadows off (α does not depend
on them), then the layered model (``render_layered``, ``direct`` maps, the scene's layer reads) once per oblique law
of ``--laws`` (``hairlut.render.OBLIQUE_LAWS``: ``rays`` traces each sector's maps with every ray's optical depth ×
1/sin ψ; ``strands`` lengthens each texel by Campbell's law; ``volume`` by 1/sin ψ; ``off`` not at all), compared
with ``hairlut.render.compare``: mean-α bias (relative), 8 × 8-block α and RGB RMSE.  ``--grid N --steps K`` trace
the direct maps on an N × N density grid with K steps instead of the scene's ``[tables.hrir]`` (Sintel's scene uses
the default 32 × 32, Ratboy's 96 × 96 / 192).  Beside each row: the online frame's warm CPU seconds (maps and
shading: best of ``--repeat`` calls of ``hairlut.synth.render_view`` with the law's paths, computed once before).

Usage: python -m benchmarks.oblique_laws [--scene S.toml ...] [--resolution 128] [--laws rays strands volume off]
       [--grid 96 --steps 192]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from hairlut.bench import with_config
from hairlut.render import OBLIQUE_LAWS, compare, render_layered, render_strands, sector_paths
from hairlut.scene import load_scene
from hairlut.synth import prepare, render_view

from ._common import SCENES, save, table


def frame_cpu(prep, cam, law: str, repeat: int) -> float:
    """Best process seconds of a whole online frame (``render``: maps and shading) over ``repeat`` warm calls."""
    paths = sector_paths(cam, prep) if law == "rays" else (None, None)
    render_view(prep, path=paths[0], light_path=paths[1])  # warm
    best = float("inf")
    for _ in range(repeat):
        c0 = time.process_time()
        render_view(prep, path=paths[0], light_path=paths[1])
        best = min(best, time.process_time() - c0)
    return best


def run_scene(path, resolution: int, laws, grid, steps, repeat: int) -> list[dict]:
    sc = with_config(load_scene(path), camera={"resolution": [resolution] * 2}, shadows={"method": "none"})
    c0 = time.process_time()
    truth = render_strands(sc, levels=[0])
    print(f"{Path(path).stem}: reference level 0, {time.process_time() - c0:.1f} CPU s", flush=True)
    extra = {"tables": {"hrir": {"sectors": {"grid": [grid] * 2}, "trace": {"steps": steps}}}} if grid else {}
    layered = with_config(sc, render={"method": "direct"}, **extra)
    prep = prepare(layered)
    rows = []
    for law in laws:
        f = render_layered(layered, camera=truth.camera, prepared=prep, oblique=law, repeat=0)
        figs = compare(f, truth, flip=False)[0]
        row = {
            "scene": Path(path).stem,
            "resolution": resolution,
            "grid": grid or "scene",
            "law": f.info["oblique"],
            "reads": layered.config["render"]["layer_reads"],
            "alpha_bias": figs["alpha_bias_relative"],
            "alpha_rmse_8x8": figs["alpha_rmse_8x8"],
            "rgb_rmse_8x8": figs["rgb_rmse_8x8"],
            "frame_cpu_s": frame_cpu(prep, truth.camera, law, repeat) if repeat else None,
        }
        rows.append(row)
        print(row, flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", nargs="+", default=[str(s) for s in SCENES])
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--laws", nargs="+", default=list(OBLIQUE_LAWS), choices=list(OBLIQUE_LAWS))
    ap.add_argument("--grid", type=int, default=0, help="density grid side for the direct maps (0: the scene's)")
    ap.add_argument("--steps", type=int, default=192, help="march steps with --grid")
    ap.add_argument("--repeat", type=int, default=2, help="warm frames timed for the maps stage (0: none)")
    a = ap.parse_args()
    rows = [r for s in a.scene for r in run_scene(s, a.resolution, a.laws, a.grid, a.steps, a.repeat)]
    print(
        table(
            rows,
            [
                ("scene", "scene", "s"),
                ("grid", "grid", "s"),
                ("law", "law", "s"),
                ("alpha_bias", "mean-α bias", "+.1%"),
                ("alpha_rmse_8x8", "8×8 α RMSE", ".4f"),
                ("rgb_rmse_8x8", "8×8 RGB RMSE", ".4f"),
                ("frame_cpu_s", "frame CPU s", ".2f"),
            ],
        )
    )
    save(f"oblique_laws_{a.resolution}" + (f"_grid{a.grid}" if a.grid else ""), {"rows": rows})


if __name__ == "__main__":
    main()
