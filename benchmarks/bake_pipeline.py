"""Where an HRIR bake's time goes: tracing on the device against the host's work (sampling, compression, writes).

The bake overlaps the two (the devices trace block i + 1 while the host writes block i) and
compresses each table's chunks on every core (hairlut.assets.chunks).  This script measures the
pieces on their own, block by block, for the default recipe (``--quick``: 128 sectors), then a whole
bake, all after compilation, and prints:

- host preparation (sampling the sectors, their density grids and geometry) and tracing, summed over
  blocks, each waited for (wall and this process's CPU seconds);
- writing every block's α, reflectance and density tables with the filter pipeline (shuffle, gzip,
  fletcher32) on one thread and on every core (``HAIRLUT_WRITE_THREADS``);
- the whole bake (``hairlut.hrir.bake``: parts, then the assembled file) beside the serial sum of its
  pieces: below the sum where the overlap pays.

Usage: python -m benchmarks.bake_pipeline [--quick] [--json OUT]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from hairlut.assets import Axis, Variable, register_kind, write_table
from hairlut.assets.chunks import workers
from hairlut.geometry.density import sector_density
from hairlut.hrir import bake, resolve_recipe, sample_block, trace_sectors
from hairlut.march import sector_geometry

from ._common import emit, table

BLOCK = 32
register_kind("bench_block", ("alpha", "reflectance"), "a block of HRIR tables (benchmarks/bake_pipeline.py)")


class Clock:
    """Wall and CPU seconds summed over the timed sections."""

    def __init__(self):
        self.wall = self.cpu = 0.0

    def __call__(self, fn, *args, **kw):
        w, c = time.perf_counter(), time.process_time()
        out = fn(*args, **kw)
        self.wall += time.perf_counter() - w
        self.cpu += time.process_time() - c
        return out


def prepare(r: dict, start: int, stop: int):
    splats, params = sample_block(r, start, stop)
    rho = sector_density(splats, tuple(r["sectors"]["grid"]), density_scale=r["sectors"]["density_scale"], chunk=1)
    g = sector_geometry(
        params, kappa=r["trace"]["extinction"], n_pix=r["trace"]["pixels"], smooth_ratio=r["trace"]["smooth_ratio"]
    )
    return rho, g


def write_block(path: Path, rho, alpha, refl) -> None:
    """The block's tables with the chunks a part file uses (α by 16 sectors, reflectance by sector)."""
    n, V, L, P = refl.shape
    axes = [
        Axis("sector", np.arange(n), "1", "sector"),
        Axis("theta_v", np.arange(V, dtype=float), "rad", "view"),
        Axis("theta_l", np.arange(L, dtype=float), "rad", "light"),
        Axis("pixel", np.arange(P, dtype=float), "1", "px"),
        Axis("s", np.arange(rho.shape[1], dtype=float), "1", "s"),
        Axis("r", np.arange(rho.shape[2], dtype=float), "1", "r"),
    ]
    variables = [
        Variable("alpha", alpha, ("sector", "theta_v", "pixel"), "1", "alpha", chunks=(min(n, 16), V, P)),
        Variable("reflectance", refl, ("sector", "theta_v", "theta_l", "pixel"), "1", "re", chunks=(1, V, L, P)),
        Variable("density", rho, ("sector", "s", "r"), "1", "density", chunks=(min(n, 64), *rho.shape[1:])),
    ]
    write_table(path, "bench_block", {"bench": "bake_pipeline"}, axes, variables)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="128 sectors instead of the default recipe's 512")
    ap.add_argument("--json", type=Path, help="write the results here (default benchmarks/results/bake_pipeline.json)")
    a = ap.parse_args(argv)
    given = {"sectors": {"count": 128}} if a.quick else {}
    r = resolve_recipe(given)
    n = r["sectors"]["count"]
    blocks = [(s, min(s + BLOCK, n)) for s in range(0, n, BLOCK)]
    rho, g = prepare(r, 0, 1)
    trace_sectors(rho, g, r)  # compile
    prep, trace, one, every = Clock(), Clock(), Clock(), Clock()
    threads = workers()
    old = os.environ.get("HAIRLUT_WRITE_THREADS")
    with tempfile.TemporaryDirectory() as tmp:
        for s, e in blocks:
            rho, g = prep(prepare, r, s, e)
            alpha, refl = trace(trace_sectors, rho, g, r)
            for clock, t in ((one, 1), (every, threads)):
                os.environ["HAIRLUT_WRITE_THREADS"] = str(t)
                clock(write_block, Path(tmp) / f"{t}.h5", rho, alpha, refl)
        if old is None:
            os.environ.pop("HAIRLUT_WRITE_THREADS")
        else:
            os.environ["HAIRLUT_WRITE_THREADS"] = old
        w, c = time.perf_counter(), time.process_time()
        rep = bake(given, Path(tmp) / "db.h5", block=BLOCK)
        bake_wall, bake_cpu = time.perf_counter() - w, time.process_time() - c
    serial = prep.wall + trace.wall + every.wall
    rows = [
        {
            "what": f"host preparation: sampling, density grids, geometry ({len(blocks)} blocks)",
            "wall": prep.wall,
            "cpu": prep.cpu,
        },
        {"what": "tracing, each block waited for", "wall": trace.wall, "cpu": trace.cpu},
        {"what": "writing the blocks' tables, 1 thread", "wall": one.wall, "cpu": one.cpu},
        {
            "what": f"writing the blocks' tables, {threads} threads",
            "wall": every.wall,
            "cpu": every.cpu,
            "ratio": one.wall / every.wall,
        },
        {"what": "serial sum: preparation + tracing + writing (all threads)", "wall": serial},
        {"what": "bake(): parts, tracing overlapped with writing", "wall": rep["blocks_s"]},
        {"what": "bake(): assembling the final file from the parts", "wall": rep.get("assemble_s")},
        {"what": "bake(): whole", "wall": bake_wall, "cpu": bake_cpu, "ratio": serial / rep["blocks_s"]},
    ]
    print(
        f"## Where a bake's time goes: {n} sectors, {r['angles']['views']} x {r['angles']['lights']} angles, "
        f"{r['trace']['pixels']} px, {r['trace']['steps']} steps; blocks of {BLOCK}; {threads} write threads\n"
    )
    print(
        table(
            rows,
            [("what", "", "s"), ("wall", "wall s", ".2f"), ("cpu", "CPU s (this process)", ".2f"), ("ratio", "speed-up", ".2f")],
        )
    )
    print("\nspeed-up: writing, 1 thread over all threads; bake, the serial sum over the overlapped parts loop")
    emit(
        "bake_pipeline",
        {"recipe": r, "block": BLOCK, "threads": threads, "rows": rows, "block_seconds": rep.get("block_seconds")},
        a.json,
    )


if __name__ == "__main__":
    main()
