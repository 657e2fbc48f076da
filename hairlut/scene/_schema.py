"""Scene files (satf §6): clusters, strands, camera, lights, material, effects, shadows, tables.

A scene is a TOML mapping validated by :func:`resolve_scene` (every key path checked by
:mod:`hairlut.recipes`; an unknown, missing or out-of-range key raises
:class:`~hairlut.errors.ValidationError` naming it, e.g. ``material.kd`` or
``clusters[1].layer_radii``).  Clusters come either from ``[[clusters]]`` tables (the
:class:`~hairlut.geometry.ClusterSpec` fields) with procedural strands (``[strands]``), or
from ``[groom]``: a strand file whose strands are grouped into ``clusters`` fitted
clusters (:func:`~hairlut.geometry.fit_clusters`).  Directions point *toward* the viewer
and the lights (DESIGN.md).  A relative groom or environment-map path is resolved next to
the scene file (:func:`resolve_path`), and nowhere else.

``[shadows] method`` picks where each light's transmittance T at a texel comes from
(:data:`SHADOW_METHODS`): ``smap``, eq 12 from the α-maps (``material.k_shadow``,
``material.shadow_form``; the default); ``light_oriented``, the light-oriented density map
(bertails; ``resolution``, ``kappa``, ``padding``); ``opacity_maps``, opacity shadow maps
(kim ch. 6; ``resolution``, ``slices``, ``kappa``); or ``none``.  A key the chosen method
does not read is rejected (``shadows.slices`` with ``light_oriented``, say).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import budget, errors
from ..files import regular_file
from ..geometry.cluster_defaults import STRUCTURE_DEFAULTS as _D
from ..recipes import Field, get_path, load_toml, resolve
from ..validate import at_least as _int_at_least
from ..validate import auto_or, direction, float32, in_range, one_of
from ..validate import nonneg as _nonneg
from ..validate import positive as _pos
from ..validate import unit_interval as _unit_interval
from ._camera import CAMERA, check_camera, derive_view
from ._choices import CLUSTERS_MAX, Choice, shadow_method


def _colour(x):
    if len(x) != 3 or not all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in x):
        return "need 3 numbers (RGB)"
    return None if all(0 <= c <= 1 for c in x) else "colour components lie in [0, 1]"


def _pair(check):
    def run(x):
        if len(x) != 2 or not all(isinstance(c, int) and not isinstance(c, bool) for c in x):
            return "need 2 integers"
        return check(min(x))

    return run


#: Keys without a default, and why each is refused when missing.
REQUIRED = {
    "camera.view": "missing required key (or give both camera.position and camera.look_at: the view is derived from them)",
    "lights.directions": "missing required key",
}
#: Keys that were renamed: old dotted key → new one (an old key is refused naming the new one).
RENAMED = {"render.reference_bound": "render.strands_bound"}

#: ``[shadows] method``: where each light's transmittance at a texel comes from (eq 13 with one τ per light).
SHADOW_METHODS = ("auto", "smap", "light_oriented", "opacity_maps", "none")
#: ``[material] reflectance``: what eq 13 multiplies the lighting by (``hairlut.synth.shade_kernel``): ``unit``, each
#: layer reflects the lighting per unit of its opacity α, as the strand render shades each strand (the default);
#: ``hrir``, the paper's eq 13 as written, × the HRIR's accumulated Phong reflectance re.
REFLECTANCES = ("unit", "hrir")
#: The ``[shadows]`` keys each method reads (``smap`` reads material.k_shadow and material.shadow_form).
SHADOW_KEYS = {
    "auto": ("resolution", "slices", "kappa", "padding"),
    "smap": (),
    "none": (),
    "light_oriented": ("resolution", "kappa", "padding"),
    "opacity_maps": ("resolution", "slices", "kappa"),
}


#: ``[render] method``: how the online re- and α-maps are made.
MAP_METHODS = ("auto", "direct", "scene", "satf")
#: The ``[render]`` knobs each map method reads (``auto`` accepts them all: the planner picks the method).
MAP_KEYS = {"direct": ("rays",), "scene": ("rays", "views", "terms", "shading_pixels", "ratio_step", "precision"), "satf": ()}
MAP_KNOBS = ("rays", "views", "terms", "shading_pixels", "ratio_step", "precision")


def _kappa(x):
    if x == "auto":
        return None
    if isinstance(x, str) or not (math.isfinite(x) and x > 0):
        return "'auto' (the mean strand diameter) or a fibre width > 0"
    return None


_F, _I, _B, _L, _S = (float, int), (int,), (bool,), (list,), (str,)

SCHEMA = {
    "render": {
        "resolution": Field(
            "auto",
            (list, str),
            auto_or(_pair(_int_at_least(2))),
            "texels per layer: [u columns, t rows], or auto (the planner chooses from the camera: hairlut.scene.texel_resolution)",
        ),
        "background": Field([0.0, 0.0, 0.0], _L, _colour, "RGB behind the innermost layer (eq 14)"),
        "neighbours": Field(4, _I, _int_at_least(1), "k of the SATF k-NN lookup"),
        "preview_size": Field(256, _I, _int_at_least(16), "pixels of the orthographic preview"),
        "method": Field(
            "auto", _S, one_of(*MAP_METHODS), "how the re-/α-maps are made: auto (the planner chooses), direct, scene or satf"
        ),
        "animated": Field(False, _B, None, "the hair moves between frames (auto then never picks a per-groom table)"),
        "rays": Field(2, _I, in_range(1, 64), "direct and scene: rays per pixel of each sector's projection"),
        "views": Field(
            "auto",
            (int, str),
            auto_or(lambda x: None if isinstance(x, int) and 8 <= x <= 1024 and x % 2 == 0 else "an even number in [8, 1024]"),
            "scene: view angles of the per-groom table, or auto (the planner chooses from the sector grid: "
            "hairlut.scene.table_layout)",
        ),
        "terms": Field(2, _I, in_range(0, 16), "scene: Fourier terms of each sector's re/α ratio in θl − θv"),
        "shading_pixels": Field(
            "auto",
            (int, str),
            auto_or(in_range(1, 8192)),
            "scene: pixel bins of the re/α ratio (a divisor of tables.hrir trace.pixels), or auto (the planner chooses "
            "from the sector grid: hairlut.scene.table_layout)",
        ),
        "ratio_step": Field(
            2, _I, in_range(1, 1024), "scene: the re/α terms are kept on every ratio_step-th view (a divisor of views)"
        ),
        "precision": Field("float16", _S, one_of("float16", "float32"), "scene: storage precision of the per-groom table"),
        "strands_bound": Field(
            0.01,
            _F,
            in_range(1e-6, 1.0),
            "the strand render (render --strands): stop refining once one more level changes "
            "the RGB and α RMSE by less than this; the bound is stored in the frame",
        ),
        "layer_reads": Field(
            "auto",
            _S,
            one_of("auto", "pair", "track"),
            "what a layer texel reads: auto (the planner chooses: hairlut.scene.layer_reads), pair (eq 7: its HSV's two sectors) or track (every sector "
            "its in-plane ray crosses in its track, on its side of the chord: closer to the strands, "
            "a sweep ~5x costlier at paper scale, about as costly on the vendored grooms)",
        ),
    },
    "camera": CAMERA,
    "lights": {
        "directions": Field(None, _L, None, "list of directions toward the lights"),
        "colors": Field([], _L, None, "RGB intensity per light (default white)"),
    },
    "material": {
        "kd": Field(0.5, _F, _nonneg, "diffuse coefficient (eq 9)"),
        "ks_I": Field(0.3, _F, _nonneg, "primary specular coefficient (eq 10)"),
        "ks_II": Field(0.2, _F, _nonneg, "secondary specular coefficient (eq 11)"),
        "p_I": Field(80.0, _F, _pos, "primary exponent"),
        "p_II": Field(20.0, _F, _pos, "secondary exponent (Scheuermann: its own exponent)"),
        "shift": Field(0.1, _F, _nonneg, "tangent shift s along the normal (eqs 10, 11)"),
        "hair_color": Field([0.45, 0.3, 0.15], _L, _colour, "f_dif"),
        "spec_color_I": Field([1.0, 1.0, 1.0], _L, _colour, "f_speI (the light's colour)"),
        "spec_color_II": Field([1.0, 1.0, 1.0], _L, _colour, "f_speII when not tinted by the hair"),
        "secondary_hair_tint": Field(True, _B, None, "f_speII = hair_color × spec_color_II (eq 11, Scheuermann)"),
        "diffuse_scale": Field(1.0, _F, _nonneg, "Scheuermann: diffuse = max(0, scale·sin + bias); 1, 0 is eq 9"),
        "diffuse_bias": Field(0.0, _F, in_range(-1, 1), "see diffuse_scale"),
        "noise_amount": Field(0.5, _F, _unit_interval, "secondary modulated by 1 − amount·noise"),
        "noise_frequency": Field(8.0, _F, _pos, "noise lattice cells per unit of texture space"),
        # float32 in the kernel: exp(−k Σα) and max(0, 1 − k Σα) saturate for any finite k; an infinite one is inf · 0 = NaN
        "k_shadow": Field(0.5, _F, float32(_nonneg), "eq 12 self-shadow intensity"),
        "shadow_form": Field("exp", _S, one_of("exp", "linear"), "eq 12"),
        "reflectance": Field(
            "unit",
            _S,
            one_of(*REFLECTANCES),
            "eq 13's reflectance: unit (the lighting per unit of α, as the strands are shaded) or hrir (× the HRIR's re)",
        ),
        "k_threshold": Field(1.0, _F, lambda x: None if x >= 0 else "must be ≥ 0 (inf: always uniform)", "eq 6"),
    },
    "effects": {name: Field(True, _B, None, "") for name in ("diffuse", "primary", "secondary", "shadow")}
    | {"noise": Field(False, _B, None, "")},
    "environment": {
        "map": Field("", _S, None, "environment light: an EXR map (lat-long or cube), 'sky' (built in) or '' (none)"),
        "layout": Field("auto", _S, one_of("auto", "latlong", "cube"), "layout of an EXR map"),
        "up": Field("z", _S, one_of("z", "y"), "up axis of the map"),
        "intensity": Field(1.0, _F, _nonneg, "scale of the environment radiance"),
        "bands": Field(
            "auto",
            (int, str),
            auto_or(in_range(1, 65)),
            "light bands for Rs; auto: the fewest whose radiance is within tolerance of a 30-band reference",
        ),
        "tolerance": Field(
            0.015,
            _F,
            lambda x: None if 0 < x < 1 else "must lie in (0, 1)",
            "relative RMS radiance error that bands = auto allows (against 30 bands)",
        ),
        "window": Field(
            "none",
            _S,
            one_of("none", "hanning", "lanczos"),
            "σ-factors against SH ringing on the light and the voxel transmittance",
        ),
        "self_shadow": Field(False, _B, None, "shadow the environment with the strands' voxel SH transmittance (xing §5)"),
        "kappa": Field(0.5, _F, _pos, "extinction per unit of voxel strand density"),
        "voxels": Field(32, _I, in_range(8, 256), "voxel grid side"),
    },
    "shadows": {
        "method": Field(
            "auto",
            _S,
            one_of(*SHADOW_METHODS),
            "auto (the planner chooses: hairlut.scene.shadow_method), smap (eq 12 from the α-maps), "
            "light_oriented (bertails), opacity_maps (kim ch. 6) or none",
        ),
        "resolution": Field(
            32, _I, in_range(2, 512), "cells (light_oriented) or texels (opacity_maps) along the hair's longest extent"
        ),
        "slices": Field(16, _I, in_range(1, 256), "opacity_maps: depth slices"),
        "kappa": Field(
            "auto",
            (float, int, str),
            _kappa,
            "light-blocking width of a fibre, scene units ('auto': the "
            "mean strand diameter); τ = exp(−κ · hair length per unit area toward the light)",
        ),
        "padding": Field(2, _I, in_range(0, 16), "light_oriented: empty cells around the hair"),
    },
    "tables": {
        "hrir": Field({}, (dict,), None, "hrir_db recipe keys over the defaults (as hairlut bake hrir --set)"),
        "restrict": Field(True, _B, None, "restrict the database's sector space to the scene's own sectors"),
        "hair_bsdf": Field(
            False,
            (bool, dict),
            None,
            "bake the hair_bsdf tables an engine's hair shading reads: true (the defaults), or a table of hair_bsdf "
            "recipe keys over them (as hairlut bake hair_bsdf --set)",
        ),
    },
    "strands": {
        "count": Field(200, _I, _int_at_least(0), "strands per procedural cluster"),
        "radius": Field(0.004, _F, _pos, "metric strand radius"),
        "profile": Field("uniform", _S, one_of("uniform", "gaussian", "clumped"), ""),
        "spread": Field(0.35, _F, _pos, ""),
        "jitter": Field(0.0, _F, _nonneg, ""),
        "seed": Field(0, _I, _int_at_least(0), ""),
    },
}

CLUSTER = {
    "trajectory": Field(None, _L, None, "(n, 3) control points"),
    "half_axis_a": Field(None, (float, int, list), None, "A(t): a number or control values"),
    "half_axis_b": Field(None, (float, int, list), None, "B(t)"),
    "twist": Field(0.0, (float, int, list), None, "q(t)"),
    "layer_radii": Field(list(_D["layer_radii"]), _L, None, "shell radii (fractions)"),
    "core_radius": Field(_D["core_radius"], _F, _nonneg, ""),
    "s_t": Field(_D["s_t"], _I, _int_at_least(1), ""),
    "s_v": Field(_D["s_v"], _I, lambda x: None if x == 1 else "the online module maps one track per layer: use 1", ""),
    "s_u": Field(_D["s_u"], _I, _int_at_least(1), ""),
    "seed": Field(-1, _I, _int_at_least(-1), "strand seed (−1: derived from strands.seed and this table)"),
}

GROOM = {
    "path": Field(None, _S, None, "strand file (.tfx, .hair, .usda)"),
    "clusters": Field(
        "auto",
        (int, str),
        auto_or(_int_at_least(1)),
        "number of fitted clusters (auto: chosen from the groom's strand count and curl, hairlut.scene.cluster_count)",
    ),
    "radius": Field(0.1, _F, _pos, "metric strand radius when the file has no thickness"),
    "layer_radii": Field(list(_D["layer_radii"]), _L, None, ""),
    "core_radius": Field(
        0.0, _F, _nonneg, "no core: a groom's strands fill the whole cross-section (a 0.25 core held 6–30 % of their length)"
    ),
    "s_t": Field(_D["s_t"], _I, _int_at_least(1), ""),
    "s_u": Field(_D["s_u"], _I, _int_at_least(1), ""),
    "seed": Field(0, _I, _int_at_least(0), ""),
}


@dataclass(frozen=True, eq=False)
class Scene:
    """A validated scene: ``config`` (the resolved tables), cluster specs and the strand source."""

    config: dict
    specs: tuple
    cluster_seeds: tuple
    groom_path: Path | None
    view: np.ndarray
    lights: np.ndarray
    light_colors: np.ndarray
    source: str = "<mapping>"
    raw: dict = field(default_factory=dict)

    @property
    def material(self) -> dict:
        return self.config["material"]

    @property
    def effects(self) -> dict:
        """The switches the online module obeys: each effect as configured, and off when its
        coefficient is zero (no work is done for a term that contributes nothing)."""
        fx, m = self.config["effects"], self.material
        out = {
            "diffuse": fx["diffuse"] and m["kd"] > 0,
            "primary": fx["primary"] and m["ks_I"] > 0,
            "secondary": fx["secondary"] and m["ks_II"] > 0,
            "shadow": self.shadow_method != "none",
        }
        out["noise"] = fx["noise"] and out["secondary"] and m["noise_amount"] > 0
        return out

    @property
    def shadow_method(self) -> str:
        """The shadow method the online module runs: ``shadows.method``, or ``none`` when
        ``effects.shadow`` is off or the s-map's k_shadow is 0 (no shadow work at all)."""
        method = self.shadow_choice.value
        if not self.config["effects"]["shadow"] or method == "smap" and self.material["k_shadow"] <= 0:
            return "none"
        return method

    @property
    def shadow_choice(self) -> Choice:
        """``shadows.method`` as given, or as ``auto`` chooses it (:func:`hairlut.scene.shadow_method`), with the reason."""
        has_strands = self.groom_path is not None or self.config["strands"]["count"] > 0
        return shadow_method(self.config, self.raw, has_strands)

    @property
    def environment(self) -> dict | None:
        """The ``[environment]`` table, or None when the scene has no environment light."""
        env = self.config["environment"]
        return env if env["map"] else None


