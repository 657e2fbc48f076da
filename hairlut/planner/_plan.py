"""The scene planner: the assets a scene needs, what the cache already holds, and the work it skips.

:func:`plan` reads a scene (:mod:`hairlut.scene` format) and decides, rule by rule, each in words:

* **Map method** (``[render] method``, :func:`map_method`): ``direct``, ``scene`` or ``satf``; ``auto``
  picks by device (a GPU: direct), motion (moving hair on a CPU: satf) and memory (static hair on a
  CPU: the per-groom ``scene_maps`` table when it fits in a quarter of the memory), and says why.
  The scene table is baked only for ``scene``, content-addressed by the groom's geometry and recipe.
* **HRIR database** (only for the ``satf`` map method, which reads it).  Its recipe is the
  defaults with ``[tables.hrir]`` over them; with ``tables.restrict`` (the default) the
  sampled sector space is fitted to the scene's own sectors (phase steps s_u exactly;
  aspect, inner radius, radial extent, strand count and relative strand radius over their ranges in
  the scene, widened by a margin): narrower where the scene uses less of the default
  space, so the same N records cover its features more densely, and wider where its
  sectors fall outside the defaults, which would not cover them.  A cached database is reused when its recipe hash matches, or
  when it differs only in a sector space that contains the scene's.  The in-plane view
  and light angles the scene's sectors produce are measured on the database's grid
  (with the neighbouring node bilinear interpolation reads); the grid is periodic, so the
  full circle is baked and the coverage is reported.
* **SH tables** only with an environment light: p = p_I sets the light bands,
  ceil(√p) + 1, i.e. (√p + 1)² coefficients (xing §4), and the specular energy left
  beyond them is reported; ks_I = ks_II = 0 (or both highlights off) bakes no Rs, kd = 0
  no Rd.  The light is projected (its hash is part of the recipe), so a new map re-bakes.
* **Voxel SH transmittance** only when an environment light and ``self_shadow`` are on.
* **Online work**: each shading term whose switch is off or whose coefficient is zero
  is skipped (no secondary highlight → none of its lighting or noise), and the uniformity
  test's fetch count follows k_threshold.
* **Hair BSDF tables** (``hair_bsdf``) only when the scene asks for them (``[tables] hair_bsdf = true``, or a
  table of recipe keys): an engine's Marschner-family hair shading reads them, hairlut's own online
  module (Kajiya–Kay) does not, so otherwise nothing reads them and the step is skipped, saying so.
* **Shadows** (``[shadows] method``): eq 12's s-map (``s_map``; off with k_shadow = 0 or
  ``effects.shadow`` off), or a light-oriented density map / opacity shadow maps per light
  (``shadow_maps``; built per scene in ``prepare``, rebuilt when the lights change), or none.

:func:`bake` carries a plan out through :mod:`hairlut.bake.registry` (and its cache) without
naming a kind; :func:`find_assets` gives the cached assets of a scene to ``synthesize``
without baking.  A bake's size and time are its kind's ``estimate`` (throughputs measured by
``benchmarks/hrir_bake.py`` and the plan part of ``hairlut bench`` on the 2-core development CPU;
that part reports them beside the real times).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from .. import budget, errors
from ..assets import recipe_hash
from ..bake import cache, registry
from ..scene import (
    Choice,
    SceneSectors,
    as_scene,
    cluster_choice,
    grid_choice,
    grid_coverage,
    hrir_with_grid,
    layer_reads,
    layer_shells,
    restricted_space,
    scene_sectors,
    table_layout,
    texel_choice,
)
from ._lighting import environment_bands, environment_light, sh_recipe

#: Voxel SH transmittance: casts (voxel · direction · step) per second (``hairlut bench --only plan``).
CAST_RATE = 6.0e7


@dataclass(frozen=True)
class Step:
    """One decision: ``action`` is ``bake``, ``reuse`` or ``skip`` for an asset, ``run`` or
    ``skip`` for online work; ``bytes`` and ``seconds`` are estimates for a bake, the file
    size for a reuse."""

    name: str
    action: str
    reason: str
    kind: str | None = None
    recipe: dict | None = None
    path: str | None = None
    bytes: int = 0
    seconds: float = 0.0
    details: dict = field(default_factory=dict)
    #: the kind's keyed bake inputs (e.g. the SH tables' ``light``): passed to the baker, not serialised
    inputs: dict = field(default_factory=dict, repr=False, compare=False)
    #: whether the online module reads the asset (``find_assets`` looks for those only)
    online: bool = True


@dataclass(frozen=True)
class Plan:
    """What :func:`plan` decided for ``scene``: its :class:`Step` s in order (``step(name)`` finds one) and the
    table cache they refer to; ``to_json()`` is the plan as ``hairlut plan --json`` prints it, with the totals
    to bake and to reuse."""

    scene: object
    steps: tuple
    cache_dir: str

    def step(self, name: str) -> Step:
        """The step called ``name`` (``hrir_db``, ``sh_tables``, ``map_method``, …)."""
        return next(s for s in self.steps if s.name == name)

    def to_json(self) -> dict:
        """The plan as ``hairlut plan --json`` prints it: the steps (without their bake inputs) and the bake/reuse
        totals."""
        return {
            "scene": self.scene.source,
            "cache": self.cache_dir,
            "steps": [{k: v for k, v in asdict(s).items() if k != "inputs"} for s in self.steps],
            "totals": {
                "bake_seconds": sum(s.seconds for s in self.steps if s.action == "bake"),
                "bake_bytes": sum(s.bytes for s in self.steps if s.action == "bake"),
                "reused_bytes": sum(s.bytes for s in self.steps if s.action == "reuse"),
            },
        }


# ----------------------------------------------------------------------------- rules


def _contains(outer: dict, inner: dict) -> bool:
    return all(
        k == "profile_weights"
        and outer[k] == inner[k]
        or k != "profile_weights"
        and outer[k][0] <= inner[k][0]
        and inner[k][1] <= outer[k][1]
        for k in inner
    )


def _cached(kind: str, recipe: dict, root) -> tuple[Path, bool]:
    path = cache.asset_path(kind, recipe, root)
    return path, cache.is_valid(path, kind, recipe_hash(recipe))


def _hrir_step(scene, ss: SceneSectors, root) -> Step:
    from ..hrir import resolve_recipe

    tab = scene.config["tables"]
    given = hrir_with_grid(tab["hrir"], grid_choice(scene, ss))
    try:
        base = resolve_recipe(given)
    except errors.ValidationError as exc:
        raise errors.ValidationError(f"tables.hrir.{exc.field}", exc.value, exc.reason) from None
    recipe = base
    details = {"sectors": int(len(ss.aspect)), "strands_per_sector": [int(ss.strands.min()), int(ss.strands.max())]}
    if tab["restrict"]:
        space = restricted_space(ss, base["sectors"]["space"])
        recipe = resolve_recipe({**given, "sectors": {**given["sectors"], "space": space}})
        details["space"] = {
            k: {"scene": space[k], "default": base["sectors"]["space"][k]}
            for k in space
            if space[k] != base["sectors"]["space"][k]
        }
    a = recipe["angles"]
    cov = {"views": grid_coverage(ss.theta_v, a["views"]), "lights": grid_coverage(ss.theta_l, a["lights"])}
    details["angle_coverage"] = cov
    nbytes, seconds = registry.get("hrir_db").estimate(recipe)
    angle_words = (
        f"the scene's sectors read {100 * cov['views']:.0f} % of the {a['views']} view and "
        f"{100 * cov['lights']:.0f} % of the {a['lights']} light grid angles; the grid is periodic, so the "
        "full circle is kept"
    )
    restrict_words = (
        (
            "sector space fitted to the scene's sectors ("
            + ", ".join(f"{k} {v['scene'][0]:.3g}–{v['scene'][1]:.3g}" for k, v in details.get("space", {}).items())
            + ")"
        )
        if tab["restrict"]
        else "sector space as given (tables.restrict = false)"
    )
    path, hit = _cached("hrir_db", recipe, root)
    if hit:
        return Step(
            "hrir_db",
            "reuse",
            f"recipe hash matches the cache; {angle_words}",
            "hrir_db",
            recipe,
            str(path),
            path.stat().st_size,
            0.0,
            details,
        )
    for e in cache.entries(root):
        if e.kind != "hrir_db":
            continue
        other = cache.recipe_of(e.path)
        same = {k: v for k, v in other.items() if k != "sectors"} == {k: v for k, v in recipe.items() if k != "sectors"}
        so, sr = other.get("sectors", {}), recipe["sectors"]
        if (
            same
            and all(so.get(k) == sr[k] for k in ("grid", "density_scale", "features"))
            and so.get("count", 0) >= sr["count"]
            and _contains(so["space"], sr["space"])
        ):
            return Step(
                "hrir_db",
                "reuse",
                f"cached database {e.path.name} samples a sector space that contains the "
                f"scene's, with ≥ {sr['count']} records; {angle_words}",
                "hrir_db",
                other,
                str(e.path),
                e.bytes,
                0.0,
                details,
            )
    return Step(
        "hrir_db",
        "bake",
        f"the SATF lookup needs it; {restrict_words}; {angle_words}",
        "hrir_db",
        recipe,
        str(path),
        nbytes,
        seconds,
        details,
    )


def _sh_step(scene, root) -> Step:
    from ..shtables import band_truncation_error, full_recipe

    env = scene.environment
    if env is None:
        return Step(
            "sh_tables",
            "skip",
            "no environment light: the scene is lit by its "
            f"{len(scene.lights)} directional light(s) alone, so no SH tables are needed",
        )
    given = sh_recipe(scene)
    if given is None:
        return Step(
            "sh_tables",
            "skip",
            "the environment light has nothing to shade: kd = 0 and ks_I = ks_II = 0 (or those effects are off)",
        )
    light = environment_light(scene)
    recipe = full_recipe(given, light)
    k, b = recipe["kernel"], recipe["bands"]
    words = [f"environment light {Path(env['map']).name}"]
    details = {"light_band_error": dict(zip(light.channels, light.band_error.tolist()))}
    if k["specular"]:
        err = band_truncation_error(k["p"], b["light_specular"])
        eb = environment_bands(scene)
        details["specular_truncation_error"] = err
        details["environment_bands"] = eb
        how = f"the fewest within environment.tolerance = {env['tolerance']:g}" if env["bands"] == "auto" else "environment.bands"
        words.append(
            f"{b['light_specular']} light bands ({how}): the environment radiance is within "
            f"{100 * eb['error']:.1f} % RMS of 30 bands (window {env['window']}; {100 * eb['clamped']:.1f} % of "
            f"(tangent, θ′) samples below 0 before the clamp; the lobe keeps all but {100 * err:.0f} % of its "
            f"L2 energy; the paper's ⌈√p⌉ + 1 = {eb['rule']} would leave {100 * eb['rule_error']:.1f} %)"
        )
    else:
        words.append("ks_I = ks_II = 0: no Rs")
    if not k["diffuse"]:
        words.append("kd = 0: no Rd")
    path, hit = _cached("sh_tables", recipe, root)
    if hit:
        return Step(
            "sh_tables",
            "reuse",
            "recipe hash matches the cache; " + "; ".join(words),
            "sh_tables",
            recipe,
            str(path),
            path.stat().st_size,
            0.0,
            details,
            {"light": light},
        )
    nbytes, seconds = registry.get("sh_tables").estimate(recipe)
    return Step("sh_tables", "bake", "; ".join(words), "sh_tables", recipe, str(path), nbytes, seconds, details, {"light": light})


def _hair_bsdf_step(scene, root) -> Step:
    """The hair BSDF tables: baked (or reused) when the scene asks for them, else skipped: nothing reads them."""
    from ..hairbsdf import resolve_recipe

    asked = scene.config["tables"]["hair_bsdf"]
    if asked is False:
        return Step(
            "hair_bsdf",
            "skip",
            "nothing reads it: hairlut's online module shades Kajiya–Kay (satf eqs 9–11); [tables] hair_bsdf = true "
            "bakes the hair BSDF tables an engine's Marschner-family shading reads",
            online=False,
        )
    try:
        recipe = resolve_recipe({} if asked is True else dict(asked))
    except errors.ValidationError as exc:
        raise errors.ValidationError(f"tables.hair_bsdf.{exc.field}", exc.value, exc.reason) from None
    g = recipe["grid"]
    words = (
        f"[tables] hair_bsdf asks for them (an engine's hair shading reads them, hairlut's does not): "
        f"{', '.join(t for t in ('dual_scattering', 'mean_energy', 'coverage') if recipe[t]['bake'])} on "
        f"{' × '.join(map(str, g['resolution']))} (sin θ × roughness × {recipe['absorption']['axis']})"
    )
    path, hit = _cached("hair_bsdf", recipe, root)
    if hit:
        return Step(
            "hair_bsdf", "reuse", "recipe hash matches the cache; " + words, "hair_bsdf", recipe, str(path),
            path.stat().st_size, online=False,
        )  # fmt: skip
    nbytes, seconds = registry.get("hair_bsdf").estimate(recipe)
    return Step("hair_bsdf", "bake", words, "hair_bsdf", recipe, str(path), nbytes, seconds, online=False)


def _transmittance_step(scene) -> Step:
    env = scene.environment
    if env is None:
        return Step("transmittance", "skip", "no environment light to shadow")
    if not env["self_shadow"]:
        return Step("transmittance", "skip", "environment.self_shadow is off: the environment is unoccluded")
    n = env["voxels"]
    casts = (n // 2) ** 3 * 64 * 2 * n  # (n/stride)³ voxels × directions × steps
    return Step(
        "transmittance",
        "run",
        f"environment light with self-shadowing: {n}³ voxel SH transmittance of the strands (xing §5), per scene",
        seconds=casts / CAST_RATE,
        bytes=4 * 9 * n**3,
        details={"voxels": n, "kappa": env["kappa"]},
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


def _map_steps(sc, ss: SceneSectors, root) -> tuple[str, list[Step]]:
    """The map method (and why), and its per-groom table when it needs one."""
    n, live = int(len(ss.strands)), int((ss.strands > 0).sum())
    method, why = map_method(sc, n, live)
    steps = [Step("map_method", "run", why, details={"method": method, "sectors": n, "live": live})]
    if method != "scene":
        steps.append(Step("scene_maps", "skip", f"the maps come from {method!r}: no per-groom table"))
        return method, steps
    recipe = scene_maps_recipe(sc)
    t = recipe["table"]
    words = (
        f"{live} of {n} sectors on {t['views']} views × {t['lights']} light angles, α ({t['dtype']}, mirror-"
        f"symmetric half) and {2 * t['terms'] + 1} re/α Fourier terms × {t['shading_pixels']} pixel bins; keyed by "
        f"the groom's geometry {recipe['geometry']['sha256'][:12]}…"
    )
    path, hit = _cached("scene_maps", recipe, root)
    details = {"sectors": n, "live": live, **t}
    if hit:
        steps.append(
            Step(
                "scene_maps",
                "reuse",
                "recipe hash matches the cache; " + words,
                "scene_maps",
                recipe,
                str(path),
                path.stat().st_size,
                0.0,
                details,
                {"scene": sc},
            )
        )
    else:
        nbytes, seconds = registry.get("scene_maps").estimate(recipe, n, live)
        steps.append(
            Step(
                "scene_maps",
                "bake",
                "the scene map method reads it: " + words,
                "scene_maps",
                recipe,
                str(path),
                nbytes,
                seconds,
                details,
                {"scene": sc},
            )
        )
    return method, steps


SHADOW_WORDS = {"light_oriented": "light-oriented density map (bertails §2–3)", "opacity_maps": "opacity shadow maps (kim ch. 6)"}


def _shadow_steps(scene) -> list[Step]:
    """The shadow seam: eq 12's s-map, a light-space map per light, or nothing, and why."""
    method, choice, cfg = scene.shadow_method, scene.shadow_choice, scene.config["shadows"]
    off = (
        "effects.shadow is off"
        if not scene.config["effects"]["shadow"]
        else "material.k_shadow = 0"
        if choice.value == "smap"
        else "shadows.method = 'none'"
        if choice.given
        else choice.reason
    )
    if method == "smap":
        smap = Step(
            "s_map",
            "run",
            f"eq 12 s-map from the outer layers' α (shadows.method = {choice.value!r}): one τ per texel for every light, "
            "no per-view map",
        )
    elif method == "none":
        smap = Step("s_map", "skip", f"{off}: τ = 1, no shadow work")
    else:
        smap = Step("s_map", "skip", f"shadows.method = {method!r}: each light's transmittance comes from its own map")
    if method in SHADOW_WORDS:
        n, k = cfg["resolution"], cfg["kappa"]
        size = f"{n + 1 + 2 * cfg['padding']}³ cells" if method == "light_oriented" else f"{cfg['slices']} slices of ~{n}² texels"
        kappa = "κ = the mean strand diameter" if k == "auto" else f"κ = {k:g}"
        maps = Step(
            "shadow_maps",
            "run",
            f"{SHADOW_WORDS[method]} of all strands, one per light ({len(scene.lights)}), "
            f"{size}, {kappa}, evaluated at the texels' 3-D positions; built in prepare (independent of the "
            "view), rebuilt only when the lights change",
            details={
                "method": method,
                "lights": len(scene.lights),
                **{key: cfg[key] for key in ("resolution", "kappa", "padding" if method == "light_oriented" else "slices")},
            },
        )
    else:
        maps = Step(
            "shadow_maps",
            "skip",
            "no light-space shadow map: " + ("eq 12's s-map from the α-maps needs none" if method == "smap" else off),
        )
    return [smap, maps]


