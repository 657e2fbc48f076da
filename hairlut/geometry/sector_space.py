"""The parameter space of random generalized sectors (satf §5): its fields, defaults and rules, once.

§5 "initialize[s] control parameters of a generalized sector using random values";
:class:`SectorSpace` makes those parameters explicit, each a (low, high) range.  This
module is the one place that says what the fields are, what they default to and which
ranges are valid: :func:`hairlut.geometry.sample_sectors` draws from a SectorSpace, the
HRIR-DB recipe's ``sectors.space`` table is derived from it (:func:`recipe_fields`), and
the planner restricts it to a scene's sectors.  NumPy only (recipes resolve without JAX).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

from ..errors import ValidationError

#: Each range's rule: (integer?, low bound, low bound excluded?, high bound or None, high excluded?, doc).
RULES = {
    "strands": (True, 0, False, None, False, "strands crossing a sector"),
    "radius_rel": (False, 0.0, True, None, False, "strand radius / √(sector area)"),
    "spread": (False, 0.0, True, None, False, "blob standard deviation (sector units)"),
    "clumps": (True, 1, False, None, False, "blobs of a clumped sector"),
    "aspect": (False, 0.0, True, 1.0, False, "B / A of the ellipse"),
    "v_inner": (False, 0.0, False, 1.0, True, "inner radius v0 (ellipse fraction)"),
    "radial_extent": (False, 0.0, True, None, False, "radial extent v1 − v0 (ellipse fraction)"),
    "s_u": (True, 1, False, None, False, "phase steps (Δu = 2π / s_u)"),
}
WEIGHTS_DOC = "weights of the profiles uniform, gaussian, clumped"


@dataclass(frozen=True)
class SectorSpace:
    """The parameter space of random sectors: each entry a (low, high) range (:data:`RULES`)."""

    strands: tuple[int, int] = (0, 48)
    radius_rel: tuple[float, float] = (0.002, 0.1)
    spread: tuple[float, float] = (0.05, 1.0)
    clumps: tuple[int, int] = (2, 5)
    aspect: tuple[float, float] = (0.3, 1.0)
    v_inner: tuple[float, float] = (0.0, 0.9)
    radial_extent: tuple[float, float] = (0.05, 0.5)
    s_u: tuple[int, int] = (4, 32)
    profile_weights: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if reason := field_reason(name, value):
                raise ValidationError(f"space.{name}", value, reason)


def _number(x, integer: bool) -> bool:
    if isinstance(x, bool):
        return False
    if integer:
        return isinstance(x, int) or type(x).__name__.startswith(("int", "uint"))
    try:
        return math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def range_reason(name: str, pair) -> str | None:
    """Why ``pair`` is not a valid (low, high) range of field ``name``, or None."""
    integer, lo, lo_open, hi, hi_open, _ = RULES[name]
    try:
        items = tuple(pair)
    except TypeError:
        return "need a [low, high] pair"
    if len(items) != 2 or not all(_number(x, integer) for x in items):
        return f"need a [low, high] pair of {'integers' if integer else 'finite numbers'}"
    low, high = items
    low_ok = low > lo if lo_open else low >= lo
    high_ok = hi is None or (high < hi if hi_open else high <= hi)
    if not (low_ok and high_ok and low <= high):
        top = "" if hi is None else f" {'<' if hi_open else '≤'} {hi:g}"
        return f"need {lo:g} {'<' if lo_open else '≤'} low ≤ high{top}"
    return None


def weights_reason(weights) -> str | None:
    """Why ``weights`` are not three profile weights ≥ 0, not all 0, or None."""
    try:
        items = tuple(weights)
    except TypeError:
        items = ()
    if len(items) != 3 or not all(_number(x, False) and float(x) >= 0 for x in items) or sum(map(float, items)) <= 0:
        return "need three weights ≥ 0 (uniform, gaussian, clumped), not all 0"
    return None


def field_reason(name: str, value) -> str | None:
    """Why ``value`` is not valid for SectorSpace field ``name``, or None."""
    return weights_reason(value) if name == "profile_weights" else range_reason(name, value)


def defaults() -> dict:
    """Every field's default, as lists (the form a TOML recipe holds)."""
    return {f.name: list(f.default) for f in fields(SectorSpace)}


def recipe_fields() -> dict:
    """The ``sectors.space`` table of a recipe schema: one :class:`hairlut.recipes.Field` per
    SectorSpace field, with its default and rule."""
    from ..recipes import Field

    docs = {name: rule[-1] for name, rule in RULES.items()} | {"profile_weights": WEIGHTS_DOC}
    return {name: Field(value, (list,), lambda v, n=name: field_reason(n, v), docs[name]) for name, value in defaults().items()}


def canonical(space: dict) -> dict:
    """A validated ``sectors.space`` mapping with integer fields as ints and the rest as floats."""
    return {k: [int(x) if k in RULES and RULES[k][0] else float(x) for x in v] for k, v in space.items()}