def _unit(name, value) -> np.ndarray:
    return direction(value, name)  # finite, non-zero 3 numbers, normalised (hairlut.validate)


def resolve_path(path: str, base: Path) -> Path:
    """A groom or environment-map path: absolute, or relative to ``base`` (the scene file's folder)."""
    p = Path(path)
    full = p if p.is_absolute() else base / p
    return regular_file(
        full, "a groom or environment map", missing=f"file not found ({path!r} is resolved next to the scene file)"
    )


def _cluster(i: int, given, strand_seed: int):
    from ..geometry import ClusterSpec

    where = f"clusters[{i}]."
    if not isinstance(given, Mapping):
        raise errors.ValidationError(f"clusters[{i}]", given, "expected a table of keys")
    for key in ("trajectory", "half_axis_a", "half_axis_b"):
        if key not in given:
            raise errors.ValidationError(where + key, None, "missing required key")
    c = resolve(CLUSTER, given, where)
    seed = c.pop("seed")
    if seed < 0:  # derived from the table's content, so a cluster's strands do not depend on its position
        text = json.dumps({k: given[k] for k in sorted(given)}, sort_keys=True, default=str)
        seed = int.from_bytes(hashlib.sha256(f"{strand_seed}:{text}".encode()).digest()[:4], "little")
    try:
        spec = ClusterSpec(**c)
    except errors.ValidationError as exc:
        raise errors.ValidationError(where + exc.field, exc.value, exc.reason) from None
    return spec, seed


