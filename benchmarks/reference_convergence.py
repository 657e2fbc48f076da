"""The strand reference's convergence (issue 13): each level ℓ of ``hairlut.render.render_reference`` (2^ℓ × 2^ℓ
samples per pixel, 2^(ℓ+1) steps per crossing, shadows from the lights' grids at cell 4 r̄ / 2^ℓ while they are
small, else an exact shadow ray per step) on the vendored grooms, and its change from the level before: RMSE of the
premultiplied RGB and of α, what ``render_reference`` compares with its ``bound``.  For a bound B the reference is
converged at the first level whose change is below B, and verified when the next level's change is below B too.

Per level: CPU seconds (process time) and wall seconds, where the shadows came from, the shadow points; JSON in
benchmarks/results/reference_convergence.json (rows merged by scene and level, so levels can be run separately).

Usage: python benchmarks/reference_convergence.py [--scene sintel ratboy] [--levels 0 1 2] [--resolution 128]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from render import SCENES, with_config  # noqa: E402

from hairlut.render import render_reference  # noqa: E402
from hairlut.scene import load_scene  # noqa: E402

OUT = Path(__file__).resolve().parent / "results" / "reference_convergence.json"


def change(a, b) -> dict:
    """RMSE of premultiplied RGB and of α between two (h, w, 4) frames (``render_reference``'s convergence test)."""
    return {"rgb_rmse": float(np.sqrt(np.mean((a[..., :3] - b[..., :3]) ** 2))),
            "alpha_rmse": float(np.sqrt(np.mean((a[..., 3] - b[..., 3]) ** 2)))}


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", nargs="+", default=["sintel", "ratboy"])
    ap.add_argument("--levels", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--frames", default=None, help="folder to keep each level's RGBA (.npy), to extend a run later")
    args = ap.parse_args(argv)
    for name in args.scene:
        path = next(s for s in SCENES if name in s.stem)
        sc = with_config(load_scene(path), camera={"resolution": [args.resolution, args.resolution]})
        for lv in args.levels:
            t0, c0 = time.perf_counter(), time.process_time()
            f = render_reference(sc, levels=[lv])
            cpu, wall = time.process_time() - c0, time.perf_counter() - t0
            st = f.info["levels"][-1]
            row = {"scene": path.stem, "resolution": args.resolution, "level": lv, "cpu_s": cpu, "wall_s": wall,
                   "samples_per_pixel": st["samples_per_pixel"], "steps_per_crossing": st["steps_per_crossing"],
                   "shadow_source": st.get("shadow_source"), "shadow_cell": st.get("shadow_cell"),
                   "shadow_points": st.get("shadow_points"), "alpha_mean": float(f.rgba[..., 3].mean())}
            if args.frames:
                folder = Path(args.frames)
                folder.mkdir(parents=True, exist_ok=True)
                np.save(folder / f"{path.stem}_{args.resolution}_L{lv}.npy", f.rgba)
                prev = folder / f"{path.stem}_{args.resolution}_L{lv - 1}.npy"
                if prev.exists():
                    row["change_from_previous"] = change(f.rgba, np.load(prev))
            rows = json.loads(OUT.read_text())["rows"] if OUT.exists() else []  # another run may have added rows
            rows = [r for r in rows if (r["scene"], r["resolution"], r["level"]) != (path.stem, args.resolution, lv)]
            rows.append(row)
            print(json.dumps(row), flush=True)
            OUT.parent.mkdir(parents=True, exist_ok=True)
            OUT.write_text(json.dumps({"rows": sorted(rows, key=lambda r: (r["scene"], r["resolution"], r["level"]))},
                                      indent=1))


if __name__ == "__main__":
    main()
