"""The ``scene_maps`` table kind: its declaration for :mod:`hairlut.bake.registry` (light: no JAX).

The scene is a keyed input: ``resolve_recipe(given, scene=...)`` folds its groom's geometry key
into the recipe (the cache key), and ``bake(recipe, out, scene=...)`` traces its sectors.  On the
command line ``--scene`` is the scene's TOML file.
"""

from __future__ import annotations

from ..bake.protocol import Baker, Bound, Option, Units, deferred
from ..hrir import phong_sum
from ._recipe import SCHEMA, hrir_recipe, resolve_recipe

KIND = "scene_maps"
SHARD_KIND = "scene_shard"
#: Table rows (non-empty sectors) per resumable part (``OUT.parts/``).
BLOCK = 64
#: Throughputs of the bake (``hairlut.march.bake_view_grid``), measured on 64 of the paper model's sectors
#: (benchmarks/scene_layouts.py --paper-subset, idle 2-core CPU, 0dd2ae1): re/α shading samples (kept view · light
#: · lane · step, self-shadowed; the dense count, of which the bake shades the live ones, 30 % on that model, so
#: thinner grooms bake faster than this says) per CPU second, α march samples (view · lane · step, V/2 views) per
#: CPU second, and the α projection's multiply-adds (2 · m² · V/2 · lanes with table.alpha_grid m) per CPU second
#: (measured under load, before 0dd2ae1).
SHADE_RATE = 4.4e8
MARCH_RATE = 6.2e7
PROJECT_RATE = 6.7e10
BAKE_OVERHEAD = 8.0
#: Non-empty sectors assumed per sector when the count is unknown (Sintel: 793 of 1,296; ratboy 2,217 of 2,592).
LIVE_FRACTION = 0.75


#: The recipe keys that drive the traced tables (named when a table is refused).
KEYS = (
    "hrir.trace.extinction",
    "hrir.sectors.density_scale",
    "hrir.phong.ambient",
    "hrir.phong.diffuse",
    "hrir.phong.specular",
    "hrir.phong.shininess",
)


def _reflect(recipe: dict, tables=None) -> float:
    """k_a + k_d + k_s of the recipe's trace: the ratio ρ = Σ re / Σ α lies in [0, k_a + k_d + k_s]."""
    return phong_sum(hrir_recipe(recipe))


#: The physical bounds of the tables (hairlut.assets.bounds): α in [0, 1]; the ratio's terms c₀ (the mean of ρ over
#: the lights) in [0, k_a + k_d + k_s] and a_k, b_k (twice a DFT term of ρ ≥ 0, at most 2 c₀) in ±2 (k_a + k_d + k_s).
BOUNDS = (
    Bound("alpha", 0.0, 1.0, keys=KEYS[:2], text="0 ≤ α ≤ 1"),
    Bound("ratio", 0.0, 1.0, scale=_reflect, at=(..., 0), keys=KEYS, text="0 ≤ c₀ ≤ k_a + k_d + k_s"),
    Bound("ratio", -2.0, 2.0, scale=_reflect, keys=KEYS, text="|a_k|, |b_k| ≤ 2 (k_a + k_d + k_s)"),
)


def estimate(recipe: dict, sectors: int = 1296, live: int | None = None) -> tuple[int, float]:
    """(bytes, seconds) of a bake of ``sectors`` sectors, ``live`` of them non-empty (by default
    :data:`LIVE_FRACTION` of them); the bytes are uncompressed (an upper bound), the seconds CPU seconds."""
    r = resolve_recipe(recipe)
    t, tr = r["table"], hrir_recipe(r)["trace"]
    n = int(sectors * LIVE_FRACTION) if live is None else int(live)
    item = 2 if t["dtype"] == "float16" else 4
    nbytes = (
        item * n * (t["views"] // 2 * tr["pixels"] + t["views"] // t["ratio_step"] * t["shading_pixels"] * (2 * t["terms"] + 1))
    )
    lanes, m = tr["pixels"] * tr["rays_per_pixel"], t["alpha_grid"]
    shade = (
        t["views"]
        // t["ratio_step"]
        * t["lights"]
        * tr["pixels"]
        * (t["shade_rays"] or tr["rays_per_pixel"])
        * (t["shade_steps"] or tr["steps"])
        / SHADE_RATE
    )
    alpha = 2 * m * m * t["views"] // 2 * lanes / PROJECT_RATE if m else t["views"] // 2 * lanes * tr["steps"] / MARCH_RATE
    return int(nbytes + 4 * sectors), BAKE_OVERHEAD + n * (shade + alpha)


def _load_scene(value, recipe, options):
    from ..scene import as_scene

    return as_scene(value)


def _part(name):
    return deferred(f"{__package__}._parts", name)


def describe(report: dict) -> list[str]:
    t = report["recipe"]["table"]
    lo, hi = report["unit_range"]
    rows = f"rows {lo}..{hi - 1} of {report['total_units']}, " if report["kind"] == SHARD_KIND else ""
    return [
        f"wrote {report['out']} ({report['kind']}, {rows}{report['bytes'] / 2**20:.1f} MiB) in {report['seconds']:.1f} s",
        f"  {report['total_units']} of {report['sectors']} sectors are table rows: traced {report['computed']}, resumed "
        f"{report['resumed']}, on {t['views']} views × {t['lights']} lights; {2 * t['terms'] + 1} ratio terms × "
        f"{t['shading_pixels']} bins ({t['dtype']}) on 1 view in {t['ratio_step']}; alpha "
        + (f"through a {t['alpha_grid']}² node grid" if t["alpha_grid"] else "by the tracer's march"),
    ]


BAKER = Baker(
    kind=KIND,
    command="scene_maps",
    description="per-groom sector projections: alpha on a view grid, re/alpha Fourier terms",
    required=("alpha", "ratio", "row"),
    schema=SCHEMA,
    resolve_recipe=resolve_recipe,
    bake=None,
    load=deferred(f"{__package__}._bake", "load_scene_maps"),
    estimate=estimate,
    describe=describe,
    options=(Option("scene", "path", None, "The scene (TOML) whose groom the table is baked for.", load=_load_scene),),
    keyed=("scene",),
    unit="sectors",
    shard_kind=SHARD_KIND,
    shard_required=("alpha", "ratio", "scene_index"),
    bounds=BOUNDS,
    units=Units(
        "sector",
        _part("count"),
        _part("bake_part"),
        _part("join"),
        _part("assemble"),
        _part("whole"),
        block=BLOCK,
        check=_part("check"),
        index=_part("part_index"),
        start=_part("start"),
        report=_part("report"),
    ),
    help="""Per-groom scene table: each sector's own projections (the `scene` map method).

    Traces every non-empty sector of the scene's groom on a grid of views and lights once;
    online, each sector's alpha and re rows are read at its exact angles.  Usually baked by
    the planner (hairlut bake --scene SCENE.toml) when the scene's render.method resolves to
    scene; its units are the table rows (the non-empty sectors).""",
    examples=(
        "hairlut bake scene_maps --scene tables/scenes/sintel-groom.toml",
        "hairlut bake scene_maps --scene tables/scenes/sintel-groom.toml --set table.views=128",
        "hairlut bake scene_maps --scene tables/scenes/sintel-groom.toml --out s0.h5 --shard 0/2   # and 1/2; then",
        "hairlut merge s0.h5 s1.h5 --out sintel-maps.h5",
    ),
)
