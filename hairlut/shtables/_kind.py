"""The ``sh_tables`` table kind: its declaration for :mod:`hairlut.bake.registry` (light: no JAX).

The environment light is a keyed input: ``resolve_recipe(given, light=EnvLight)`` folds its
identity into the recipe (so the cache key changes with the light) and
``bake(recipe, out, light=EnvLight)`` also bakes Cd/Cs.  On the command line ``--light`` is a
path (an EXR map, projected with ``--layout``/``--up`` to the recipe's bands, or an
``sh_light`` table).  The kind also declares ``sh_light``, the light's own asset.
"""

from __future__ import annotations

import numpy as np

from ..bake.protocol import Baker, Bound, Option, Units, deferred
from ._recipe import SCHEMA, light_bands, resolve_recipe

KIND = "sh_tables"
SHARD_KIND = "sh_shard"
#: Tangents per resumable part (``OUT.parts/``) of a bake with dense tables.
BLOCK = 512
LIGHT_KIND = "sh_light"
#: EXR environment-map layouts (``hairlut.envlight.LAYOUTS``, which needs JAX to import).
LAYOUTS = ("auto", "latlong", "cube")
#: Start-up of a bake (imports, jit compilation), seconds; the bake itself is far shorter.
BAKE_OVERHEAD = 4.0


#: The recipe keys that drive the tables (named when a table is refused).
KEYS = ("kernel.p", "bands.light_diffuse", "bands.light_specular", "bands.transmittance", "dense.storage")


def light_norm(recipe: dict, tables) -> float:
    """max over channels of ‖a‖₂, the light's SH coefficients (the table ``light/a``): |Cd|, |Cs| ≤ ‖a‖₂."""
    a = np.asarray(tables["light/a"][0], np.float64)
    return float(np.sqrt((a * a).sum(axis=0)).max(initial=0.0))


#: The physical bounds of the tables (hairlut.assets.bounds).  R(i, j, t) = ∫ Y_i Y_j K dω with a kernel 0 ≤ K ≤ 1
#: (sin θ; max(0, cos(π − θ − θ′))^p), so |R| ≤ ∫ |Y_i Y_j| ≤ 1 (Cauchy–Schwarz, orthonormal Y); C = Σ_i a_i R(i, ·)
#: = ∫ L Y_j K with L = Σ a_i Y_i, so |C| ≤ ‖L‖₂ = ‖a‖₂ per channel.
BOUNDS = (
    Bound("dense/rd", -1.0, 1.0, keys=KEYS, text="|Rd| ≤ 1"),
    Bound("dense/rs", -1.0, 1.0, keys=KEYS, text="|Rs| ≤ 1"),
    Bound("light/cd", -1.0, 1.0, scale=light_norm, keys=KEYS, text="|Cd| ≤ ‖a‖₂"),
    Bound("light/cs", -1.0, 1.0, scale=light_norm, keys=KEYS, text="|Cs| ≤ ‖a‖₂"),
)


def estimate(recipe: dict) -> tuple[int, float]:
    """(bytes, seconds) of a bake: the float64 Gaunt tensor dominates the file."""
    r = resolve_recipe(recipe)
    k, b = r["kernel"], r["bands"]
    li = max(b["light_specular"] if k["specular"] else 0, b["light_diffuse"])
    nbytes = 8 * (li + b["transmittance"] - 1) ** 2 * li**2 * b["transmittance"] ** 2
    return int(nbytes), BAKE_OVERHEAD


def load_light_option(value, recipe: dict, options: dict):
    """``--light``: an EnvLight as is; ``sky``, the built-in sky; else a path (EXR map or sh_light
    table), projected to the recipe's bands."""
    if hasattr(value, "coeffs"):
        return value
    from ..envlight import load_light, sky_light

    if str(value) == "sky":
        return sky_light(light_bands(recipe) - 1)
    return load_light(value, light_bands(recipe) - 1, options.get("layout") or "auto", options.get("up") or "z")


def _bake(name: str):
    return deferred(f"{__package__}._bake", name)


