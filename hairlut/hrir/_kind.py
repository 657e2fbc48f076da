"""The ``hrir_db`` table kind: its declaration for :mod:`hairlut.registry` (light: no JAX).

The baker, reader and merge live in ``_bake`` and ``_io`` and are imported on first call.
"""

from __future__ import annotations

import numpy as np

from ..baker import Baker, Bound, Option, Units, deferred
from ._recipe import SCHEMA, resolve_recipe

KIND = "hrir_db"
SHARD_KIND = "hrir_shard"

#: HRIR tracer throughput, (sector · view · light · pixel · step · ray) per second, with and without
#: in-sector self-shadowing (benchmarks/hrir_bake.py: 35 and 49 sectors/s at 32 × 32 angles, 64², 2 cores).
TRACE_RATE = {True: 1.47e8, False: 2.07e8}
#: Start-up of a bake (imports, jit compilation), seconds.
BAKE_OVERHEAD = 6.0


#: The recipe keys that drive the traced tables (named when a table is refused): the optical depth's and the shading's.
DEPTH_KEYS = ("trace.extinction", "sectors.density_scale", "sectors.space.radial_extent", "sectors.space.radius_rel")
SHADING_KEYS = ("phong.ambient", "phong.diffuse", "phong.specular", "phong.shininess")


def phong_sum(recipe: dict, tables=None) -> float:
    """k_a + k_d + k_s: the most a unit of opacity reflects (re = k_a α + Σ w (k_d max(0, n·l) + k_s spec), each
    factor of k_d and k_s at most 1, Σ w = α), so re ≤ α·(k_a + k_d + k_s)."""
    p = recipe["phong"]
    return float(p["ambient"] + p["diffuse"] + p["specular"])


#: The physical bounds of the traced tables (hairlut.assets.bounds): checked on every part and asset written.
BOUNDS = (
    Bound("alpha", 0.0, 1.0, keys=DEPTH_KEYS, text="0 ≤ α ≤ 1"),
    Bound("reflectance", 0.0, 1.0, of="alpha", scale=phong_sum, keys=DEPTH_KEYS + SHADING_KEYS,
          text="0 ≤ re ≤ α·(k_a + k_d + k_s)"),
    Bound("density", 0.0, None, keys=("sectors.density_scale", "sectors.grid", *DEPTH_KEYS[2:]), text="ρ ≥ 0"),
    Bound("geometry/*", None, None, keys=DEPTH_KEYS, text="finite"),
)


def estimate(recipe: dict) -> tuple[int, float]:
    """(bytes, seconds) of a bake: the α and reflectance tables dominate the file; tracing the time."""
    r = resolve_recipe(recipe)
    n, a, t = r["sectors"]["count"], r["angles"], r["trace"]
    work = n * a["views"] * a["lights"] * t["pixels"] * t["steps"] * t["rays_per_pixel"]
    seconds = BAKE_OVERHEAD + work / TRACE_RATE[t["self_shadow"]]
    item = np.dtype(r["storage"]["dtype"]).itemsize
    return int(item * n * a["views"] * t["pixels"] * (a["lights"] + 1)), float(seconds)


def _bake(recipe, out, *, progress=None, shard=None, block=None, keep_parts=False, distributed=False, merge=None):
    from ._bake import bake

    return bake(recipe, out, shard=shard, block=block, progress=progress,
                keep_parts=keep_parts, distributed=distributed, merge=merge)


def _count(recipe, **_):
    return resolve_recipe(recipe)["sectors"]["count"]


def _check(recipe, path):
    from ._io import read_shard

    read_shard(path)  # every table and attribute a part must hold (a part of an older format is baked again)


def _budget(recipe, block, held, note=""):
    from ..budget import check_hrir

    check_hrir(recipe, block=block, held=held, note=note)


def _load(path):
    from ._io import load_hrir_db

    return load_hrir_db(path)


def _merge(shards, out):
    from ._bake import merge

    return merge(shards, out)


def describe(report: dict) -> list[str]:
    lo, hi = report["sector_range"]
    rate = report["computed"] / report["seconds"] if report["seconds"] > 0 else 0.0
    return [f"wrote {report['out']} ({report['kind']}, sectors {lo}..{hi - 1} of {report['total_sectors']}, "
            f"{report['bytes'] / 2**20:.1f} MiB) in {report['seconds']:.1f} s",
            f"  baked {report['computed']} sectors ({rate:.1f}/s), resumed {report['resumed']}"]


BAKER = Baker(
    kind=KIND,
    command="hrir",
    description="HRIR database: planar ray-traced sectors (satf §4-5)",
    required=("features", "alpha", "reflectance"),
    schema=SCHEMA,
    resolve_recipe=resolve_recipe,
    bake=_bake,
    load=_load,
    estimate=estimate,
    describe=describe,
    options=(
        Option("block", int, None, "Sectors per resumable part (OUT.parts/); does not change the result.  Default: "
               "32, or up to a 16th of a large bake as the device's memory allows (32 with --shard/--distributed).",
               minimum=1),
        Option("keep_parts", bool, False, "Keep OUT.parts/ after the final file is written."),
    ),
    unit="sectors",
    shard_kind=SHARD_KIND,
    shard_required=("alpha", "reflectance", "density"),
    bounds=BOUNDS,
    merge=_merge,
    units=Units("sector", _count, deferred(f"{__package__}._bake", "bake_part"), deferred(f"{__package__}._bake", "join_parts"),
                deferred(f"{__package__}._bake", "assemble_parts"), deferred(f"{__package__}._parts", "whole"), block=32,
                check=_check, budget=_budget, index=deferred(f"{__package__}._parts", "part_index")),
    help="""HRIR database: planar ray tracing of random generalized sectors (satf §5).

    Resumable: finished blocks are kept in OUT.parts/; rerun the same command after an
    interruption and it continues, writing the same bytes as an uninterrupted bake.
    With --shard K/N it bakes the K-th of N slices into an hrir_shard file; `hairlut merge`
    joins them into the same bytes as a one-shot bake.  Sectors are spread over every
    local device; with --distributed each of JAX's processes bakes its share and process
    0 writes OUT as HDF5 virtual datasets over OUT.parts/ (--merge copy: one file).

    \b
    Examples:
      hairlut bake hrir --recipe tables/hrir-default.toml --out tables/hrir-default.h5
      hairlut bake hrir --recipe tables/hrir-default.toml --out s0.h5 --shard 0/2
      hairlut bake hrir --recipe tables/hrir-default.toml --out s1.h5 --shard 1/2
      hairlut merge s0.h5 s1.h5 --out tables/hrir-default.h5
      hairlut bake hrir --set sectors.count=64        # into the table cache (tables/)
      hairlut bake hrir --recipe r.toml --out db.h5 --distributed \\
          --coordinator 10.0.0.1:12355 --num-processes 2 --process-id 0   # and --process-id 1 elsewhere
    """,
)
