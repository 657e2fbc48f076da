"""The ``hair_bsdf`` recipe: the tables' axes and resolutions, the fibre, the quadrature, the storage.

Light (no JAX): the registry, the planner and the command line resolve recipes without baking.

Two grids.  ``dual_scattering`` (A_f, A_b, ᾱ_f, ᾱ_b, β̄_f, β̄_b; Zinke et al. 2008) and ``mean_energy``
(R, TT, TRT and the residual p ≥ 3) share one (sin θ, roughness, absorption) grid, ``[grid]``, at Unreal's
64 × 64 × 16 by default: an engine samples both at the same texture coordinates, and the bake splits over its
sin θ rows.  ``coverage`` has its own (radius in pixels, strand count) grid, Unreal's 64 × 64 by default.

Every axis spans an interval ``[lo, hi]`` whose ``n`` nodes sit at cell centres, lo + (i + ½)(hi − lo)/n, so
that a GPU's sampler reads node i at the texture coordinate (i + ½)/n of u = (x − lo)/(hi − lo) (Unreal's
convention).  The absorption axis is Unreal's perceptual hair colour c (``absorption.axis = "colour"``: the
linear colour is C = c², and σ_a follows from C by Chiang et al. 2016's eq. 9 at β_n = the roughness) or σ_a
itself (``"sigma_a"``), per unit fibre radius as pbrt-v4 has it.  The numbers are
:mod:`hairlut.hairbsdf._integrals`' (``tables``), which this recipe drives: ``bsdf`` is its ``model``,
``quadrature`` its ``quadrature``.
"""

from __future__ import annotations

import math

import numpy as np

from .. import budget as _budget
from .. import errors
from ..recipes import Field, resolve
from ..validate import one_of

METHOD = "hairbsdf/1"
#: The per-entry quantities of each table, in the order the EXR atlas stores them.
DUAL = ("A_f", "A_b", "alpha_f", "alpha_b", "beta_f", "beta_b")
ENERGY = ("R", "TT", "TRT", "residual")
COVERAGE = ("coverage",)
QUANTITIES = {"dual_scattering": DUAL, "mean_energy": ENERGY, "coverage": COVERAGE}
#: The largest node count of one axis.
MAX_NODES = 4096
#: Bytes one entry of a table costs a bake at once: its float64 value and error, and the stored copies.
ENTRY_BYTES = 8 * 2 * 2


def _span(lo_bound: float | None, hi_bound: float | None, what: str):
    """Field check of an axis span [lo, hi]: two finite numbers, lo < hi, inside [lo_bound, hi_bound]."""

    def check(x):
        if len(x) != 2 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in x):
            return "need [lo, hi]: two numbers"
        lo, hi = (float(v) for v in x)
        if not (math.isfinite(lo) and math.isfinite(hi)):
            return f"{what}: must be finite (NaN or infinity given)"
        if lo_bound is not None and lo < lo_bound or hi_bound is not None and hi > hi_bound:
            where = f"[{lo_bound:g}, {hi_bound:g}]" if hi_bound is not None else f"[{lo_bound:g}, ∞)"
            return f"{what}: the span must lie in {where}"
        if not lo < hi:
            return "need lo < hi"
        return None

    return check


def _counts(n: int):
    def check(x):
        if len(x) != n or not all(isinstance(v, int) and not isinstance(v, bool) for v in x):
            return f"need {n} integers"
        if min(x) < 1 or max(x) > MAX_NODES:
            return f"each count lies in [1, {MAX_NODES}]"
        return None

    return check


def _real(lo, hi, *, lo_open=False):
    def check(x):
        x = float(x)
        if not math.isfinite(x):
            return "must be finite"
        if (x <= lo if lo_open else x < lo) or x > hi:
            return f"must lie in {'(' if lo_open else '['}{lo:g}, {hi:g}]"
        return None

    return check


def _even(lo: int, hi: int):
    def check(x):
        return None if lo <= x <= hi and x % 2 == 0 else f"an even integer in [{lo}, {hi}] (the error estimate uses half)"

    return check


_F, _L, _I = (float, int), (list,), (int,)

