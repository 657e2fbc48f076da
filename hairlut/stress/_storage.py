"""Stress cases for float16 storage: every table kind hairlut bakes (``hrir_db``, ``sh_tables``,
``scene_maps``, ``hair_bsdf``), baked twice from one recipe (float16 and a wider storage dtype) through the
registry, then read back with :func:`hairlut.assets.read_table`.

The bound is float16's own: round-to-nearest changes a value by at most half an ulp, a relative
error ≤ 2⁻¹¹ for normal numbers and ≤ 2⁻²⁵ absolute below 2⁻¹⁴ (subnormals).  The metric
max |x₁₆ − x| / max(|x|, 2⁻¹⁴) folds both into one number bounded by 2⁻¹¹; a value beyond
float16's range (65504) is a fault, never a silent Inf.
"""

from __future__ import annotations

import numpy as np

from ._tally import Case

#: float16 unit roundoff: round-to-nearest moves a value by ≤ 2⁻¹¹ of itself (≤ 2⁻²⁵ absolute below 2⁻¹⁴).
FLOAT16_BOUND = 2.0**-11
SMALLEST_NORMAL = 2.0**-14

HRIR = {"sectors": {"count": 6, "grid": [8, 8]}, "angles": {"views": 4, "lights": 3}, "trace": {"pixels": 8, "steps": 16}}
SH = {"kernel": {"p": 20.0}, "bands": {"transmittance": 2}, "dense": {"t_resolution": 2, "theta_v_steps": 5}}
#: A tiny two-cluster scene (the scene schema's [[clusters]] keys) for the ``scene_maps`` kind.
SCENE = {
    "render": {"resolution": [16, 8], "method": "scene", "views": 8, "terms": 1, "shading_pixels": 8},
    "camera": {"view": [0.0, 0.2, 1.0]},
    "lights": {"directions": [[0.5, 0.7, 1.0]]},
    "strands": {"count": 20, "radius": 0.006, "seed": 3},
    "clusters": [
        {
            "trajectory": [[0.0, 1.0, 0.0], [0.05, 0.5, 0.1], [0.1, 0.0, 0.1]],
            "half_axis_a": 0.08,
            "half_axis_b": 0.06,
            "layer_radii": [0.6, 1.0],
            "core_radius": 0.2,
            "s_t": 4,
            "s_u": 4,
        }
    ],
    "tables": {"hrir": {"sectors": {"grid": [8, 8]}, "trace": {"pixels": 8, "steps": 12}}},
}


def rounding_error(stored, wide) -> np.ndarray:
    """|x₁₆ − x| / max(|x|, 2⁻¹⁴), elementwise (module docstring)."""
    x = np.asarray(wide, np.float64)
    return np.abs(np.asarray(stored, np.float64) - x) / np.maximum(np.abs(x), SMALLEST_NORMAL)


def _compare_files(tally, ctx, kind: str, half, wide) -> None:
    """Every float16 dataset of ``half`` against the same dataset of ``wide``."""
    from ..assets import read_table

    a, b = read_table(half), read_table(wide)
    seen = 0
    for name, var in a.variables.items():
        x16 = np.asarray(var.data)
        if x16.dtype != np.float16:
            continue
        seen += 1
        x = np.asarray(b[name], np.float64)
        over = int((np.abs(x) > np.finfo(np.float16).max).sum())
        if over:
            tally.fault(f"{kind} {name}: {over} values beyond float16's range")
        tally.finite(f"{kind} {name}", x16)
        tally.error(f"{kind} {name}", float(np.max(ctx.reference(x16, x))) if x.size else 0.0)
    if not seen:
        tally.fault(f"{kind}: the float16 bake stored no float16 dataset")
    tally.note(f"{kind}: {seen} float16 datasets")


def _hrir(tally, ctx):
    from ..hrir import bake

    half, wide = ctx.workdir / "h16.h5", ctx.workdir / "h32.h5"
    bake({**HRIR, "storage": {"dtype": "float16"}}, half)
    bake({**HRIR, "storage": {"dtype": "float32"}}, wide)
    _compare_files(tally, ctx, "hrir_db", half, wide)


def _sh(tally, ctx):
    from ..shtables import bake

    half, wide = ctx.workdir / "s16.h5", ctx.workdir / "s64.h5"
    bake({**SH, "dense": {**SH["dense"], "storage": "float16"}}, half)
    bake({**SH, "dense": {**SH["dense"], "storage": "float64"}}, wide)
    _compare_files(tally, ctx, "sh_tables", half, wide)


def _scene(tally, ctx):
    from ..bake import registry
    from ..planner import scene_maps_recipe
    from ..scene import resolve_scene

    sc = resolve_scene(SCENE)
    recipe = scene_maps_recipe(sc)
    half, wide = ctx.workdir / "m16.h5", ctx.workdir / "m32.h5"
    for path, dtype in ((half, "float16"), (wide, "float32")):
        registry.bake("scene_maps", {**recipe, "table": {**recipe["table"], "dtype": dtype}}, path, scene=sc)
    _compare_files(tally, ctx, "scene_maps", half, wide)


#: A tiny ``hair_bsdf`` recipe: every table, on a 4 × 3 × 2 grid and 2 × 3 coverage entries.
HAIR_BSDF = {"grid": {"resolution": [4, 3, 2]}, "coverage": {"resolution": [2, 3]}}


def _hair_bsdf(tally, ctx):
    from ..bake import registry

    half, wide = ctx.workdir / "b16.h5", ctx.workdir / "b64.h5"
    for path, dtype in ((half, "float16"), (wide, "float64")):
        registry.bake("hair_bsdf", {**HAIR_BSDF, "storage": {"dtype": dtype}}, path)
    _compare_files(tally, ctx, "hair_bsdf", half, wide)


_REASON = "float16 round-to-nearest: half an ulp, 2^-11 relative (2^-25 absolute below 2^-14)"

CASES = (
    Case(
        "storage.hrir_db_f16",
        "hrir_db α and reflectance stored as float16 vs float32",
        FLOAT16_BOUND,
        _REASON,
        rounding_error,
        _hrir,
    ),
    Case(
        "storage.sh_tables_f16",
        "sh_tables dense Rd, Rs stored as float16 vs float64",
        FLOAT16_BOUND,
        _REASON,
        rounding_error,
        _sh,
    ),
    Case(
        "storage.scene_maps_f16", "scene_maps tables stored as float16 vs float32", FLOAT16_BOUND, _REASON, rounding_error, _scene
    ),
    Case(
        "storage.hair_bsdf_f16",
        "hair_bsdf tables stored as float16 vs float64",
        FLOAT16_BOUND,
        _REASON,
        rounding_error,
        _hair_bsdf,
    ),
)