def _online_steps(scene) -> list[Step]:
    fx, m, cfg = scene.effects, scene.material, scene.config["effects"]

    def why(name, coeff, key):
        return f"effects.{name} is off" if not cfg[name] else f"{key} = 0"

    out = [
        Step(
            "diffuse",
            "run" if fx["diffuse"] else "skip",
            "Kajiya–Kay diffuse, eq 9" if fx["diffuse"] else why("diffuse", m["kd"], "material.kd"),
        ),
        Step(
            "primary",
            "run" if fx["primary"] else "skip",
            "primary highlight, eq 10" if fx["primary"] else why("primary", m["ks_I"], "material.ks_I"),
        ),
        Step(
            "secondary",
            "run" if fx["secondary"] else "skip",
            "secondary highlight, eq 11"
            if fx["secondary"]
            else why("secondary", m["ks_II"], "material.ks_II") + ": no secondary lighting and no noise",
        ),
    ]
    if fx["secondary"]:
        out.append(
            Step(
                "noise",
                "run" if fx["noise"] else "skip",
                "noise-modulated secondary (Scheuermann)"
                if fx["noise"]
                else ("effects.noise is off" if not cfg["noise"] else "material.noise_amount = 0"),
            )
        )
    out.extend(_shadow_steps(scene))
    kt = m["k_threshold"]
    fetch = (
        "k_threshold = ∞: every HSV uniform, one fetch each"
        if math.isinf(kt)
        else "k_threshold = 0: every HSV fetches two HRIRs (eq 7)"
        if kt == 0
        else f"eq 6 test at k_threshold = {kt:g}: one fetch per uniform HSV, two otherwise"
    )
    out.append(Step("uniformity", "run", fetch))
    return out