def _count(recipe, **_):
    n = recipe["dense"]["t_resolution"]
    return 6 * n * n  # the cube map's tangents


def describe(report: dict) -> list[str]:
    r = report["recipe"]
    b = r["bands"]
    lines = [
        f"wrote {report['out']} ({report['bytes'] / 1024:.1f} KiB) in {report['seconds']:.2f} s",
        f"  p = {r['kernel']['p']:.6g}; light bands diffuse {b['light_diffuse']} ({b['light_diffuse'] ** 2} coeffs), "
        f"specular {b['light_specular']} ({b['light_specular'] ** 2}); transmittance {b['transmittance']} "
        f"({b['transmittance'] ** 2})",
    ]
    if r["kernel"]["specular"]:
        lines.append(
            f"  θ′ dependence: {report['chebyshev_nodes']} Chebyshev nodes per half, series tail {report['chebyshev_tail']:.1e}"
        )
        lines.append(
            f"  specular energy beyond the light bands (relative L2, worst θ′): {report['specular_truncation_error']:.3e}"
        )
    if report.get("textures"):
        lines.append(f"wrote {report['textures']}")
    return lines


BAKER = Baker(
    kind=KIND,
    command="sh",
    description="exact SH convolution tables for Kajiya-Kay hair (xing §4)",
    required=("gaunt",),
    schema=SCHEMA,
    resolve_recipe=resolve_recipe,
    bake=_bake("bake_whole"),
    load=_bake("load_checked"),
    estimate=estimate,
    describe=describe,
    options=(
        Option("p", float, None, "Shortcut for --set kernel.p=P.", sets="kernel.p"),
        Option(
            "light",
            "path",
            None,
            "Environment map (.exr), sh_light table or `sky` (built-in): also bake Cd/Cs.",
            load=load_light_option,
        ),
        Option("layout", LAYOUTS, "auto", "Layout of an EXR --light."),
        Option("up", ("z", "y"), "z", "Up axis of an EXR --light."),
        Option(
            "textures",
            "path",
            None,
            "Also write Cd/Cs shader textures (EXR); needs --light and dense.t_resolution > 0.",
            cached=False,
        ),
    ),
    keyed=("light",),
    unit=None,  # a bake of seconds: no progress bar
    shard_kind=SHARD_KIND,
    shard_required=("dense/t_dirs",),
    bounds=BOUNDS,
    units=Units(
        "t",
        _count,
        *(_bake(f) for f in ("bake_part", "join_parts", "assemble_parts", "whole_parts")),
        block=BLOCK,
        check=_bake("check_part"),
        splits=lambda recipe: recipe["dense"]["t_resolution"] > 0,
        unsplit="SH tables split over their dense tangent grid: set dense.t_resolution > 0 (without dense "
        "tables a bake takes a second)",
        start=_bake("start"),
        report=_bake("report"),
        block_help=f"Default: {BLOCK} (dense tables only).",
    ),
    assets=((LIGHT_KIND, ("a",), "SH coefficients of an environment light (xing §4)"),),
    help="""Exact SH convolution tables Rd, Rs for Kajiya–Kay hair (xing §4).

    Stores the compact exact form (kernel Legendre coefficients over θ′ and the
    Gaunt tensor), optional dense Rd/Rs on cube-map tangents, and with --light
    the contracted Cd/Cs.  Only a bake with dense tables (dense.t_resolution > 0)
    splits, over its tangents t.""",
    examples=(
        "hairlut bake sh --recipe tables/sh-default.toml --out tables/sh.h5",
        "hairlut bake sh --recipe tables/sh-paper.toml --out paper.h5 --light sky --textures paper_tex.exr",
        "hairlut bake sh --out p200.h5 --p 200 --set bands.light_specular=auto",
        "hairlut bake sh --p 16                     # into the table cache (tables/), reused when baked",
        "hairlut bake sh --set dense.t_resolution=64 --out s0.h5 --shard 0/2   # and 1/2; then",
        "hairlut merge s0.h5 s1.h5 --out sh64.h5",
    ),
)
