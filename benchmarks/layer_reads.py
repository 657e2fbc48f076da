"""What the layered model itself loses: one sector read per layer surface (satf §6.2.2) against the whole track a
camera ray crosses.  Two figures per phase count s_u, side by side:

* **measured**: the layered render (``hairlut.render.render_layered``, ``direct`` maps: each sector's own density
  projected at its exact angles) against the strand reference at level 0 (``render_reference``), mean-α bias over
  the frame (``compare``), on a groom scene at ``--resolution`` with ``[groom] s_u`` set to each value (the fit,
  its strands and the camera stay; shadows off: α does not depend on them);
* **geometric**: the same reads on an idealised cross-section: a uniform disc of radius 1 cut into the scene's
  tracks (no core; ``layer_radii``) and s_u phase sectors at a random rotation, an in-plane ray at a uniform offset.
  The layered model reads, per track, the sector where the ray enters the layer surface and the sector where it
  leaves it, each with that sector's full chord (the sector's own projection); the strands' truth is the ray's whole
  path through the disc.  Mean α = 1 − exp(−τ) for a density of optical depth ``tau`` across the diameter, model
  over truth.  No data from the scene but its layer radii: it isolates the reads from the maps, the fit and the
  rasteriser.

A ray near a layer's silhouette or through the innermost (pie-slice) track crosses several sectors and reads two:
the model loses optical depth the more sectors a track has; with few sectors the entry and exit fall in the same
sector and count its chord twice.

Usage: python benchmarks/layer_reads.py [--scene S.toml] [--su 4 8 16] [--resolution 128] [--no-render]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import save, table  # noqa: E402
from render import with_config  # noqa: E402

from hairlut.render import compare, render_layered, render_reference  # noqa: E402
from hairlut.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def geometric_bias(s_u: int, layer_radii, tau: float, rays: int = 1500, steps: int = 2001, seed: int = 0) -> float:
    """Relative mean-α bias of the layered reads on the uniform disc (module docstring), Monte Carlo over rays."""
    rng = np.random.default_rng(seed)
    bounds = np.concatenate([[0.0], np.asarray(layer_radii, np.float64)])
    du = 2 * np.pi / s_u
    ys = np.linspace(-1.0, 1.0, steps)
    dy = ys[1] - ys[0]
    density = tau / 2.0  # optical depth per unit path: τ across the diameter
    model, truth = np.empty(rays), np.empty(rays)
    for n in range(rays):
        x, rot = rng.uniform(-1.0, 1.0), rng.uniform(0.0, du)
        r = np.hypot(x, ys)
        k = (np.mod(np.arctan2(ys, x) - rot, 2 * np.pi) // du).astype(int)
        got = 0.0
        for g in range(len(bounds) - 1):
            lo, hi = bounds[g], bounds[g + 1]
            if abs(x) >= hi:
                continue
            track = (r >= lo) & (r < hi)
            yf = np.sqrt(hi * hi - x * x)
            for y in (yf, -yf):  # the ray's entry and exit on the layer surface: the sectors read there
                kk = int(np.mod(np.arctan2(y, x) - rot, 2 * np.pi) // du)
                got += (track & (k == kk)).sum() * dy
        model[n] = 1 - np.exp(-density * got)
        truth[n] = 1 - np.exp(-density * (r < bounds[-1]).sum() * dy)
    return float(model.mean() / truth.mean() - 1.0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(ROOT / "tables" / "scenes" / "sintel-groom.toml"))
    ap.add_argument("--su", type=int, nargs="+", default=[4, 8, 16])
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--no-render", action="store_true", help="the geometric figures only")
    args = ap.parse_args()
    sc = load_scene(args.scene)
    sc = with_config(sc, camera={"resolution": [args.resolution] * 2}, shadows={"method": "none"})
    radii = sc.config["groom"]["layer_radii"] if "groom" in sc.config else [0.5, 0.75, 1.0]
    truth = None
    if not args.no_render:
        t0 = time.perf_counter()
        truth = render_reference(sc, levels=[0])
        print(f"reference level 0: {time.perf_counter() - t0:.0f} s")
    rows = []
    for s_u in args.su:
        row = {"scene": Path(args.scene).stem, "s_u": s_u, "layer_radii": list(radii),
               "geometric_tau_0.5": geometric_bias(s_u, radii, 0.5), "geometric_tau_2": geometric_bias(s_u, radii, 2.0)}
        if truth is not None:
            t0 = time.perf_counter()
            f = render_layered(with_config(sc, groom={"s_u": s_u}, render={"method": "direct"}), camera=truth.camera)
            figs = compare(f, truth, flip=False)[0]
            row.update(alpha_bias=figs["alpha_bias_relative"], alpha_rmse_8x8=figs["alpha_rmse_8x8"],
                       seconds=time.perf_counter() - t0)
        rows.append(row)
        print(row, flush=True)
    print(table(rows, [("scene", "scene", "s"), ("s_u", "s_u", "d"), ("alpha_bias", "measured mean-α bias", "+.1%"),
                       ("alpha_rmse_8x8", "8×8 α RMSE", ".3f"), ("geometric_tau_0.5", "geometric (τ 0.5)", "+.1%"),
                       ("geometric_tau_2", "geometric (τ 2)", "+.1%")]))
    save("layer_reads", {"resolution": args.resolution, "rows": rows})


if __name__ == "__main__":
    main()