def plan(scene, cache_root=None) -> Plan:
    """Decide, rule by rule, what ``scene`` needs (module docstring)."""
    sc = as_scene(scene)
    root = cache.cache_dir(cache_root)
    ss = scene_sectors(sc, root)
    method, map_steps = _map_steps(sc, ss, root)
    hrir = (
        _hrir_step(sc, ss, root)
        if method == "satf"
        else Step("hrir_db", "skip", f"the maps come from {method!r}: no SATF database is read")
    )
    online = _online_steps(sc)
    if method != "satf":
        online = [
            s
            if s.name != "uniformity"
            else Step("uniformity", "skip", f"{method!r} maps: every HSV sweeps its two sectors' own rows (eq 7), no eq 6 test")
            for s in online
        ]
    steps = [
        *_choice_steps(sc, ss),
        *map_steps,
        hrir,
        _sh_step(sc, root),
        _transmittance_step(sc),
        _hair_bsdf_step(sc, root),
        *online,
    ]
    return Plan(sc, tuple(steps), str(root))


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


def _choice_steps(sc, ss: SceneSectors) -> list[Step]:
    return [
        Step(
            c.key,
            "set" if c.given else "choose",
            f"{c.key} = {c.value!r}: {c.reason}" + (f" (measured: {c.predicted})" if c.predicted else ""),
            details=c.to_json(),
        )
        for c in choices(sc, ss)
    ]


