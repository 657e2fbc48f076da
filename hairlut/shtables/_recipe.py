"""The SH-table recipe: schema, defaults, validation, and the light folded into it (xing §4).

Light (no JAX): the planner, the registry and the CLI resolve recipes without baking.
A recipe baked with an environment light carries the light's identity in ``light``
(band count, channels, layout, the SHA-256 of its source and of its coefficients), so
the recipe hash (the cache key) changes with the light.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from .. import budget as _budget
from .. import errors
from ..kernels import exponent_reason
from ..recipes import Field, resolve
from ..validate import at_least, auto_or, in_range, one_of

METHOD = "legendre-gaunt/1"
LIGHT_KEYS = ("channels", "coeffs_sha256", "layout", "lmax", "source_sha256")


SCHEMA = {
    "kernel": {
        "p": Field(49.0, (float, int), exponent_reason, "specular exponent p"),
        "diffuse": Field(True, (bool,), None, "bake Rd"),
        "specular": Field(True, (bool,), None, "bake Rs"),
    },
    "bands": {
        "light_diffuse": Field(3, (int,), at_least(1), "light bands for Rd (9 coefficients)"),
        "light_specular": Field("auto", (int, str), auto_or(at_least(1)), "light bands (lmax + 1) for Rs; auto = ceil(√p) + 1"),
        "transmittance": Field(3, (int,), at_least(1), "transmittance bands"),
    },
    "quadrature": {
        "chebyshev": Field("auto", (int, str), auto_or(in_range(2, 4096)), "Chebyshev nodes per θ′ half (auto: until converged)"),
    },
    "dense": {
        "t_resolution": Field(0, (int,), at_least(0), "cube-map face size of the tangent grid (0: no dense tables)"),
        "theta_v_steps": Field(9, (int,), at_least(2), "θ′ samples over [0, π]"),
        "storage": Field("float32", (str,), one_of("float16", "float32", "float64"), "dtype of the dense tables"),
    },
}


def specular_band_rule(p: float) -> int:
    """Light bands for the specular term: ceil(√p) + 1, i.e. (√p + 1)² coefficients (xing §4, after King)."""
    return int(math.ceil(math.sqrt(p) - 1e-12)) + 1


def light_bands(recipe: dict) -> int:
    """The light bands a resolved recipe needs: the larger of its diffuse and specular bands."""
    return max(recipe["bands"]["light_diffuse"], recipe["bands"]["light_specular"])


def light_identity(light) -> dict:
    """The identity of an :class:`hairlut.envlight.EnvLight` that a recipe records."""
    coeffs = hashlib.sha256(np.ascontiguousarray(light.coeffs, np.float64).tobytes()).hexdigest()
    return {
        "lmax": int(light.lmax),
        "channels": list(light.channels),
        "layout": light.layout,
        "source_sha256": light.source_sha256,
        "coeffs_sha256": coeffs,
    }


def _check_light_section(section) -> dict:
    if not isinstance(section, dict) or sorted(section) != list(LIGHT_KEYS):
        raise errors.ValidationError("light", section, f"a light's identity has exactly the keys {', '.join(LIGHT_KEYS)}")
    return dict(section)


def resolve_recipe(given: dict | None = None, light=None, *, budget: bool = True) -> dict:
    """Validated recipe with every default and 'auto' made explicit; with ``light``, its identity.

    With ``budget``, a recipe whose tables would not fit in memory raises BudgetError naming
    the key (:func:`hairlut.budget.check_sh`); loaders of a baked file pass ``budget=False``.
    Idempotent: a resolved recipe (``method``, and ``light`` when it names one) resolves to
    itself.  A recipe that names a light and a different ``light`` argument is an error."""
    given = dict(given or {})
    method = given.pop("method", METHOD)
    if method != METHOD:
        raise errors.ValidationError("method", method, f"baked by another method; this hairlut bakes {METHOD}")
    named = given.pop("light", None)
    r = resolve(SCHEMA, given)
    if not (r["kernel"]["diffuse"] or r["kernel"]["specular"]):
        raise errors.ValidationError("kernel", r["kernel"], "bake at least one of diffuse and specular")
    r["kernel"]["p"] = float(r["kernel"]["p"])
    if r["bands"]["light_specular"] == "auto":
        auto = specular_band_rule(r["kernel"]["p"]) if r["kernel"]["p"] <= 64.0**2 else None
        if auto is None and r["kernel"]["specular"]:  # name the key the user set, not the derived band count
            raise errors.ValidationError(
                "kernel.p",
                r["kernel"]["p"],
                "bands.light_specular = 'auto' takes ceil(√p) + 1 "
                "bands, at most 65: p ≤ 4096, or set bands.light_specular (≤ 65) yourself",
            )
        r["bands"]["light_specular"] = auto if auto is not None else 65
    for key, limit in (("light_diffuse", 33), ("light_specular", 65), ("transmittance", 33)):
        if r["bands"][key] > limit:
            raise errors.ValidationError(f"bands.{key}", r["bands"][key], f"at most {limit} bands")
    r["method"] = METHOD
    if light is not None:
        ident = light_identity(light)
        if named is not None and _check_light_section(named) != ident:
            raise errors.ValidationError(
                "light",
                ident["source_sha256"],
                f"the recipe names another light (source sha256 {str(named.get('source_sha256'))[:16]}…)",
            )
        r["light"] = ident
    elif named is not None:
        r["light"] = _check_light_section(named)
    if budget:
        _budget.check_sh(r)
    return r


def full_recipe(recipe: dict | None, light=None) -> dict:
    """The resolved recipe plus, when a light is folded in, that light's identity (the cache key)."""
    return resolve_recipe(recipe, light)
