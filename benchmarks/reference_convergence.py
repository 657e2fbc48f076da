"""The strand render's convergence (issue 13): each level ℓ of ``hairlut.render.render_strands`` (2^ℓ × 2^ℓ
samples per pixel, 2^(ℓ+1) steps per crossing, shadows from the lights' grids at cell 4 r̄ / 2^ℓ while they are
small, else an exact shadow ray per step) on the vendored grooms, and its change from the level before: RMSE of the
premultiplied RGB and of α, what ``render_strands`` compares with its ``bound``.  For a bound B the reference is
converged at the first level whose change is below B, and verified when the next level's change is below B too.

Per level: CPU seconds (process time) and wall seconds, where the time went (``render_level``'s stats), where the
shadows came from, the shadow points; JSON in benchmarks/results/reference_convergence.json (rows merged by scene,
resolution, crop, pattern, samples and steps, so levels can be run separately).

``--pattern grid|lattice``: the pixel samples (``_reference.pixel_offsets``).  ``--split``: at each level ℓ ≥ 1 also
the two half-refinements from ℓ − 1 (ℓ's samples with ℓ − 1's steps, and ℓ − 1's samples with ℓ's steps), so the
change of a level separates into pixel supersampling and step size.  ``--crop N``: the N × N block of the frame with
the most partial coverage (Σ α(1 − α) at level 0), same pixel size: a cheap, dense window for such studies.

Usage: python -m benchmarks.reference_convergence [--scene sintel ratboy] [--levels 0 1 2] [--resolution 128]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from hairlut.bench import with_config
from hairlut.render import extinction, render_level, scene_camera, scene_strands, segment_lighting, segments_of
from hairlut.scene import load_scene

from ._common import RESULTS, SCENES

OUT = RESULTS / "reference_convergence.json"
KEY = ("scene", "resolution", "crop", "pattern", "samples_per_pixel", "steps_per_crossing")


def change(a, b) -> dict:
    """RMSE of premultiplied RGB and of α between two (h, w, 4) frames (``render_strands``'s convergence test)."""
    return {
        "rgb_rmse": float(np.sqrt(np.mean((a[..., :3] - b[..., :3]) ** 2))),
        "alpha_rmse": float(np.sqrt(np.mean((a[..., 3] - b[..., 3]) ** 2))),
    }


def crop_camera(cam, segs, lit, lights, size: int):
    """The ``size`` × ``size`` window of orthographic ``cam`` with the most partial coverage at level 0."""
    a = render_level(segs, cam, lit, lights, level=0, shadows=False)[..., 3]
    h, w = cam.height // size, cam.width // size
    blk = a[: h * size, : w * size].reshape(h, size, w, size)
    by, bx = np.unravel_index(np.argmax((blk * (1 - blk)).sum((1, 3))), (h, w))
    per = cam.height / cam.extent  # pixels per world unit
    cx, cy = (bx * size + size / 2 - cam.width / 2) / per, (cam.height / 2 - by * size - size / 2) / per
    return dataclasses.replace(
        cam, eye=cam.eye + cx * cam.right + cy * cam.up, width=size, height=size, extent=cam.extent * size / cam.height
    )


def save_row(row: dict) -> None:
    rows = json.loads(OUT.read_text())["rows"] if OUT.exists() else []  # another run may have added rows
    rows = [r for r in rows if tuple(r.get(k) for k in KEY) != tuple(row.get(k) for k in KEY)]
    rows.append(row)
    print(json.dumps(row), flush=True)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({"rows": sorted(rows, key=lambda r: tuple(str(r.get(k)) for k in KEY))}, indent=1))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", nargs="+", default=["sintel", "ratboy"])
    ap.add_argument("--levels", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--pattern", choices=["grid", "lattice"], default=None, help="default: the reference's own")
    ap.add_argument("--split", action="store_true", help="also the half-refinements (samples only, steps only)")
    ap.add_argument("--crop", type=int, default=None, help="render only this N x N window (same pixel size)")
    ap.add_argument("--frames", default=None, help="folder to keep each level's RGBA (.npy), to extend a run later")
    args = ap.parse_args(argv)
    lattice = None if args.pattern is None else args.pattern == "lattice"
    for name in args.scene:
        path = next(s for s in SCENES if name in s.stem)
        sc = with_config(load_scene(path), camera={"resolution": [args.resolution, args.resolution]})
        strands = scene_strands(sc)
        cam = scene_camera(sc, strands)
        segs = segments_of(strands, extinction(sc))
        lit = jnp.asarray(segment_lighting(sc, segs.tangent, cam.back, sc.lights, sc.light_colors), jnp.float32)
        if args.crop:
            cam = crop_camera(cam, segs, lit, sc.lights, args.crop)
        shadows = sc.shadow_method != "none"
        tag = f"{path.stem}_{args.resolution}{f'c{args.crop}' if args.crop else ''}_{args.pattern or 'default'}"
        folder = Path(args.frames) if args.frames else None
        for lv in args.levels:
            runs = [(1 << lv, 2 << lv)]
            if args.split and lv >= 1:
                runs += [(1 << lv, 1 << lv), (1 << (lv - 1), 2 << lv)]
            for ss, steps in runs:
                st = {}
                t0, c0 = time.perf_counter(), time.process_time()
                img = render_level(
                    segs, cam, lit, sc.lights, level=lv, shadows=shadows, stats=st, samples=ss, steps=steps, lattice=lattice
                )[..., :4]
                cpu, wall = time.process_time() - c0, time.perf_counter() - t0
                row = {
                    "scene": path.stem,
                    "resolution": args.resolution,
                    "crop": args.crop,
                    "level": lv,
                    "cpu_s": cpu,
                    "wall_s": wall,
                    "alpha_mean": float(img[..., 3].mean()),
                    **{k: v for k, v in st.items() if not isinstance(v, (list, dict))},
                }
                if folder:
                    folder.mkdir(parents=True, exist_ok=True)
                    np.save(folder / f"{tag}_s{ss}_t{steps}.npy", img)
                    prev = folder / f"{tag}_s{1 << (lv - 1)}_t{1 << lv}.npy" if lv >= 1 else None
                    if prev is not None and prev.exists():
                        row["change_from_previous"] = change(img, np.load(prev))
                save_row(row)


if __name__ == "__main__":
    main()
