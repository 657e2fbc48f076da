"""The strand render's cost before and after a change to ``hairlut/render/_strand_march.py``, in one run: the module
at a git revision (``--base``, default HEAD~1) is loaded beside the working tree's and both render the same frame
(``benchmarks/reference_convergence.py``'s crop of Ratboy, shadows on, the grid pattern both), alternating, CPU
seconds (process time) each; the images' largest difference is printed (float32 rounding expected).

Usage: python -m benchmarks.reference_cost [--base REV] [--level 2] [--crop 32] [--repeats 2]
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import json
import subprocess
import tempfile
import time
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from hairlut.bench import with_config
from hairlut.render import extinction, render_level, scene_camera, scene_strands, segment_lighting, segments_of
from hairlut.scene import load_scene

from ._common import ROOT, SCENES
from .reference_convergence import crop_camera


def load_at(rev: str):
    """``hairlut.render._strand_march`` as it was at ``rev`` (relative imports resolve in today's package)."""
    src = subprocess.run(
        ["git", "-C", str(ROOT), "show", f"{rev}:hairlut/render/_strand_march.py"], check=True, capture_output=True, text=True
    ).stdout
    path = Path(tempfile.mkdtemp()) / "_reference_base.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("hairlut.render._reference_base", path)
    mod = importlib.util.module_from_spec(spec)
    mod.__package__ = "hairlut.render"
    spec.loader.exec_module(mod)
    return mod


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--base", default="HEAD~1")
    ap.add_argument("--scene", default="ratboy")
    ap.add_argument("--level", type=int, default=2)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--crop", type=int, default=32)
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args(argv)
    path = next(s for s in SCENES if a.scene in s.stem)
    sc = with_config(load_scene(path), camera={"resolution": [a.resolution, a.resolution]})
    strands = scene_strands(sc)
    segs = segments_of(strands, extinction(sc))
    cam = scene_camera(sc, strands)
    lit = jnp.asarray(segment_lighting(sc, segs.tangent, cam.back, sc.lights, sc.light_colors), jnp.float32)
    cam = crop_camera(cam, segs, lit, sc.lights, a.crop) if a.crop else cam
    base = load_at(a.base)
    extra = {"lattice": False} if "lattice" in inspect.signature(render_level).parameters else {}
    fns = {
        "base": lambda st: base.render_level(segs, cam, lit, sc.lights, level=a.level, shadows=True, stats=st),
        "new": lambda st: render_level(segs, cam, lit, sc.lights, level=a.level, shadows=True, stats=st, **extra),
    }
    cpu, imgs, stats = {k: [] for k in fns}, {}, {}
    for f in fns.values():  # warm: compile both first
        f({})
    for _ in range(a.repeats):
        for k, f in fns.items():
            st = {}
            c0 = time.process_time()
            imgs[k] = f(st)
            cpu[k].append(time.process_time() - c0)
            stats[k] = {s: round(v, 3) for s, v in st.items() if s.endswith("seconds")}
    out = {
        "scene": path.stem,
        "level": a.level,
        "resolution": a.resolution,
        "crop": a.crop,
        "base": a.base,
        "cpu_s": {k: min(v) for k, v in cpu.items()},
        "ratio_new_over_base": min(cpu["new"]) / min(cpu["base"]),
        "max_abs_diff_rgba": float(np.abs(imgs["new"][..., :4] - imgs["base"][..., :4]).max()),
        "wall_stats": stats,
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
