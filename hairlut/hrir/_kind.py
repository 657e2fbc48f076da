"""The ``hrir_db`` table kind: its declaration for :mod:`hairlut.bake.registry` (light: no JAX).

The baker, reader and merge live in ``_bake`` and ``_io`` and are imported on first call.
"""

from __future__ import annotations

import numpy as np

from ..bake.protocol import Baker, Bound, Units, deferred
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
    Bound(
        "reflectance", 0.0, 1.0, of="alpha", scale=phong_sum, keys=DEPTH_KEYS + SHADING_KEYS, text="0 ≤ re ≤ α·(k_a + k_d + k_s)"
    ),
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


def _part(name: str):
    return deferred(f"{__package__}._parts", name)


def describe(report: dict) -> list[str]:
    lo, hi = report["unit_range"]
    rate = report["computed"] / report["seconds"] if report["seconds"] > 0 else 0.0
    return [
        f"wrote {report['out']} ({report['kind']}, sectors {lo}..{hi - 1} of {report['total_units']}, "
        f"{report['bytes'] / 2**20:.1f} MiB) in {report['seconds']:.1f} s",
        f"  baked {report['computed']} sectors ({rate:.1f}/s), resumed {report['resumed']}",
    ]


BAKER = Baker(
    kind=KIND,
    command="hrir",
    description="HRIR database: planar ray-traced sectors (satf §4-5)",
    required=("features", "alpha", "reflectance"),
    schema=SCHEMA,
    resolve_recipe=resolve_recipe,
    bake=None,
    load=deferred(f"{__package__}._io", "load_hrir_db"),
    estimate=estimate,
    describe=describe,
    unit="sectors",
    shard_kind=SHARD_KIND,
    shard_required=("alpha", "reflectance", "density"),
    bounds=BOUNDS,
    units=Units(
        "sector",
        lambda recipe, **_: recipe["sectors"]["count"],
        deferred(f"{__package__}._bake", "bake_part"),
        deferred(f"{__package__}._bake", "join_parts"),
        deferred(f"{__package__}._bake", "assemble_parts"),
        _part("whole"),
        block=deferred(f"{__package__}._bake", "auto_block"),
        check=_part("check"),
        budget=_part("budget"),
        index=_part("part_index"),
        block_help="Default: 32, or up to a 16th of a large bake as the device's memory allows (32 with --shard/--distributed).",
    ),
    help="""HRIR database: planar ray tracing of random generalized sectors (satf §5).""",
    examples=(
        "hairlut bake hrir --recipe tables/hrir-default.toml --out tables/hrir-default.h5",
        "hairlut bake hrir --recipe tables/hrir-default.toml --out s0.h5 --shard 0/2",
        "hairlut bake hrir --recipe tables/hrir-default.toml --out s1.h5 --shard 1/2",
        "hairlut merge s0.h5 s1.h5 --out tables/hrir-default.h5",
        "hairlut bake hrir --set sectors.count=64        # into the table cache (tables/)",
        "hairlut bake hrir --recipe r.toml --out db.h5 --distributed \\",
        "    --coordinator 10.0.0.1:12355 --num-processes 2 --process-id 0   # and --process-id 1 elsewhere",
    ),
)
