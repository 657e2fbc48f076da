"""The shared validators: recipe fields, arguments, directions and points (NumPy only).

One rule per idea, in two forms:

- **Field checks** (``positive``, ``nonneg``, ``unit_interval``, ``at_least(n)``,
  ``in_range(lo, hi)``, ``one_of(...)``, ``auto_or(check)``, ``float32(check)``, ``vec3``) return ``None`` for a good value or the
  reason it is bad; they are the ``check`` of a :class:`hairlut.recipes.Field`, whose
  ``resolve`` raises :class:`~hairlut.errors.ValidationError` naming the key path.
- **Argument checks** (``check_real``, ``check_int``, ``direction``, ``directions``,
  ``points``) raise that error themselves, naming the ``field`` they are given, and return
  the value converted (a float, an int, a float64 array).

Directions point *toward* the viewer and the lights (DESIGN.md); a direction is a finite,
non-zero 3-vector, normalised on the way in.  :func:`hairlut.sh.check_dirs` adds JAX
tracers and per-dtype unit tolerances on top of :func:`directions`.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from . import errors


def _is_real(x) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


def _is_int(x) -> bool:
    return isinstance(x, numbers.Integral) and not isinstance(x, bool)


# ----------------------------------------------------------------------------- reasons


def real_reason(x, lo=None, hi=None, *, lo_open=False, hi_open=False) -> str | None:
    """Why ``x`` is not a finite real in the range (``None`` when it is)."""
    if not _is_real(x) or not math.isfinite(x):
        return "must be a finite number"
    if lo is not None and (x <= lo if lo_open else x < lo) or hi is not None and (x >= hi if hi_open else x > hi):
        if lo is not None and hi is not None:
            return f"must lie in {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        if lo is not None:
            return f"must be finite and {'>' if lo_open else '≥'} {lo:g}"
        return f"must be finite and {'<' if hi_open else '≤'} {hi:g}"
    return None


def int_reason(x, lo=None, hi=None) -> str | None:
    """Why ``x`` is not an integer in [lo, hi] (``None`` when it is)."""
    if not _is_int(x):
        return "must be an integer"
    if lo is not None and hi is not None and not lo <= x <= hi:
        return f"must be an integer in [{lo}, {hi}]"
    if lo is not None and x < lo:
        return f"must be an integer ≥ {lo}"
    if hi is not None and x > hi:
        return f"must be an integer ≤ {hi}"
    return None


# ----------------------------------------------------------------------------- field checks


def positive(x) -> str | None:
    """Field check: finite and > 0."""
    return real_reason(x, 0, lo_open=True)


def nonneg(x) -> str | None:
    """Field check: finite and ≥ 0."""
    return real_reason(x, 0)


def unit_interval(x) -> str | None:
    """Field check: in [0, 1]."""
    return real_reason(x, 0, 1)


def open_unit_interval(x) -> str | None:
    """Field check: in (0, 1)."""
    return real_reason(x, 0, 1, lo_open=True, hi_open=True)


#: The largest finite float32 (3.4028235e38): a value a float32 kernel receives as it is must not exceed it, or it
#: becomes infinity there, and infinity times zero is NaN.
FLOAT32_MAX = float(np.finfo(np.float32).max)


def float32(check):
    """Field check: ``check``'s rule, and at most :data:`FLOAT32_MAX` in magnitude (for a value a float32 kernel
    receives as it is: beyond, it becomes infinity in the kernel, and inf · 0 = NaN)."""

    def run(x):
        reason = check(x)
        if reason is None and _is_real(x) and abs(x) > FLOAT32_MAX:
            return f"must be ≤ {FLOAT32_MAX:.8g} (float32's largest: the kernel computes in float32)"
        return reason

    return run


def in_range(lo, hi):
    """Field check: a number in [lo, hi] (an integer field's values are checked as integers)."""
    return lambda x: int_reason(x, lo, hi) if _is_int(x) else real_reason(x, lo, hi)


def at_least(n):
    """Field check: an integer ≥ n."""
    return lambda x: int_reason(x, n)


def one_of(*choices):
    """Field check: one of ``choices``."""
    words = ", ".join(map(repr, choices))
    return lambda x: None if x in choices else f"one of {words}"


def auto_or(check):
    """Field check: the word ``'auto'``, or a value ``check`` accepts."""

    def run(x):
        if x == "auto":
            return None
        reason = check(x)
        return None if reason is None else f"{reason}, or 'auto'"

    return run


def vec3(x) -> str | None:
    """Field check: a direction (:func:`direction`'s rule)."""
    try:
        direction(x)
    except errors.ValidationError as exc:
        return exc.reason
    return None


# ----------------------------------------------------------------------------- argument checks


def check_real(value, field: str, lo=None, hi=None, *, lo_open=False, hi_open=False) -> float:
    """A finite real in the range, as a float (ValidationError naming ``field`` otherwise)."""
    if isinstance(value, (np.generic, np.ndarray)) and np.ndim(value) == 0 and np.asarray(value).dtype != np.bool_:
        value = np.asarray(value).item()
    if reason := real_reason(value, lo, hi, lo_open=lo_open, hi_open=hi_open):
        raise errors.ValidationError(field, value, reason)
    return float(value)


def check_int(value, field: str, lo=None, hi=None) -> int:
    """An integer (not a bool) in [lo, hi], as an int (ValidationError naming ``field`` otherwise)."""
    if isinstance(value, (np.integer, np.ndarray)) and np.ndim(value) == 0 and np.asarray(value).dtype.kind in "iu":
        value = int(value)
    if reason := int_reason(value, lo, hi):
        raise errors.ValidationError(field, value, reason)
    return int(value)


def _real_array(value, field: str) -> np.ndarray:
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise errors.ValidationError(field, value, f"not an array of numbers ({exc})") from None
    if arr.dtype == np.bool_ or not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise errors.ValidationError(field, value, f"need real numbers, got dtype {arr.dtype}")
    return arr


def _at(bad: np.ndarray) -> str:
    return f" at index {tuple(int(k) for k in np.argwhere(bad)[0])}" if bad.ndim else ""


def directions(value, field: str = "dirs", *, normalize: bool = True, tol: float = 1e-6, dtype=np.float64) -> np.ndarray:
    """Directions (..., 3): real and finite; with ``normalize`` non-zero and returned as unit
    vectors, without it within ``tol`` of unit length and returned as given.  The result has
    ``dtype``; norms are taken in float64 without overflow.  A ValidationError names ``field``
    and the index of the first bad direction."""
    arr = _real_array(value, field)
    if arr.ndim < 1 or arr.shape[-1] != 3:
        raise errors.ValidationError(field, value, f"the last axis must have length 3 (x, y, z); got shape {arr.shape}")
    d64 = arr.astype(np.float64, copy=False)
    finite = np.all(np.isfinite(d64), axis=-1)
    if not finite.all():
        raise errors.ValidationError(field, value, "non-finite direction" + _at(~finite))
    norm = np.hypot(np.hypot(d64[..., 0], d64[..., 1]), d64[..., 2])
    if normalize:
        if np.any(norm == 0):
            raise errors.ValidationError(field, value, "zero vector (no direction)" + _at(norm == 0))
        return (d64 / norm[..., None]).astype(dtype, copy=False)
    dev = np.abs(norm - 1.0)
    if dev.size and float(dev.max()) > tol:
        k = np.unravel_index(int(np.argmax(dev)), dev.shape)
        raise errors.ValidationError(
            field,
            value,
            f"not a unit vector at index {tuple(int(v) for v in k)} "
            f"(|d| = {float(norm[k]):.8g}, tolerance {tol:g}); normalise first",
        )
    return arr.astype(dtype, copy=False)


def direction(value, field: str = "direction") -> np.ndarray:
    """One direction: a finite, non-zero 3-vector, returned normalised as float64 (3,)."""
    arr = _real_array(value, field)
    if arr.shape != (3,):
        raise errors.ValidationError(field, value, "need a direction of 3 real numbers")
    return directions(arr, field)


def points(value, field: str = "points") -> np.ndarray:
    """Points: a finite (n, 3) float64 array."""
    arr = _real_array(value, field)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise errors.ValidationError(field, arr.shape, "need an (n, 3) array")
    arr = arr.astype(np.float64, copy=False)
    if not np.isfinite(arr).all():
        raise errors.ValidationError(field, "non-finite", "points must be finite")
    return arr
