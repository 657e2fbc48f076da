"""What one stress case checks and records: non-finite values, bounds, the worst error, rejections.

A case body receives a :class:`Tally` and fills it: every array it meets goes through
:meth:`Tally.finite` (NaN and Inf are counted, never passed on), every quantity with a bound
through :meth:`Tally.within` (α and T in [0, 1], radiance ≥ 0), every comparison with its
float64 reference through :meth:`Tally.compare` (the worst error, in the case's own metric,
against the case's stated tolerance), every bad input through :meth:`Tally.rejects` (a
:class:`hairlut.errors.HairlutError`, not a NaN).  Counted-but-allowed effects (SH ringing)
go through :meth:`Tally.count` and :meth:`Tally.peak`.  :meth:`Tally.result` turns the record into a :class:`Result`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .. import errors


@dataclass(frozen=True)
class Result:
    """One row of the stress table.  ``status`` is ``pass``, ``fail`` or ``skip`` (a case that cannot
    run here, such as the GPU case on a CPU-only machine); ``worst`` is the largest error seen
    against the float64 reference (None when the case compares nothing)."""

    name: str
    area: str
    status: str
    worst: float | None
    tolerance: float | None
    reason: str
    non_finite: int
    out_of_bounds: int
    counted: dict
    faults: tuple
    notes: tuple
    seconds: float

    @property
    def passed(self) -> bool:
        return self.status != "fail"

    def as_dict(self) -> dict:
        """The case's result as a JSON object."""
        return {
            "name": self.name,
            "area": self.area,
            "status": self.status,
            "worst_error": self.worst,
            "tolerance": self.tolerance,
            "tolerance_reason": self.reason,
            "non_finite": self.non_finite,
            "out_of_bounds": self.out_of_bounds,
            "counted": dict(self.counted),
            "faults": list(self.faults),
            "notes": list(self.notes),
            "seconds": self.seconds,
        }


@dataclass(frozen=True)
class Case:
    """A stress case: its ``name`` (``area.what``), a one-line ``what``, the ``tolerance`` on its error
    metric with the one-line ``reason`` for it, its default float64 ``reference`` (a callable the
    body uses for every comparison; :func:`hairlut.stress.run_stress` can replace it) and the
    ``body(tally, ctx)`` that runs it."""

    name: str
    what: str
    tolerance: float | None
    reason: str
    reference: Callable | None
    body: Callable

    @property
    def area(self) -> str:
        return self.name.split(".", 1)[0]


@dataclass(frozen=True)
class Context:
    """What a case body may depend on: ``quick`` (the smaller sweep), the ``reference`` in force
    (the case's own, or the one a caller injected) and a scratch ``workdir`` for baked files."""

    quick: bool
    reference: Callable | None
    workdir: object


@dataclass
class Tally:
    """The running record of one case (module docstring)."""

    tolerance: float | None
    worst: float | None = None
    non_finite: int = 0
    out_of_bounds: int = 0
    counted: dict = field(default_factory=dict)
    faults: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    skipped: str | None = None
    worst_at: str | None = None

    def finite(self, label: str, x) -> np.ndarray:
        """``x`` as a float64 array; its NaN and Inf entries are counted (a fault)."""
        a = np.asarray(x, dtype=np.float64)
        bad = int(a.size - np.count_nonzero(np.isfinite(a)))
        if bad:
            self.non_finite += bad
            self.faults.append(f"{label}: {bad} non-finite of {a.size}")
        return a

    def within(self, label: str, x, lo: float | None = None, hi: float | None = None, slack: float = 0.0) -> None:
        """Count entries of ``x`` outside [lo − slack, hi + slack] (a fault); NaN counts as non-finite."""
        a = self.finite(label, x)
        a = a[np.isfinite(a)]
        out = np.zeros(a.shape, bool)
        if lo is not None:
            out |= a < lo - slack
        if hi is not None:
            out |= a > hi + slack
        n = int(out.sum())
        if n:
            self.out_of_bounds += n
            self.faults.append(
                f"{label}: {n} of {a.size} outside [{lo}, {hi}] (range {float(a.min()):.3g} … {float(a.max()):.3g})"
            )

    def error(self, label: str, err: float) -> float:
        """Record an error already measured in the case's metric (a non-finite error is a fault)."""
        err = float(err)
        if not math.isfinite(err):
            self.non_finite += 1
            self.faults.append(f"{label}: the error is not finite")
            return err
        if self.worst is None or err > self.worst:
            self.worst, self.worst_at = err, label
        return err

    def compare(self, label: str, got, ref, scale: float | None = None) -> float:
        """max |got − ref| / scale (scale: max |ref|, or 1 where that is 0), recorded as an error."""
        g = self.finite(label, got)
        r = np.asarray(ref, dtype=np.float64)
        if g.shape != r.shape:
            self.faults.append(f"{label}: shape {g.shape} against the reference's {r.shape}")
            return math.inf
        if scale is None:
            scale = float(np.abs(r).max()) if r.size else 0.0
        scale = scale or 1.0
        return self.error(label, float(np.abs(g - r).max()) / scale if g.size else 0.0)

    def rejects(self, label: str, call: Callable, expected=errors.HairlutError) -> None:
        """``call()`` must raise ``expected``; returning anything (NaN or not) or raising anything else is a fault."""
        try:
            out = call()
        except expected:
            self.count("rejected", 1)
            return
        except Exception as exc:
            self.faults.append(f"{label}: raised {type(exc).__name__} ({exc}), not a hairlut error")
            return
        try:
            finite = bool(np.all(np.isfinite(np.asarray(out, dtype=np.float64))))
        except (TypeError, ValueError):
            finite = True
        self.faults.append(f"{label}: accepted" + ("" if finite else ", and returned NaN/Inf"))

    def count(self, what: str, n: int) -> None:
        """Add ``n`` to a counted, allowed effect (SH ringing, rejected inputs, saturated α)."""
        self.counted[what] = self.counted.get(what, 0) + int(n)

    def peak(self, what: str, value: float) -> None:
        """Keep the largest ``value`` of an allowed effect (how far α rounded past 1)."""
        self.counted[what] = max(float(value), self.counted.get(what, float(value)))

    def fault(self, message: str) -> None:
        """Record a fault: the case fails, and the message says why."""
        self.faults.append(message)

    def note(self, message: str) -> None:
        """Record a note for the report (a count or a measured gap that does not fail the case)."""
        self.notes.append(message)

    def skip(self, reason: str) -> None:
        """The case cannot run here (reported as ``skip`` with the reason, never as a pass)."""
        self.skipped = reason

    def result(self, case: Case, seconds: float) -> Result:
        """The case's :class:`Result`: skip, or fail on any fault, non-finite value, bound broken or error over the
        tolerance; else pass."""
        if self.skipped is not None:
            status = "skip"
            notes = (self.skipped, *self.notes)
        else:
            over = self.tolerance is not None and self.worst is not None and not self.worst <= self.tolerance
            status = "fail" if (self.faults or self.non_finite or self.out_of_bounds or over) else "pass"
            notes = tuple(self.notes)
            if over:
                notes = (f"worst error at {self.worst_at}", *notes)
        return Result(
            case.name,
            case.area,
            status,
            self.worst,
            case.tolerance,
            case.reason,
            self.non_finite,
            self.out_of_bounds,
            dict(self.counted),
            tuple(self.faults),
            notes,
            seconds,
        )
