"""The memory budget: estimate what a request allocates before allocating it.

Every boundary where a user's number turns into an allocation (a scene's strand
count and render sizes, a recipe's grids and angle counts, a file's declared
shapes) asks :func:`check` with its estimate in bytes and the key that drives it.
Above the limit the request is refused with a :class:`hairlut.errors.BudgetError`
that names the key, the value, the estimate and the limit, instead of a
``MemoryError`` (or an OOM kill) half-way through.

The limit, in order of precedence:

1. the ``limit=`` keyword of the call (bytes);
2. the environment variable ``HAIRLUT_MEMORY_LIMIT``: bytes, or a number with a
   binary suffix ``K``, ``M``, ``G`` or ``T`` (``HAIRLUT_MEMORY_LIMIT=8G``);
3. half of the machine's physical memory (``os.sysconf``), or 8 GiB where the
   platform does not say.

The estimates are lower bounds of the peak (the arrays that must exist at once);
a request under the limit can still fail for memory, one over it never starts.
"""

from __future__ import annotations

import math
import os
import re

from . import errors

ENV = "HAIRLUT_MEMORY_LIMIT"
FALLBACK = 8 << 30
_SUFFIX = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}
_SPEC = re.compile(r"^\s*([0-9]+(?:\.[0-9]*)?(?:[eE][0-9]+)?)\s*([KMGT]?)(?:i?B)?\s*$", re.IGNORECASE)


def physical_memory() -> int | None:
    """Bytes of physical memory, or None where ``os.sysconf`` does not say."""
    try:
        pages, size = os.sysconf("SC_PHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None
    return pages * size if pages > 0 and size > 0 else None


def parse_size(text: str, field: str = ENV) -> int:
    """``"8G"`` → 8·2³⁰; plain numbers are bytes.  ValidationError naming ``field`` otherwise."""
    m = _SPEC.match(str(text))
    value = float(m.group(1)) * _SUFFIX[m.group(2).upper()] if m else float("nan")
    if not (math.isfinite(value) and value >= 1):
        raise errors.ValidationError(field, text, "a size in bytes, optionally with K, M, G or T (binary), ≥ 1")
    return int(value)


def memory_limit(limit: int | None = None) -> int:
    """The budget in bytes: ``limit``, else ``$HAIRLUT_MEMORY_LIMIT``, else half the physical memory."""
    if limit is not None:
        if isinstance(limit, bool) or not isinstance(limit, (int, float)) or not limit >= 1:
            raise errors.ValidationError("memory_limit", limit, "a positive number of bytes")
        return int(limit)
    env = os.environ.get(ENV)
    if env:
        return parse_size(env)
    phys = physical_memory()
    return phys // 2 if phys else FALLBACK


def describe(nbytes: float) -> str:
    """``1.5 GiB``-style text of a byte count (any size, even absurd ones)."""
    n = float(nbytes)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} PiB"  # pragma: no cover


def source() -> str:
    """Where the current limit comes from (for messages)."""
    return f"${ENV}" if os.environ.get(ENV) else f"half the physical memory; set ${ENV} to change"


def check(field: str, value: object, nbytes: float, what: str, limit: int | None = None) -> float:
    """Refuse (BudgetError naming ``field`` = ``value``) when ``nbytes`` exceeds the budget.

    ``what`` says what the estimate counts (``"the traced reflectance table"``).
    Returns ``nbytes`` so that callers can add estimates up.
    """
    cap = memory_limit(limit)
    if not nbytes <= cap:  # also refuses NaN and inf estimates
        raise errors.BudgetError(
            field, value,
            f"needs about {describe(nbytes)} for {what}, above the memory limit of {describe(cap)} "
            f"({'the limit= argument' if limit is not None else source()})",
            estimate=int(min(nbytes, 2**63 - 1)) if math.isfinite(nbytes) else 2**63 - 1, limit=cap,
        )
    return nbytes


def product(*factors) -> float:
    """The product of ``factors`` as a float (no integer overflow, no huge Python ints)."""
    out = 1.0
    for f in factors:
        out *= float(f)
    return out


__all__ = ["ENV", "check", "describe", "memory_limit", "parse_size", "physical_memory", "product"]