# ----------------------------------------------------------------------------- carrying it out


def bake(p: Plan, progress=None) -> dict[str, dict]:
    """Bake (or reuse) every asset step of a plan through the registry and the cache;
    ``progress(name, done, total)``.  No kind is named here: each step carries its kind,
    recipe and keyed inputs.

    Returns {name: {"path", "status", "seconds"}} for the asset steps that are not skipped."""
    out = {}
    for s in p.steps:
        if s.kind is None or s.action == "skip":
            continue
        t0 = time.perf_counter()
        if s.action == "reuse":
            path, status = Path(s.path), "reused"
        else:
            cb = (lambda d, n, name=s.name: progress(name, d, n)) if progress else None
            path, status = registry.ensure(s.kind, s.recipe, p.cache_dir, cb, **s.inputs)
        out[s.name] = {"path": str(path), "status": status, "seconds": time.perf_counter() - t0}
    return out


def find_assets(scene, cache_root=None) -> dict[str, Path]:
    """The cached assets a scene needs, without baking: {"hrir_db" or "scene_maps": path[, "sh_tables": path]}
    (none of the two for the ``direct`` map method).

    Raises :class:`~hairlut.errors.AssetNotFoundError` naming the missing asset and the command that bakes it."""
    p = plan(scene, cache_root)
    out = {}
    for s in p.steps:
        if s.kind is None or s.action == "skip" or not s.online:
            continue
        if s.action != "reuse":
            bake_it = f"run `hairlut bake --scene {p.scene.source}` (or give its path)"
            if os.path.lexists(s.path):  # there, but unusable: say why rather than "not in the cache"
                try:
                    cache.check(Path(s.path), s.kind, recipe_hash(s.recipe))
                except errors.AssetError as exc:
                    why = exc.fault if exc.path == s.path else str(exc)  # a part's fault names the part
                    raise errors.CorruptAssetError(
                        s.path, f"the scene's cached {s.kind} is unusable ({why}); {bake_it} to bake it again"
                    ) from None
            raise errors.AssetNotFoundError(s.path, f"the scene's {s.kind} is not in the cache; {bake_it}")
        out[s.name] = Path(s.path)
    return out


def scene_assets(scene, cache_root=None, *, db=None, sh=None) -> tuple[str | None, str | None, str | None]:
    """(hrir_db, sh_tables, scene_maps) paths for rendering ``scene``: the given ``db``/``sh`` paths,
    and from the cache (:func:`find_assets`) what is missing; a scene table only when no database is
    given.  Paths are strings, ``None`` where the scene needs no such table."""
    maps = None
    if db is None or (sh is None and scene.environment is not None):
        found = find_assets(scene, cache_root)
        db = db or (str(found["hrir_db"]) if "hrir_db" in found else None)
        maps = str(found["scene_maps"]) if "scene_maps" in found and db is None else None
        sh = sh or (str(found["sh_tables"]) if "sh_tables" in found else None)
    return db, sh, maps
