"""What ``[render] layer_reads = "track"`` costs against ``"pair"``: the eq 7 sweep from every sector's rows to
the texels (``hairlut.synth.sweep_sectors`` on fixed random rows of 32 pixels: the rows themselves, the direct
trace's or the scene table's fetch, are the same for both reads), per model, both reads in the same run, best
of ``--runs`` as process CPU time (every thread: the measure on a shared machine) and wall time.

Models: the paper-scale procedural model (``hairlut.bench.ring_model``: 17 clusters × 3 layers, s_t 64, s_u 16,
64² texels) and the vendored grooms' scenes (their own layout and camera resolution).
Writes benchmarks/results/track_cost.json.

Usage: python -m benchmarks.track_cost [--models paper sintel-groom ratboy-groom] [--runs 20]
"""

from __future__ import annotations

import argparse

import numpy as np

from hairlut.bench import ring_model, with_config
from hairlut.scene import load_scene, resolve_scene
from hairlut.synth import params_kernel, prepare, sweep_sectors

from ._common import ROOT, best_wall_cpu, save, table


def _scene(name: str, reads: str):
    if name == "paper":
        cfg = ring_model(17, 64, 16, 64, 200)
        cfg["render"].update(method="direct", layer_reads=reads)
        return resolve_scene(cfg, "paper-scale model")
    sc = load_scene(ROOT / "tables" / "scenes" / f"{name}.toml")
    return with_config(sc, render={"method": "direct", "layer_reads": reads}, shadows={"method": "none"})


def sweep_cost(name: str, runs: int) -> list[dict]:
    import jax.numpy as jnp

    rows = []
    for reads in ("pair", "track"):
        prep = prepare(_scene(name, reads))
        ix, sc = prep.index, prep.scene
        f32 = np.float32
        cs = params_kernel(ix, sc.view.astype(f32), sc.lights.astype(f32), f32(0.0), n_v=1, n_l=1)[2]
        S, Lt = int(ix.axes.shape[1]), len(sc.lights)
        rng = np.random.default_rng(0)
        alpha = jnp.asarray(rng.uniform(0, 0.5, (S, 32)), jnp.float32)
        re = jnp.asarray(rng.uniform(0, 0.2, (S, Lt, 32)), jnp.float32)
        wall, cpu = best_wall_cpu(lambda: sweep_sectors(ix, alpha, re, cs), runs, warm=True)
        rows.append(
            {
                "model": name,
                "reads": reads,
                "sectors": S,
                "texels": int(np.prod(ix.offset.shape[2:])),
                "sweep_ms": 1e3 * wall,
                "sweep_cpu_ms": 1e3 * cpu,
            }
        )
        print(rows[-1], flush=True)
    rows[-1]["ratio_cpu"] = rows[-1]["sweep_cpu_ms"] / rows[-2]["sweep_cpu_ms"]
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", default=["paper", "sintel-groom", "ratboy-groom"])
    ap.add_argument("--runs", type=int, default=20)
    args = ap.parse_args(argv)
    rows = [r for name in args.models for r in sweep_cost(name, args.runs)]
    print(
        table(
            rows,
            [
                ("model", "model", "s"),
                ("reads", "reads", "s"),
                ("sectors", "sectors", "d"),
                ("texels", "texels", "d"),
                ("sweep_ms", "sweep ms", ".1f"),
                ("sweep_cpu_ms", "sweep CPU ms", ".1f"),
                ("ratio_cpu", "track/pair CPU", ".1f"),
            ],
        )
    )
    print("(best of the runs; CPU ms: process CPU time, every thread)")
    save("track_cost", {"args": vars(args), "rows": rows})


if __name__ == "__main__":
    main()