def resolve_scene(given: Mapping, base_dir=None, *, source: str = "<mapping>") -> Scene:
    """Validate a scene mapping (module docstring); ``base_dir`` anchors relative paths."""
    if not isinstance(given, Mapping):
        raise errors.ValidationError("scene", type(given).__name__, "expected a table of keys")
    given = dict(given)
    clusters, groom = given.pop("clusters", None), given.pop("groom", None)
    if "camera" in given:
        given["camera"] = derive_view(given["camera"])
    for old, new in RENAMED.items():
        if get_path(given, old) is not None:
            raise errors.ValidationError(old, get_path(given, old), f"renamed: write {new} instead")
    for key, reason in REQUIRED.items():
        if get_path(given, key) is None:
            raise errors.ValidationError(key, None, reason)
    cfg = resolve(SCHEMA, given)
    method, shadow_given = cfg["shadows"]["method"], given.get("shadows", {})
    for key in shadow_given:
        if key != "method" and key not in SHADOW_KEYS[method]:
            raise errors.ValidationError(
                f"shadows.{key}",
                shadow_given[key],
                f"shadows.method = {method!r} does not read "
                f"it (it reads: {', '.join(SHADOW_KEYS[method]) or 'no [shadows] keys'})",
            )
    map_method, render_given = cfg["render"]["method"], given.get("render", {})
    for key in MAP_KNOBS:
        if key in render_given and map_method != "auto" and key not in MAP_KEYS[map_method]:
            raise errors.ValidationError(
                f"render.{key}",
                render_given[key],
                f"render.method = {map_method!r} does not "
                f"read it (it reads: {', '.join(MAP_KEYS[map_method]) or 'none of ' + ', '.join(MAP_KNOBS)})",
            )
    view = _unit("camera.view", cfg["camera"]["view"])
    check_camera(cfg["camera"])
    dirs = cfg["lights"]["directions"]
    if not dirs:
        raise errors.ValidationError("lights.directions", dirs, "give at least one light direction")
    lights = np.stack([_unit(f"lights.directions[{j}]", d) for j, d in enumerate(dirs)])
    cols = cfg["lights"]["colors"] or [[1.0, 1.0, 1.0]] * len(lights)
    if len(cols) != len(lights):
        raise errors.ValidationError("lights.colors", cols, f"need one RGB per light ({len(lights)})")
    for j, col in enumerate(cols):
        if not isinstance(col, list) or len(col) != 3 or not all(isinstance(x, (int, float)) and x >= 0 for x in col):
            raise errors.ValidationError(f"lights.colors[{j}]", col, "need 3 numbers ≥ 0")
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    env = cfg["environment"]
    if env["map"] not in ("", "sky"):
        env["map"] = str(resolve_path(env["map"], base))
    if (clusters is None) == (groom is None):
        raise errors.ValidationError("clusters", None, "give exactly one of [[clusters]] or [groom]")
    if groom is not None:
        if not isinstance(groom, Mapping):
            raise errors.ValidationError("groom", groom, "expected a table of keys")
        if "path" not in groom:
            raise errors.ValidationError("groom.path", None, "missing required key")
        g = resolve(GROOM, groom, "groom.")
        cfg["groom"] = g
        specs, seeds, gpath = (), (), resolve_path(g["path"], base)
    else:
        if not isinstance(clusters, list) or not clusters:
            raise errors.ValidationError("clusters", clusters, "need a non-empty array of cluster tables")
        made = [_cluster(i, c, cfg["strands"]["seed"]) for i, c in enumerate(clusters)]
        specs, seeds, gpath = tuple(m[0] for m in made), tuple(m[1] for m in made), None
        for i, s in enumerate(specs):
            if s.structure() != specs[0].structure():
                raise errors.ValidationError(
                    f"clusters[{i}]",
                    s.structure(),
                    f"layer count, s_t, s_v and s_u must agree across clusters ({specs[0].structure()})",
                )
    budget.check_scene(
        cfg,
        len(specs) if specs else (CLUSTERS_MAX if cfg["groom"]["clusters"] == "auto" else cfg["groom"]["clusters"]),
        specs[0].n_layers if specs else len(cfg["groom"]["layer_radii"]),
        len(lights),
        structure=("clusters[0]", specs[0].s_t, specs[0].s_u, _D)
        if specs
        else ("groom", cfg["groom"]["s_t"], cfg["groom"]["s_u"], _D),
    )
    return Scene(
        cfg,
        specs,
        seeds,
        gpath,
        view,
        lights,
        np.asarray(cols, np.float64),
        source,
        {**given, **({"clusters": clusters} if clusters is not None else {"groom": groom})},
    )


def load_scene(path) -> Scene:
    """Read and validate a scene TOML file (relative paths are taken from its folder)."""
    p = Path(path)
    return resolve_scene(load_toml(p), p.parent, source=str(p))


def as_scene(scene) -> Scene:
    """A Scene from a Scene, a mapping or a path."""
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, Mapping):
        return resolve_scene(scene)
    if isinstance(scene, (str, os.PathLike)):
        return load_scene(scene)
    raise errors.ValidationError("scene", type(scene).__name__, "give a Scene, a mapping or a TOML path")
