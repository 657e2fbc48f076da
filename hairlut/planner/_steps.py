"""The plan's steps, rule by rule (the module docstring of ``_plan`` says what each decides): the HRIR database,
the SH tables, the hair BSDF tables, the voxel transmittance, the map method and its table, the shadows, the
online terms and the choices, each a :class:`Step` with its reason, size and time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from .. import errors
from ..assets import recipe_hash
from ..bake import cache, registry
from ..scene import (
    SceneSectors,
    grid_choice,
    grid_coverage,
    hrir_with_grid,
    restricted_space,
)
from ._lighting import environment_bands, environment_light, sh_recipe
from ._recipes import choices, map_method, scene_maps_recipe

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


def _asset_step(kind: str, recipe: dict, root, words: str, bake_words: str, estimate, **extra) -> Step:
    """The step of an asset whose cache entry is exactly ``recipe``: ``reuse`` when the cache holds it (its size),
    else ``bake`` with ``estimate()`` = (bytes, seconds); ``extra``: the Step's other fields."""
    path, hit = _cached(kind, recipe, root)
    if hit:
        return Step(
            kind, "reuse", "recipe hash matches the cache; " + words, kind, recipe, str(path), path.stat().st_size, **extra
        )
    nbytes, seconds = estimate()
    return Step(kind, "bake", bake_words, kind, recipe, str(path), nbytes, seconds, **extra)


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
    return _asset_step("hair_bsdf", recipe, root, words, words, lambda: registry.get("hair_bsdf").estimate(recipe), online=False)


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
    steps.append(
        _asset_step(
            "scene_maps",
            recipe,
            root,
            words,
            "the scene map method reads it: " + words,
            lambda: registry.get("scene_maps").estimate(recipe, n, live),
            details={"sectors": n, "live": live, **t},
            inputs={"scene": sc},
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