SCHEMA = {
    "bsdf": {
        "eta": Field(1.55, _F, _real(1.0, 4.0, lo_open=True), "index of refraction of the fibre (pbrt-v4's 1.55)"),
        "alpha": Field(2.0, _F, _real(-22.5, 22.5), "cuticle tilt α in degrees (Chiang et al. 2016; pbrt-v4's 2°)"),
    },
    "grid": {
        "resolution": Field([64, 64, 16], _L, _counts(3), "sin θ × roughness × absorption nodes (Unreal: 64 × 64 × 16)"),
        "sin_theta": Field([0.0, 1.0], _L, _span(-1.0, 1.0, "sin θ lies in [-1, 1]"), "span of sin θ_o (Unreal: [0, 1])"),
        "roughness": Field(
            [0.0, 1.0],
            _L,
            _span(0.0, 1.0, "roughness β lies in (0, 1]"),
            "span of the roughness β = β_m = β_n; its cell centres lie in (0, 1]",
        ),
    },
    "absorption": {
        "axis": Field("colour", (str,), one_of("colour", "sigma_a"), "the absorption axis: Unreal's perceptual colour, or σ_a"),
        "colour": Field([0.0, 1.0], _L, _span(0.0, 1.0, "a colour channel lies in [0, 1]"), "span of the colour axis (C = c²)"),
        "sigma_a": Field([0.0, 8.0], _L, _span(0.0, None, "σ_a is ≥ 0"), "span of the σ_a axis (per unit fibre radius)"),
    },
    "dual_scattering": {"bake": Field(True, (bool,), None, "bake A_f, A_b, ᾱ_f, ᾱ_b, β̄_f, β̄_b (Zinke et al. 2008)")},
    "mean_energy": {"bake": Field(True, (bool,), None, "bake the mean energy of the R, TT, TRT and residual lobes")},
    "coverage": {
        "bake": Field(True, (bool,), None, "bake the pixel coverage of N strands"),
        "resolution": Field([64, 64], _L, _counts(2), "radius × strand count nodes (Unreal: 64 × 64)"),
        "radius": Field([0.0, 0.5], _L, _span(0.0, 1e3, "a radius is ≥ 0"), "span of the strand radius in pixels (Unreal's)"),
        "strands": Field(
            [-0.5, 63.5], _L, _span(-1.0, 1e6, "a strand count is ≥ 0"), "span of the strand count N (nodes 0, 1, …, 63)"
        ),
    },
    "quadrature": {
        "nodes": Field(12, _I, _even(2, 64), "Gauss–Legendre nodes per panel of the BSDF integrals"),
        "levels": Field(4, _I, lambda x: None if 1 <= x <= 8 else "an integer in [1, 8]", "panels graded about each feature"),
        "coverage_nodes": Field(16, _I, _even(2, 64), "Gauss–Legendre nodes per panel of the coverage integrals"),
    },
    "storage": {"dtype": Field("float32", (str,), one_of("float16", "float32", "float64"), "dtype of the stored values")},
}

#: Unused-key rule: the absorption span the chosen axis does not read must stay at its default.
_OTHER_SPAN = {"colour": "sigma_a", "sigma_a": "colour"}


def nodes(span, n: int) -> np.ndarray:
    """The n cell-centre nodes of ``span`` = [lo, hi]: lo + (i + ½)(hi − lo)/n (float64)."""
    lo, hi = (float(v) for v in span)
    return lo + (np.arange(n, dtype=np.float64) + 0.5) * ((hi - lo) / n)


def grid_axes(recipe: dict) -> dict[str, np.ndarray]:
    """The nodes of every axis of a resolved recipe: ``sin_theta``, ``roughness``, ``absorption`` (the axis's own
    coordinate), ``radius`` and ``strands``."""
    g, a, c = recipe["grid"], recipe["absorption"], recipe["coverage"]
    n_s, n_r, n_a = g["resolution"]
    return {
        "sin_theta": nodes(g["sin_theta"], n_s),
        "roughness": nodes(g["roughness"], n_r),
        "absorption": nodes(a[a["axis"]], n_a),
        "radius": nodes(c["radius"], c["resolution"][0]),
        "strands": nodes(c["strands"], c["resolution"][1]),
    }


