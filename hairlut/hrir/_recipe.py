"""The HRIR-DB recipe: schema, defaults and validation (satf §5).

Every key is validated by :func:`hairlut.recipes.resolve`, which names the key path
(``trace.steps``) of a bad value.  ``sectors.space`` is
derived from :class:`hairlut.geometry.SectorSpace` (its defaults and rules, as [low, high] pairs).

**Float32 limits.**  The tracer computes in float32, so a recipe is refused (naming the key) when some sector of its
space could overflow float32's largest value F = 3.4e38 (:func:`check_float32`).  The bounds are derived from the
arithmetic, over the whole sector space (A = 1 ≥ B; v ≤ 1):

* a sector's area is at least a_min = aspect_lo · (π / s_u_hi) · Δv², Δv = min(radial_extent_lo, 1 − v_inner_hi),
  and its extent R (the largest distance from its centre) at most 2;
* σ_t = κ / r with r = radius_rel · √area, at most κ / (radius_rel_lo · √a_min), must be finite;
* the peak density: N strands of mass π r² all in the smallest cell (area ≥ area / (n_s · n_r²)) give
  ρ̂ = density_scale · N · π · radius_rel² · n_s · n_r², N = strands_hi;
* the density gradient's local components are at most 4π · ρ̂ · max(n_s, n_r) (central differences times the grid
  size, through a Jacobian whose entries are at most 2π), and their squared norm must be finite:
  2 (4π ρ̂ n)² ≤ F, so density_scale is bounded;
* the optical depth of a ray, σ_t ρ̂ · 2R ≤ 4 κ · density_scale · N · π · radius_rel_hi · n_s · n_r² / √a_min
  (σ_t ρ̂ grows with radius_rel), must stay below F / 2 (the bilinear sums of the light's depth grid round up by
  less than that), so trace.extinction and density_scale are bounded together;
* the Phong coefficients enter as they are (re ≤ α·(k_a + k_d + k_s)): each and their sum at most F; the
  shininess p at most F (p · log(r·d) with r·d = 1 is p · 0, NaN for an infinite p).

The bounds are loose (a real sector's density is far below ρ̂) but never too tight: within them every sector traces
to finite values.  They still admit far more than physics asks for (trace.extinction up to 7e29 with the default
space and grid, sectors.density_scale up to 6e11), where α saturates at a ray's first dense sample.
"""

from __future__ import annotations

import math

