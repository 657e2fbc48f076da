"""One measured figure of a benchmark part, and what the harness derives from a table of them:
ratios against the table's same-run baseline, and the Pareto front of run time against error."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from .. import errors


@dataclass
class Figure:
    """One setting of one part, measured in this run.

    ``table`` groups figures that share a baseline and an error measure (one table and one plot
    in the report); ``seconds`` is the warm run time of the setting (None when the row has no
    time of its own, e.g. a storage-precision row); ``error`` is measured against the table's
    reference (``error_name`` says which); ``baseline`` marks the straightforward method the
    table's ratios are taken against (exactly one per table); ``paper`` marks the papers' own
    settings (reference points on the plots)."""

    part: str
    table: str
    label: str
    seconds: float | None
    error: float | None
    error_name: str
    knobs: dict = field(default_factory=dict)
    baseline: bool = False
    paper: bool = False
    extra: dict = field(default_factory=dict)
    time_ratio: float | None = None
    error_ratio: float | None = None
    pareto: bool = False

    def to_json(self) -> dict:
        """The figure as a JSON object (its dataclass fields)."""
        return asdict(self)


def _finite(x) -> bool:
    return x is not None and math.isfinite(x)


def pareto_front(points: list[tuple[float | None, float | None]]) -> list[bool]:
    """For each (seconds, error), whether it is on the Pareto front: no other point is at least as
    fast and at least as accurate and strictly better in one.  Points missing either value are
    never on it; equal points are all on it."""
    out = []
    for i, (t, e) in enumerate(points):
        if not (_finite(t) and _finite(e)):
            out.append(False)
            continue
        dominated = any(
            j != i and _finite(t2) and _finite(e2) and t2 <= t and e2 <= e and (t2 < t or e2 < e)
            for j, (t2, e2) in enumerate(points)
        )
        out.append(not dominated)
    return out


def tables(figures: list[Figure]) -> dict[tuple[str, str], list[Figure]]:
    """Figures grouped by (part, table), in the order they were measured."""
    out: dict[tuple[str, str], list[Figure]] = {}
    for f in figures:
        out.setdefault((f.part, f.table), []).append(f)
    return out


def derive(figures: list[Figure]) -> list[Figure]:
    """Fill ``time_ratio`` and ``error_ratio`` (each figure over its table's same-run baseline) and
    ``pareto``, in place; returns ``figures``.  A table without exactly one baseline is refused."""
    for (part, name), rows in tables(figures).items():
        base = [f for f in rows if f.baseline]
        if len(base) != 1:
            raise errors.ValidationError(f"{part}.{name}", len(base), "a table needs exactly one same-run baseline")
        b = base[0]
        for f in rows:
            f.time_ratio = f.seconds / b.seconds if _finite(f.seconds) and _finite(b.seconds) and b.seconds > 0 else None
            f.error_ratio = f.error / b.error if _finite(f.error) and _finite(b.error) and b.error > 0 else None
        for f, on in zip(rows, pareto_front([(f.seconds, f.error) for f in rows])):
            f.pareto = on
    return figures