def physics_axes(recipe: dict) -> tuple[dict, dict]:
    """(axes, resolution) of a resolved recipe as :func:`hairlut.hairbsdf._integrals.tables` takes them."""
    g, a, c = recipe["grid"], recipe["absorption"], recipe["coverage"]
    axes = {
        "sin_theta_o": tuple(g["sin_theta"]),
        "roughness": tuple(g["roughness"]),
        "absorption": tuple(a[a["axis"]]),
        "absorption_kind": a["axis"],
        "radius_px": tuple(c["radius"]),
        "strand_count": tuple(c["strands"]),
    }
    n_s, n_r, n_a = g["resolution"]
    resolution = {
        "sin_theta_o": n_s,
        "roughness": n_r,
        "absorption": n_a,
        "radius_px": c["resolution"][0],
        "strand_count": c["resolution"][1],
    }
    return axes, resolution


def grid_tables(recipe: dict) -> tuple[str, ...]:
    """The grid tables a recipe bakes, of ``dual_scattering`` and ``mean_energy``."""
    return tuple(t for t in ("dual_scattering", "mean_energy") if recipe[t]["bake"])


def quantities(recipe: dict) -> tuple[str, ...]:
    """The per-entry quantities of the grid tables a recipe bakes (the datasets with ``sin_theta`` first)."""
    return tuple(q for t in grid_tables(recipe) for q in QUANTITIES[t])


def check_budget(recipe: dict, limit: int | None = None) -> None:
    """Refuse (BudgetError naming the key) a recipe whose tables would not fit the memory budget, before any
    allocation: a copied asset holds every entry of the grid tables (value and error, float64, and the stored
    copies) and of the coverage table at once."""
    g, c = recipe["grid"], recipe["coverage"]
    per_entry = len(quantities(recipe)) * ENTRY_BYTES
    if per_entry:
        _budget.check(
            "grid.resolution",
            g["resolution"],
            _budget.product(*g["resolution"], per_entry),
            f"the {' and '.join(grid_tables(recipe))} tables ({' × '.join(map(str, g['resolution']))} entries "
            f"× {len(quantities(recipe))} quantities, value and error)",
            limit,
        )
    if c["bake"]:
        _budget.check(
            "coverage.resolution",
            c["resolution"],
            _budget.product(*c["resolution"], ENTRY_BYTES),
            f"the coverage table ({c['resolution'][0]} × {c['resolution'][1]} entries, value and error)",
            limit,
        )


def resolve_recipe(given: dict | None = None, *, budget: bool = True) -> dict:
    """Validated recipe with every default explicit (:data:`SCHEMA`); idempotent.

    A bad value raises ValidationError naming its key (``absorption.sigma_a`` for a negative σ_a,
    ``grid.roughness`` for a roughness outside (0, 1], ``absorption.colour`` for a NaN colour); with ``budget``,
    a resolution whose tables would not fit in memory raises BudgetError naming ``grid.resolution`` or
    ``coverage.resolution`` before anything is allocated.  Readers of a baked file pass ``budget=False``."""
    given = dict(given or {})
    method = given.pop("method", METHOD)
    if method != METHOD:
        raise errors.ValidationError("method", method, f"baked by another method; this hairlut bakes {METHOD}")
    r = resolve(SCHEMA, given)
    for section, keys in SCHEMA.items():
        for key, spec in keys.items():
            if isinstance(spec.default, list):
                r[section][key] = [float(v) for v in r[section][key]] if isinstance(spec.default[0], float) else r[section][key]
            elif isinstance(spec.default, float):
                r[section][key] = float(r[section][key])
    a = r["absorption"]
    other = _OTHER_SPAN[a["axis"]]
    if a[other] != SCHEMA["absorption"][other].default:
        raise errors.ValidationError(
            f"absorption.{other}", a[other], f"the {a['axis']} axis does not read it; set absorption.axis = {other!r} to use it"
        )
    if not (r["dual_scattering"]["bake"] or r["mean_energy"]["bake"] or r["coverage"]["bake"]):
        raise errors.ValidationError("dual_scattering.bake", False, "bake at least one of dual_scattering, mean_energy, coverage")
    r["method"] = METHOD
    if budget:
        check_budget(r)
    return r
