"""The HRIR-DB recipe: schema, defaults and validation (satf §5).

Every key is validated by :func:`hairlut.recipes.resolve`, which names the key path
(``trace.steps``) of a bad value.  ``sectors.space`` mirrors
:class:`hairlut.geometry.SectorSpace` (ranges as [low, high] pairs).
"""

from __future__ import annotations

import math

from .. import errors
from ..recipes import Field, resolve

METHOD = "planar-ray-trace/1"


def _int_range(lo, hi=None):
    def check(v):
        if v < lo or (hi is not None and v > hi):
            return f"must be in [{lo}, {hi}]" if hi is not None else f"must be ≥ {lo}"
        return None
    return check


def _positive(v):
    return None if math.isfinite(v) and v > 0 else "must be finite and > 0"


def _nonneg(v):
    return None if math.isfinite(v) and v >= 0 else "must be finite and ≥ 0"


def _unit_open(v):
    return None if 0 < v < 1 else "must be in (0, 1)"


def _pair(kind, lo=0.0):
    def check(v):
        if len(v) != 2 or not all(isinstance(x, kind) and not isinstance(x, bool) for x in v):
            return f"need a [low, high] pair of {kind.__name__ if isinstance(kind, type) else 'numbers'}"
        if not (math.isfinite(v[0]) and math.isfinite(v[1]) and lo <= v[0] <= v[1]):
            return f"need {lo} ≤ low ≤ high"
        return None
    return check


def _grid(v):
    if len(v) != 2 or not all(isinstance(x, int) and not isinstance(x, bool) and 2 <= x <= 512 for x in v):
        return "need [n_s, n_r], integers in [2, 512]"
    return None


def _weights(v):
    if len(v) != 3 or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and x >= 0 for x in v) or sum(v) <= 0:
        return "need three weights ≥ 0 (uniform, gaussian, clumped), not all 0"
    return None


_NUM = (int, float)

SCHEMA = {
    "sectors": {
        "count": Field(512, (int,), _int_range(1, 10_000_000), "number of random sectors N"),
        "seed": Field(0, (int,), _int_range(0, 2**63 - 1), "sector i is drawn from the seed and i alone"),
        "grid": Field([32, 32], (list,), _grid, "density grid (n_s, n_r) of each sector"),
        "density_scale": Field(1.0, _NUM, _positive, "density of a fully covered cell"),
        "features": Field("basic", (str,), lambda v: None if v in ("basic", "moments") else "use basic or moments",
                          "feature set of the index (satf §5.2)"),
        "space": {
            "strands": Field([0, 48], (list,), _pair(int), "strands crossing a sector"),
            "radius": Field([0.002, 0.1], (list,), _pair(_NUM, 1e-9), "strand radius / √(sector area)"),
            "spread": Field([0.05, 1.0], (list,), _pair(_NUM, 1e-9), "blob standard deviation (sector units)"),
            "clumps": Field([2, 5], (list,), _pair(int, 1), "blobs of a clumped sector"),
            "aspect": Field([0.3, 1.0], (list,), _pair(_NUM, 1e-9), "B / A of the ellipse"),
            "v_inner": Field([0.0, 0.9], (list,), _pair(_NUM), "inner radius v0"),
            "thickness": Field([0.05, 0.5], (list,), _pair(_NUM, 1e-9), "radial extent"),
            "s_u": Field([4, 32], (list,), _pair(int, 1), "phase steps (Δu = 2π / s_u)"),
            "profile_weights": Field([1.0, 1.0, 1.0], (list,), _weights, "uniform, gaussian, clumped"),
        },
    },
    "angles": {
        "views": Field(32, (int,), _int_range(1, 4096), "view angles θv = 2πi/V"),
        "lights": Field(32, (int,), _int_range(1, 4096), "light angles θl = 2πj/L"),
    },
    "trace": {
        "pixels": Field(64, (int,), _int_range(2, 8192), "pixels per HRIR"),
        "steps": Field(64, (int,), _int_range(2, 65536), "ray-march steps across the sector's extent"),
        "rays_per_pixel": Field(1, (int,), _int_range(1, 64), "box-filtered rays per pixel"),
        "extinction": Field(2 / math.pi, _NUM, _positive, "κ in σ_t = κ / r_strand (2/π: opaque discs)"),
        "termination": Field(1e-4, _NUM, _unit_open, "stop a ray when 1 − α_acc < this"),
        "self_shadow": Field(True, (bool,), None, "in-plane attenuation toward the light (within the sector)"),
        "smooth": Field(True, (bool,), None, "1-D Gaussian smoothing along pixels"),
        "smooth_ratio": Field(1.5, _NUM, _positive, "smoothing σ over the strand Gaussian's σ"),
    },
    "phong": {
        "ambient": Field(0.1, _NUM, _nonneg, "k_a"),
        "diffuse": Field(0.6, _NUM, _nonneg, "k_d"),
        "specular": Field(0.3, _NUM, _nonneg, "k_s"),
        "shininess": Field(20.0, _NUM, _positive, "Phong exponent p"),
    },
    "storage": {
        "dtype": Field("float32", (str,), lambda v: None if v in ("float16", "float32") else "use float16 or float32",
                       "dtype of alpha and reflectance"),
    },
}


def resolve_recipe(given: dict | None = None) -> dict:
    """Validated recipe with every default explicit (raises ValidationError naming the key path).

    Idempotent: a resolved recipe (with its ``method``) resolves to itself."""
    given = dict(given or {})
    method = given.pop("method", METHOD)
    if method != METHOD:
        raise errors.ValidationError("method", method, f"baked by another method; this hairlut bakes {METHOD}")
    r = resolve(SCHEMA, given)
    sp = r["sectors"]["space"]
    if sp["v_inner"][1] >= 1:
        raise errors.ValidationError("sectors.space.v_inner", sp["v_inner"], "need high < 1")
    if sp["aspect"][1] > 1:
        raise errors.ValidationError("sectors.space.aspect", sp["aspect"], "need high ≤ 1 (B ≤ A)")
    r["sectors"]["space"] = {k: [float(x) if isinstance(x, int) and k not in ("strands", "clumps", "s_u") else x
                                 for x in v] for k, v in sp.items()}
    r["method"] = METHOD
    return r


def sector_space(recipe: dict):
    """The :class:`hairlut.geometry.SectorSpace` of a resolved recipe."""
    from ..geometry.sampler import SectorSpace

    sp = recipe["sectors"]["space"]
    return SectorSpace(**{k: tuple(v) for k, v in sp.items()})