from .. import budget as _budget
from .. import errors
from ..geometry.sector_space import canonical as canonical_space
from ..geometry.sector_space import recipe_fields as space_fields
from ..recipes import Field, get_path, resolve
from ..validate import FLOAT32_MAX, float32, in_range, int_reason, nonneg, one_of, open_unit_interval, positive

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
        "density_scale": Field(1.0, _NUM, float32(positive), "density of a fully covered cell"),
        "features": Field(
            "basic",
            (str,),
            one_of("basic", "moments", "projection"),
            "feature set of the index: the paper's (satf §5.2), moments, or projection "
            "(each sector's density projected at 8 views, 24 principal components)",
        ),
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
        "ambient": Field(0.1, _NUM, float32(nonneg), "k_a"),
        "diffuse": Field(0.6, _NUM, float32(nonneg), "k_d"),
        "specular": Field(0.3, _NUM, float32(nonneg), "k_s"),
        "shininess": Field(20.0, _NUM, float32(positive), "Phong exponent p"),
    },
    "storage": {
        "dtype": Field("float32", (str,), one_of("float16", "float32"), "dtype of alpha and reflectance"),
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
    check_float32(r, given)
    r["method"] = METHOD
    if budget:
        _budget.check_hrir(r)
    return r


def sector_space(recipe: dict):
    """The :class:`hairlut.geometry.SectorSpace` of a resolved recipe."""
    from ..geometry import SectorSpace

    sp = recipe["sectors"]["space"]
    return SectorSpace(**{k: tuple(v) for k, v in sp.items()})


def float32_factors(recipe: dict) -> dict:
    """The module docstring's float32 bounds of a resolved recipe, per unit of the key each bounds: ``sigma_t`` (the
    largest σ_t per unit κ), ``gradient`` (the bound of the density gradient's local components per unit
    density_scale) and ``depth`` (of a ray's optical depth per unit κ · density_scale)."""
    sp, (n_s, n_r) = recipe["sectors"]["space"], recipe["sectors"]["grid"]
    dv = min(sp["radial_extent"][0], 1.0 - sp["v_inner"][1])
    root_area = math.sqrt(sp["aspect"][0] * (math.pi / sp["s_u"][1])) * dv
    rel_lo, rel_hi = sp["radius_rel"]
    mass = sp["strands"][1] * math.pi * rel_hi * n_s * n_r * n_r  # ρ̂ = density_scale · mass · radius_rel_hi
    return {
        "sigma_t": 1.0 / (rel_lo * root_area),
        "gradient": 4 * math.pi * mass * rel_hi * max(n_s, n_r),
        "depth": 4 * mass / root_area,
    }


#: The keys each float32 bound depends on, the one it limits first (the others are named when the user set them).
SPACE_AREA = ("sectors.space.radial_extent", "sectors.space.v_inner", "sectors.space.aspect", "sectors.space.s_u")
BOUND_KEYS = {
    "sigma_t": ("trace.extinction", "sectors.space.radius_rel", *SPACE_AREA),
    "gradient": ("sectors.density_scale", "sectors.grid", "sectors.space.strands", "sectors.space.radius_rel"),
    "depth": (
        "trace.extinction",
        "sectors.density_scale",
        "sectors.grid",
        "sectors.space.strands",
        "sectors.space.radius_rel",
        *SPACE_AREA,
    ),
}


def _refuse(recipe: dict, given: dict, bound: str, reason: str):
    """A ValidationError naming the first key of the bound that the recipe sets (``given``), else the bound's own key:
    the user hears of the value they wrote, not of a default it overflows against."""
    keys = BOUND_KEYS[bound]
    key = next((k for k in keys if get_path(given, k) is not None), keys[0])
    return errors.ValidationError(key, get_path(recipe, key), reason)


def check_float32(recipe: dict, given: dict | None = None) -> None:
    """Refuse a recipe whose trace could overflow float32 for some sector of its space (module docstring), naming
    the key the bound depends on that ``given`` (the recipe as the user wrote it) sets, and the largest value of the
    bound's own key with the others as they are."""
    given = given if given is not None else recipe
    kappa, scale = recipe["trace"]["extinction"], recipe["sectors"]["density_scale"]
    f = float32_factors(recipe)
    if not kappa * f["sigma_t"] <= FLOAT32_MAX:
        raise _refuse(
            recipe,
            given,
            "sigma_t",
            f"σ_t = κ / r_strand reaches {kappa * f['sigma_t']:.3g} for the "
            f"sector space's thinnest strand in its smallest sector, beyond float32 ({FLOAT32_MAX:.3g}); "
            f"trace.extinction ≤ {FLOAT32_MAX / f['sigma_t']:.3g} with the rest as given",
        )
    top = math.sqrt(FLOAT32_MAX / 2)
    if not scale * f["gradient"] <= top:
        raise _refuse(
            recipe,
            given,
            "gradient",
            f"the density gradient's components can reach "
            f"{scale * f['gradient']:.3g} (sectors.grid, the space's strands and radius_rel), whose squares "
            f"overflow float32 ({FLOAT32_MAX:.3g}); sectors.density_scale ≤ {top / f['gradient']:.3g} "
            "with the rest as given",
        )
    if not kappa * (scale * f["depth"]) <= FLOAT32_MAX / 2:  # (no strands: 0, whatever κ)
        raise _refuse(
            recipe,
            given,
            "depth",
            f"a ray's optical depth can reach {kappa * (scale * f['depth']):.3g} "
            f"(κ × sectors.density_scale × the sector space's densest sector), beyond float32 "
            f"({FLOAT32_MAX:.3g} / 2); trace.extinction ≤ {FLOAT32_MAX / 2 / (scale * f['depth']):.3g} "
            "with the rest as given",
        )
    ph = recipe["phong"]
    if not ph["ambient"] + ph["diffuse"] + ph["specular"] <= FLOAT32_MAX:
        top = max(("ambient", "diffuse", "specular"), key=lambda k: ph[k])
        raise errors.ValidationError(
            f"phong.{top}",
            ph[top],
            f"k_a + k_d + k_s (the reflectance of a unit of opacity) must be ≤ {FLOAT32_MAX:.8g} (float32's largest)",
        )
