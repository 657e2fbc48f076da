"""Why local devices run one single-device executable each: an SPMD bake is not bitwise equal (issue 16 item 2).

Traces the same 8 HRIR sectors (8 views × 8 lights, 16 px, 16 steps) four ways on 2 CPU devices
and compares each, bit for bit, with the executable `hairlut.bake.devices.map_units` runs (one sector
per call, ``trace_kernel(chunk=1)``): ``shard_map`` over a 1-D ``Mesh`` with one sector per device
per call (the same per-device shapes), ``shard_map`` with four sectors per device, ``jit`` on
``NamedSharding`` inputs (XLA's SPMD partitioner), and the one-device executable on two sectors per
call.  Reports values that differ, the largest difference in float32 ULPs and in absolute value.

    JAX_NUM_CPU_DEVICES=2 .venv/bin/python -m benchmarks.spmd_bits [--json benchmarks/results/spmd_bits.json]
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

os.environ.setdefault("JAX_PLATFORMS", "cpu")
os.environ.setdefault("JAX_NUM_CPU_DEVICES", "2")

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from hairlut.geometry import angle_grid
from hairlut.geometry.density import sector_density
from hairlut.hrir import resolve_recipe, sample_block, trace_kernel
from hairlut.march import sector_geometry

try:
    from jax import shard_map
except ImportError:  # older JAX
    from jax.experimental.shard_map import shard_map


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default="benchmarks/results/spmd_bits.json")
    a = ap.parse_args(argv)
    r = resolve_recipe(
        {"sectors": {"count": 8, "grid": [8, 8]}, "angles": {"views": 8, "lights": 8}, "trace": {"pixels": 16, "steps": 16}}
    )
    n = 8
    splats, params = sample_block(r, 0, n)
    dens = np.asarray(
        sector_density(splats, tuple(r["sectors"]["grid"]), density_scale=r["sectors"]["density_scale"], chunk=1), np.float32
    )
    tr, ph = r["trace"], r["phong"]
    geom = np.asarray(
        sector_geometry(params, kappa=tr["extinction"], n_pix=tr["pixels"], smooth_ratio=tr["smooth_ratio"]), np.float32
    )
    cfg = {
        "n_pix": tr["pixels"],
        "n_steps": tr["steps"],
        "rays": tr["rays_per_pixel"],
        "shadow": tr["self_shadow"],
        "smooth": tr["smooth"],
        "eps": float(tr["termination"]),
    }
    angles = np.asarray(angle_grid(8), np.float32)
    phong = np.asarray([ph["ambient"], ph["diffuse"], ph["specular"], ph["shininess"]], np.float32)

    def body(d, g):
        return trace_kernel(d, g, angles, angles, phong, chunk=1, **cfg)

    one = jax.jit(body)
    ref = [np.concatenate([np.asarray(one(dens[i : i + 1], geom[i : i + 1])[k]) for i in range(n)]) for k in range(2)]
    mesh = Mesh(np.array(jax.devices()[:2]), ("d",))
    sm = jax.jit(shard_map(body, mesh=mesh, in_specs=(P("d"), P("d")), out_specs=(P("d"), P("d"))))
    sh = NamedSharding(mesh, P("d"))
    ways = {
        "shard_map, 1 sector per device per call": lambda: [
            np.concatenate(x)
            for x in zip(*[[np.asarray(o) for o in sm(dens[s : s + 2], geom[s : s + 2])] for s in range(0, n, 2)])
        ],
        "shard_map, 4 sectors per device": lambda: sm(dens, geom),
        "jit on NamedSharding inputs": lambda: jax.jit(body)(jax.device_put(dens, sh), jax.device_put(geom, sh)),
        "one device, 2 sectors per call": lambda: [
            np.concatenate(x)
            for x in zip(*[[np.asarray(o) for o in one(dens[s : s + 2], geom[s : s + 2])] for s in range(0, n, 2)])
        ],
    }
    rows = []
    print(f"{'against one sector per call on one device':<40} {'table':>11} {'differ':>11} {'max ULP':>8} {'max abs':>9}")
    for name, fn in ways.items():
        got = fn()
        for k, table in enumerate(("alpha", "reflectance")):
            x, y = ref[k], np.asarray(got[k])
            ulp = np.abs(x.view(np.int32).astype(np.int64) - y.view(np.int32).astype(np.int64))
            row = {
                "way": name,
                "table": table,
                "differ": int((ulp != 0).sum()),
                "values": int(x.size),
                "max_ulp": int(ulp.max()),
                "max_abs": float(np.abs(x - y).max()),
            }
            rows.append(row)
            print(f"{name:<40} {table:>11} {row['differ']:>5}/{row['values']:<5} {row['max_ulp']:>8} {row['max_abs']:>9.1e}")
    doc = {"jax": jax.__version__, "backend": jax.default_backend(), "devices": len(jax.devices()), "rows": rows}
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    Path(a.json).write_text(json.dumps(doc, indent=2))
    return doc


if __name__ == "__main__":
    main()
