"""What a scene's tables are made of and how its maps are made: the planner's choices and recipes.

:func:`choices` lists every knob the planner chooses for a scene (``hairlut.scene``'s rules, each a
:class:`~hairlut.scene.Choice` with its reason); :func:`direct_recipe` and :func:`scene_maps_recipe` are the
recipes the ``direct`` and ``scene`` map methods trace with (the sector grid and the scene table's layout folded
in as chosen); :func:`map_method` picks the map method by device, motion and memory and says why.
"""

from __future__ import annotations

from .. import budget, errors
from ..bake import registry
from ..scene import (
    Choice,
    SceneSectors,
    as_scene,
    cluster_choice,
    grid_choice,
    hrir_with_grid,
    layer_reads,
    layer_shells,
    scene_sectors,
    table_layout,
    texel_choice,
)

#: Largest share of the machine's memory a scene table may take for ``auto`` to pick the ``scene`` method.
SCENE_MEMORY_SHARE = 0.25
#: ``[render]`` knob of each scene_maps recipe key (for error messages).
_MAP_FIELDS = {
    "table.views": "render.views",
    "table.terms": "render.terms",
    "table.lights": "render.terms",
    "table.shading_pixels": "render.shading_pixels",
    "table.ratio_step": "render.ratio_step",
    "table.dtype": "render.precision",
}


def direct_recipe(scene) -> dict:
    """The HRIR recipe (trace, Phong, density grid) the ``direct`` and ``scene`` map methods trace
    with: the scene's ``[tables.hrir]`` over the defaults, the sector grid the scene leaves out chosen
    (:func:`hairlut.scene.sector_grid`), ``render.rays`` rays per pixel."""
    from ..hrir import resolve_recipe

    sc = as_scene(scene)
    given = hrir_with_grid(sc.config["tables"]["hrir"], grid_choice(sc))
    trace = {**given.get("trace", {}), "rays_per_pixel": sc.config["render"]["rays"]}
    try:
        return resolve_recipe({**given, "trace": trace})
    except errors.ValidationError as exc:
        raise errors.ValidationError(f"tables.hrir.{exc.field}", exc.value, exc.reason) from None


def scene_table_layout(scene, recipe: dict | None = None) -> tuple:
    """The scene table's ``render.views`` and ``render.shading_pixels`` (:func:`hairlut.scene.table_layout`, two
    :class:`~hairlut.scene.Choice`) on the sector grid and trace pixels of ``recipe`` (:func:`direct_recipe`)."""
    sc = as_scene(scene)
    rec = direct_recipe(sc) if recipe is None else recipe
    return table_layout(sc.config["render"], max(rec["sectors"]["grid"]), rec["trace"]["pixels"])


def scene_maps_recipe(scene) -> dict:
    """The ``scene_maps`` recipe of a scene (its groom's geometry key folded in): the trace settings of
    :func:`direct_recipe` and the table layout from ``render.views``, ``terms``, ``shading_pixels`` (``auto``:
    :func:`scene_table_layout`), ``ratio_step`` and ``precision`` (light angles: 4·terms + 1; on Sintel the re error at 2 terms was 0.147 at 9 and 16
    light angles and 0.149 at 5, ``benchmarks/scene_layouts.py``)."""
    from ..scenemaps import resolve_recipe

    sc = as_scene(scene)
    r, rec = sc.config["render"], direct_recipe(sc)
    views, bins = (c.value for c in scene_table_layout(sc, rec))
    given = {
        "hrir": {
            "sectors": {k: rec["sectors"][k] for k in ("grid", "density_scale")},
            "trace": rec["trace"],
            "phong": rec["phong"],
        },
        "table": {
            "views": views,
            "lights": 4 * r["terms"] + 1,
            "terms": r["terms"],
            "shading_pixels": bins,
            "ratio_step": r["ratio_step"],
            "dtype": r["precision"],
        },
    }
    try:
        return resolve_recipe(given, scene=sc)
    except errors.ValidationError as exc:
        name = _MAP_FIELDS.get(exc.field, exc.field.replace("hrir.", "tables.hrir.", 1))
        raise errors.ValidationError(name, exc.value, exc.reason) from None


def _sector_bound(sc) -> int:
    """An upper bound of a scene's sector count from its settings alone (no strands built)."""
    if sc.groom_path is not None:
        g = sc.config["groom"]
        return cluster_choice(sc).value * (g["s_t"] + 1) * len(g["layer_radii"]) * g["s_u"]
    return sum((s.s_t + 1) * s.n_layers * s.s_u for s in sc.specs)


def map_method(scene, sectors: int | None = None, live: int | None = None) -> tuple[str, str]:
    """The map method a scene runs (``direct``, ``scene`` or ``satf``) and why, in words.

    ``render.method`` unless it is ``auto``; then: on a GPU (or another accelerator), ``direct``;
    on the CPU with moving hair (``render.animated``), ``satf`` (a per-groom table would be stale once
    the hair moves and the exact projection costs seconds a view on a CPU); on the CPU with static hair,
    ``scene`` when its table fits in a quarter of the machine's memory, else ``satf``.  ``sectors``
    and ``live``: the scene's sector counts when known (an upper bound from its settings otherwise)."""
    sc = as_scene(scene)
    r = sc.config["render"]
    method = r["method"]
    words = {
        "direct": "every sector projected from its own density at the exact view and lights, each view",
        "scene": "the groom's own sector projections, baked once, read at the exact angles of each view",
        "satf": "the paper's SATF database lookup (no per-scene bake)",
    }
    if method != "auto":
        return method, f"render.method = {method!r}: {words[method]}"
    import jax

    backend = jax.default_backend()
    if backend != "cpu":
        return "direct", f"auto: the device is a {backend}, so {words['direct']} (no per-scene bake; hair may move)"
    if r["animated"]:
        return "satf", (
            "auto: the hair moves (render.animated) on the CPU: a per-groom table would be stale once the "
            f"hair moves and the exact projection costs seconds a view here, so {words['satf']}"
        )
    n = _sector_bound(sc) if sectors is None else int(sectors)
    nbytes, _ = registry.get("scene_maps").estimate(scene_maps_recipe(sc), n, live)
    mem = budget.physical_memory() or budget.FALLBACK
    if nbytes > SCENE_MEMORY_SHARE * mem:
        return "satf", (
            f"auto: static hair on the CPU, but its scene table (~{nbytes / 2**20:.0f} MiB) would exceed "
            f"{100 * SCENE_MEMORY_SHARE:.0f} % of the memory ({mem / 2**30:.0f} GiB), so {words['satf']}"
        )
    return "scene", (
        f"auto: static hair on the CPU, so {words['scene']} (~{nbytes / 2**20:.1f} MiB, {100 * nbytes / mem:.2f} % of the memory)"
    )


def choices(scene, ss: SceneSectors | None = None) -> list:
    """Every knob the planner chooses for ``scene`` (a :class:`hairlut.scene.Choice` each: as given, or chosen with
    its reason and the error the picture benchmark measured for it)."""
    sc = as_scene(scene)
    ss = scene_sectors(sc) if ss is None else ss
    return [
        cluster_choice(sc),
        layer_shells(sc.raw.get("groom", {}).get("layer_radii"), sc.config["groom"]["core_radius"])
        if sc.groom_path is not None
        else Choice("clusters.layers", [s.n_layers for s in sc.specs], True, "the layer shells of the scene's own [[clusters]]"),
        texel_choice(sc),
        grid_choice(sc, ss),
        *scene_table_layout(sc),
        layer_reads(sc.config["render"]["layer_reads"], int(len(ss.strands))),
        sc.shadow_choice,
    ]
