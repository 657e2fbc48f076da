"""Physical bounds of a kind's tables, checked on every write: a table out of its bounds is never stored.

A table kind declares its bounds where it declares itself (``hairlut.bake.protocol.Baker(bounds=...)``, one
:class:`Bound` a line: α in [0, 1], re ≤ α·(k_a + k_d + k_s), |Rd| ≤ 1, ...); ``register_kind`` files them
with the kind (the kind and its shard kind alike), and :func:`hairlut.assets.write_table` calls
:func:`check_bounds` before anything is written.  So every part of a bake, every ``--shard`` file, every
merge and every one-shot asset is checked at the one place all of them pass through, and a new kind gets
the check by declaring its bounds.

A breach is refused like NaN, naming the recipe keys that drive the table with their values: a value that
is not finite raises :class:`hairlut.errors.NonFiniteError`, a finite value out of bounds
:class:`hairlut.errors.BoundsError`.  Tolerance (float rounding, not physics): a value may pass a bound
``b`` by ``(RTOL + ε)·|b| + ATOL + δ``, ε the machine epsilon and δ the smallest subnormal of the stored
dtype (a stored value and the table it is compared with are each rounded to it: at most ε relative
together; δ for values in the subnormal range).  RTOL = 1e-5 covers the float32 arithmetic of the
bakers' sums (a march of K steps: about K·2⁻²⁴ relative between Σ w and Σ w·shading).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from .. import errors
from ..recipes import get_path

#: Relative tolerance of a bound beyond the stored dtype's rounding (the float32 sums of the bakers).
RTOL = 1e-5
#: Absolute tolerance of a bound.
ATOL = 1e-7
#: Values compared at once (the first axis is cut into slabs of about this many values: bounded memory).
SLAB = 1 << 22


@dataclass(frozen=True)
class Bound:
    """lo·u ≤ ``table``[``at``] ≤ hi·u for every value, where u = ``scale(recipe, tables)`` (1 without one)
    times the table ``of`` (1 without one; aligned by dimension name, broadcast over the dimensions it lacks).

    ``table`` ``group/*``: every table of the group.  ``lo``/``hi`` None: no bound on that side (both None: finite
    only).  ``keys``: the recipe key paths (``phong.diffuse``) that drive
    the table, named with their values in a refusal; ``text``: the bound in words, for the message
    (``"0 ≤ re ≤ α·(k_a + k_d + k_s)"``; by default ``[lo, hi]``)."""

    table: str
    lo: float | None
    hi: float | None
    of: str | None = None
    scale: Callable[[Mapping, Mapping], float] | None = None
    at: tuple | None = None
    keys: tuple[str, ...] = ()
    text: str = ""

    def __post_init__(self):
        if self.at is not None and self.of is not None:
            raise ValueError(f"bound of {self.table}: 'at' and 'of' exclude each other")

    def describe(self) -> str:
        if self.text:
            return self.text
        lo, hi = ("−∞" if self.lo is None else f"{self.lo:g}"), ("∞" if self.hi is None else f"{self.hi:g}")
        return f"[{lo}, {hi}]" + (" × " + self.of if self.of else "") + (" × scale" if self.scale else "")


def _drivers(recipe: Mapping, keys) -> str:
    given = {k: get_path(recipe, k) for k in keys}
    named = ", ".join(f"{k}={v}" if v is not None else f"{k} (default)" for k, v in given.items())
    return f"the recipe drives it: {named}" if named else "check the recipe"


def _aligned(ref: np.ndarray, ref_dims, dims) -> np.ndarray:
    """``ref`` (dims ``ref_dims``) transposed and expanded to broadcast against an array of ``dims``."""
    order = [d for d in dims if d in ref_dims]
    if len(order) != len(ref_dims):
        raise ValueError(f"bound reference dims {ref_dims} are not a subset of {dims}")
    ref = np.transpose(ref, [list(ref_dims).index(d) for d in order])
    return ref.reshape([ref.shape[order.index(d)] if d in ref_dims else 1 for d in dims])


def _slack(limit: np.ndarray, dtype) -> np.ndarray:
    """The module docstring's tolerance at the bound ``limit`` for values stored as ``dtype``."""
    info = np.finfo(dtype if np.issubdtype(dtype, np.floating) else np.float64)
    return (RTOL + float(info.eps)) * np.abs(limit) + ATOL + float(info.smallest_subnormal)


def _refuse(where: str, b: Bound, recipe: Mapping, v: np.ndarray, edge: np.ndarray, excess: np.ndarray, s: int):
    idx = np.unravel_index(int(np.argmax(excess)), excess.shape)
    at = [int(i) + (s if k == 0 else 0) for k, i in enumerate(idx)]
    n = int(np.count_nonzero(excess > 0))
    raise errors.BoundsError(
        f"{where} breaks its bound {b.describe()}: {n} value{'s' if n > 1 else ''} beyond it "
        f"(worst {v[idx]:.6g} against {edge[idx]:.6g}, at index {at}); {_drivers(recipe, b.keys)}"
    )


def check_bounds(kind: str, bounds, recipe: Mapping, tables: Mapping[str, tuple[np.ndarray, tuple]], file: str = "") -> None:
    """Raise unless every table of ``tables`` (name → (data, dims)) lies in the ``bounds`` declared for it.

    NonFiniteError for NaN or infinity, BoundsError for a finite value beyond a bound (with the tolerance of the
    module docstring); both name the kind, the ``file``, the table, the worst value and the recipe keys with their
    values.  The first axis is taken in slabs of about :data:`SLAB` values (memory stays small for any table)."""
    for b in bounds:
        names = [n for n in tables if n.startswith(b.table[:-1])] if b.table.endswith("/*") else [b.table]
        for name in names:
            if name in tables and (b.of is None or b.of in tables):
                _check(f"{kind}{' ' + file if file else ''}: {name}", b, recipe, tables, *tables[name])


def _check(where: str, b: Bound, recipe: Mapping, tables: Mapping, data, dims) -> None:
    data = np.atleast_1d(np.asarray(data))
    if b.at is not None:
        data = np.atleast_1d(data[b.at])
        where += f"[{', '.join('...' if i is ... else str(i) for i in b.at)}]"
    u = float(b.scale(recipe, tables)) if b.scale is not None else 1.0
    ref = None if b.of is None else _aligned(np.asarray(tables[b.of][0], np.float64), tables[b.of][1], dims)
    step = max(1, SLAB // max(1, int(np.prod(data.shape[1:], dtype=np.int64))))
    for s in range(0, len(data), step):
        v = data[s : s + step].astype(np.float64)
        if not np.isfinite(v).all():
            raise errors.NonFiniteError(
                f"{where} is not finite ({int(np.count_nonzero(~np.isfinite(v)))} NaN/inf values); {_drivers(recipe, b.keys)}"
            )
        r = u if ref is None else u * (ref[s : s + step] if ref.shape[0] == len(data) else ref)
        for limit, sign in ((b.lo, -1.0), (b.hi, 1.0)):
            if limit is not None:
                edge = np.broadcast_to(limit * np.asarray(r, np.float64), v.shape)
                excess = sign * (v - edge) - _slack(edge, data.dtype)
                if (excess > 0).any():
                    _refuse(where, b, recipe, v, edge, excess, s)
