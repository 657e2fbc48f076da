"""The HRIR-DB recipe: schema, defaults and validation (satf §5).

Every key is validated by :func:`hairlut.recipes.resolve`, which names the key path
(``trace.steps``) of a bad value.  ``sectors.space`` is
derived from :class:`hairlut.geometry.SectorSpace` (its defaults and rules, as [low, high] pairs).
"""

from __future__ import annotations

import math

from .. import budget as _budget
from .. import errors
from ..geometry.sector_space import canonical as canonical_space
from ..geometry.sector_space import recipe_fields as space_fields
from ..recipes import Field, resolve
from ..validate import in_range, int_reason, nonneg, one_of, open_unit_interval, positive

METHOD = "planar-ray-trace/1"


def _grid(v):
    if len(v) != 2 or any(int_reason(x, 2, 512) for x in v):
        return "need [n_s, n_r], integers in [2, 512]"
    return None


_NUM = (int, float)

SCHEMA = {
    "sectors": {
        "count": Field(512, (int,), in_range(1, 10_000_000), "number of random sectors N"),
        "seed": Field(0, (int,), in_range(0, 2**63 - 1), "sector i is drawn from the seed and i alone"),
        "grid": Field([32, 32], (list,), _grid, "density grid (n_s, n_r) of each sector"),
        "density_scale": Field(1.0, _NUM, positive, "density of a fully covered cell"),
        "features": Field("basic", (str,), one_of("basic", "moments", "projection"),
                          "feature set of the index: the paper's (satf §5.2), moments, or projection "
                          "(each sector's density projected at 8 views, 24 principal components)"),
        "space": space_fields(),
    },
    "angles": {
        "views": Field(32, (int,), in_range(1, 4096), "view angles θv = 2πi/V"),
        "lights": Field(32, (int,), in_range(1, 4096), "light angles θl = 2πj/L"),
    },
    "trace": {
        "pixels": Field(64, (int,), in_range(2, 8192), "pixels per HRIR"),
        "steps": Field(64, (int,), in_range(2, 65536), "ray-march steps across the sector's extent"),
        "rays_per_pixel": Field(1, (int,), in_range(1, 64), "box-filtered rays per pixel"),
        "extinction": Field(2 / math.pi, _NUM, positive, "κ in σ_t = κ / r_strand (2/π: opaque discs)"),
        "termination": Field(1e-4, _NUM, open_unit_interval, "stop a ray when 1 − α_acc < this"),
        "self_shadow": Field(True, (bool,), None, "in-plane attenuation toward the light (within the sector)"),
        "smooth": Field(True, (bool,), None, "1-D Gaussian smoothing along pixels"),
        "smooth_ratio": Field(1.5, _NUM, positive, "smoothing σ over the strand Gaussian's σ"),
    },
    "phong": {
        "ambient": Field(0.1, _NUM, nonneg, "k_a"),
        "diffuse": Field(0.6, _NUM, nonneg, "k_d"),
        "specular": Field(0.3, _NUM, nonneg, "k_s"),
        "shininess": Field(20.0, _NUM, positive, "Phong exponent p"),
    },
    "storage": {
        "dtype": Field("float32", (str,), one_of("float16", "float32"),
                       "dtype of alpha and reflectance"),
    },
}


def resolve_recipe(given: dict | None = None, *, budget: bool = True) -> dict:
    """Validated recipe with every default explicit (raises ValidationError naming the key path).

    Idempotent: a resolved recipe (with its ``method``) resolves to itself.  With ``budget``,
    a recipe whose bake would not fit in memory raises BudgetError naming the key that drives
    it (:func:`hairlut.budget.check_hrir`); loaders of a baked file pass ``budget=False``."""
    given = dict(given or {})
    method = given.pop("method", METHOD)
    if method != METHOD:
        raise errors.ValidationError("method", method, f"baked by another method; this hairlut bakes {METHOD}")
    r = resolve(SCHEMA, given)
    r["sectors"]["space"] = canonical_space(r["sectors"]["space"])
    r["method"] = METHOD
    if budget:
        _budget.check_hrir(r)
    return r


def sector_space(recipe: dict):
    """The :class:`hairlut.geometry.SectorSpace` of a resolved recipe."""
    from ..geometry import SectorSpace

    sp = recipe["sectors"]["space"]
    return SectorSpace(**{k: tuple(v) for k, v in sp.items()})
