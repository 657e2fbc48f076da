"""Every stress case, in table order, and the runner.

:func:`run_stress` runs the selected cases one after another (each in its own scratch
folder, each timed), catching nothing but reporting everything: an exception inside a case
is that case's fault (``fail``), not a crash of the whole run.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from .. import errors
from ._density import CASES as DENSITY
from ._gpu import CASES as GPU
from ._report import Report, machine
from ._sh import CASES as SH
from ._shadows import CASES as SHADOWS
from ._storage import CASES as STORAGE
from ._tally import Case, Context, Result, Tally

#: Every case, in the order of the table.
CASES: tuple[Case, ...] = (*SH, *DENSITY, *SHADOWS, *STORAGE, *GPU)


def case_names() -> list[str]:
    """Every case's name, in table order."""
    return [c.name for c in CASES]


def select(only=None) -> list[Case]:
    """The cases named in ``only`` (names, or area prefixes such as ``sh``), in table order; all when None."""
    if only is None:
        return list(CASES)
    wanted = [w.strip() for w in ([only] if isinstance(only, str) else only) if w.strip()]
    areas = {c.area for c in CASES}
    for w in wanted:
        if w not in areas and w not in case_names():
            raise errors.ValidationError("only", w, f"not a stress case or area; cases: {', '.join(case_names())}")
    if not wanted:
        raise errors.ValidationError("only", only, "name at least one case or area")
    return [c for c in CASES if c.name in wanted or c.area in wanted]


def run_case(case: Case, *, quick: bool = False, reference: Callable | None = None, workdir=None) -> Result:
    """Run one case; ``reference`` replaces the case's own float64 reference (used to show a case can fail)."""
    tally = Tally(case.tolerance)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="hairlut-stress-", dir=workdir) as tmp:
        ctx = Context(quick, case.reference if reference is None else reference, Path(tmp))
        try:
            case.body(tally, ctx)
        except Exception as exc:
            tally.fault(f"raised {type(exc).__name__}: {exc}")
    return tally.result(case, time.perf_counter() - t0)


def run_stress(
    *, quick: bool = False, only=None, references: dict | None = None, progress: Callable | None = None, workdir=None
) -> Report:
    """Run the stress cases and return their :class:`Report`.

    ``only``: case names or areas (``sh``, ``hrir``, ``shadow``, ``storage``, ``gpu``);
    ``references``: {case name: callable} replacing those cases' float64 references (each
    with the signature of the case's own); ``progress(done, total, name)`` after each case.
    """
    cases = select(only)
    references = dict(references or {})
    unknown = sorted(set(references) - set(case_names()))
    if unknown:
        raise errors.ValidationError("references", unknown[0], "not a stress case")
    t0 = time.perf_counter()
    results = []
    for i, case in enumerate(cases):
        if progress:
            progress(i, len(cases), case.name)
        results.append(run_case(case, quick=quick, reference=references.get(case.name), workdir=workdir))
    if progress:
        progress(len(cases), len(cases), "")
    return Report(tuple(results), quick, machine(), time.perf_counter() - t0)
