"""What the layered model itself loses: one sector read per layer surface (satf §6.2.2) against the whole track a
camera ray crosses.  Two figures per phase count s_u, side by side:

* **measured**: the layered render (``hairlut.render.render_layered``, ``direct`` maps: each sector's own density
  projected at its exact angles) against the strand reference at level 0 (``render_strands``), mean-α bias over
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
sector and count its chord twice.  ``[render] layer_reads = "track"`` reads every sector the ray crosses in the
track instead (``hairlut.synth.sweep_sectors``); on the idealised disc it reads the whole chord by construction (the
tests check it against the analytic depth), so only the measured figures are given for it.  Per s_u and read the
rows also hold the 8 × 8-block RGB RMSE, the FLIP mean and the maps stage's wall and CPU seconds (the frame's
``maps`` time, one warm frame after the render's own).

With ``--paper``: only the maps stage's cost per read on the paper-scale model (:func:`paper_cost`).

Usage: python -m benchmarks.layer_reads [--scene S.toml] [--su 4 8 16] [--reads pair track] [--resolution 128]
[--no-render] [--paper]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from hairlut.bench import ring_model, with_config
from hairlut.render import compare, render_layered, render_strands
from hairlut.scene import load_scene
from hairlut.synth import prepare, render_view

from ._common import ROOT, best_wall_cpu, save, table


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


def paper_cost(frames: int = 5) -> list[dict]:
    """The part of the maps stage the read changes on the paper-scale model (``hairlut.bench.ring_model``: 17
    clusters × 3 layers, s_t 64, s_u 16, 64² texels): the sweep from every sector's rows to the texels
    (``sweep_sectors`` on fixed random rows of 32 pixels), best of ``frames``, wall and process time.  The rows
    themselves (the direct method's trace, the scene table's fetch) are the same for both reads."""
    import jax.numpy as jnp

    from hairlut.scene import resolve_scene
    from hairlut.synth import params_kernel, sweep_sectors

    rows = []
    for reads in ("pair", "track"):
        cfg = ring_model(17, 64, 16, 64, 200)
        cfg["render"].update(method="direct", layer_reads=reads)
        prep = prepare(resolve_scene(cfg, "paper-scale model"))
        ix, sc = prep.index, prep.scene
        f32 = np.float32
        _, _, cs, _, _ = params_kernel(ix, sc.view.astype(f32), sc.lights.astype(f32), f32(0.0), n_v=1, n_l=1)
        S, Lt = int(np.prod(ix.grid[:1]) * (ix.grid[1] + 1) * ix.grid[2] * ix.grid[3]), len(sc.lights)
        rng = np.random.default_rng(0)
        alpha = jnp.asarray(rng.uniform(0, 0.5, (S, 32)), jnp.float32)
        re = jnp.asarray(rng.uniform(0, 0.2, (S, Lt, 32)), jnp.float32)
        wall, cpu = best_wall_cpu(lambda: sweep_sectors(ix, alpha, re, cs), frames, warm=True)
        row = {
            "scene": "paper-scale",
            "reads": reads,
            "sweep_ms": 1e3 * wall,
            "sweep_cpu_ms": 1e3 * cpu,
            "texels": int(np.prod(ix.offset.shape[2:])),
            "sectors": S,
        }
        rows.append(row)
        print(row, flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(ROOT / "tables" / "scenes" / "sintel-groom.toml"))
    ap.add_argument("--su", type=int, nargs="+", default=[4, 8, 16])
    ap.add_argument("--reads", nargs="+", default=["pair", "track"], choices=["pair", "track"])
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--no-render", action="store_true", help="the geometric figures only")
    ap.add_argument("--paper", action="store_true", help="only the maps stage's cost on the paper-scale model")
    args = ap.parse_args()
    if args.paper:
        rows = paper_cost()
        print(
            table(
                rows,
                [
                    ("scene", "model", "s"),
                    ("reads", "reads", "s"),
                    ("sweep_ms", "sweep ms", ".1f"),
                    ("sweep_cpu_ms", "sweep CPU ms", ".1f"),
                ],
            )
        )
        save("layer_reads_paper", {"rows": rows})
        return
    sc = load_scene(args.scene)
    sc = with_config(sc, camera={"resolution": [args.resolution] * 2}, shadows={"method": "none"})
    radii = sc.config["groom"]["layer_radii"] if "groom" in sc.config else [0.5, 0.75, 1.0]
    truth = None
    if not args.no_render:
        t0 = time.perf_counter()
        truth = render_strands(sc, levels=[0])
        print(f"reference level 0: {time.perf_counter() - t0:.0f} s")
    rows = []
    for s_u in args.su:
        geo = {"geometric_tau_0.5": geometric_bias(s_u, radii, 0.5), "geometric_tau_2": geometric_bias(s_u, radii, 2.0)}
        for reads in args.reads:
            row = {
                "scene": Path(args.scene).stem,
                "s_u": s_u,
                "reads": reads,
                "layer_radii": list(radii),
                **(geo if reads == "pair" else {}),
            }
            if truth is not None:
                t0 = time.perf_counter()
                layered = with_config(sc, groom={"s_u": s_u}, render={"method": "direct", "layer_reads": reads})
                prep = prepare(layered)
                f = render_layered(layered, camera=truth.camera, prepared=prep)
                figs = compare(f, truth, flip=True)[0]
                w0, c0 = time.perf_counter(), time.process_time()
                timing = render_view(prep).stats["seconds"]  # one more (warm) frame: its maps stage
                row.update(
                    alpha_bias=figs["alpha_bias_relative"],
                    alpha_rmse_8x8=figs["alpha_rmse_8x8"],
                    rgb_rmse_8x8=figs["rgb_rmse_8x8"],
                    flip_mean=figs["flip_mean"],
                    maps_s=timing["maps"],
                    frame_cpu_s=time.process_time() - c0,
                    frame_wall_s=time.perf_counter() - w0,
                    seconds=time.perf_counter() - t0,
                )
            rows.append(row)
            print(row, flush=True)
    print(
        table(
            rows,
            [
                ("scene", "scene", "s"),
                ("s_u", "s_u", "d"),
                ("reads", "reads", "s"),
                ("alpha_bias", "measured mean-α bias", "+.1%"),
                ("alpha_rmse_8x8", "8×8 α RMSE", ".3f"),
                ("rgb_rmse_8x8", "8×8 RGB RMSE", ".4f"),
                ("flip_mean", "FLIP", ".3f"),
                ("maps_s", "maps s (warm)", ".2f"),
                ("geometric_tau_0.5", "geometric (τ 0.5)", "+.1%"),
                ("geometric_tau_2", "geometric (τ 2)", "+.1%"),
            ],
        )
    )
    save(f"layer_reads_{Path(args.scene).stem}_{args.resolution}", {"resolution": args.resolution, "rows": rows})


if __name__ == "__main__":
    main()
