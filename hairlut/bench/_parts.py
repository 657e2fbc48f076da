"""The benchmark parts: what each measures, whether it can run here, and the run context."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .. import errors
from ._figure import Figure


@dataclass
class Context:
    """What a part's runner gets: the size of the run, a scratch folder, and where to report."""

    quick: bool
    workdir: Path
    progress: Callable[[str], None] = lambda message: None
    notes: dict[str, list[str]] = field(default_factory=dict)

    def note(self, part: str, text: str) -> None:
        """A sentence for the part's section of the report (what the reference is, what was skipped)."""
        self.notes.setdefault(part, []).append(text)


@dataclass(frozen=True)
class Part:
    """A benchmark part: ``run(ctx)`` returns its figures; ``unavailable()`` says why it cannot
    run on this machine (None when it can)."""

    name: str
    title: str
    run: Callable[[Context], list[Figure]]
    unavailable: Callable[[], str | None] = lambda: None


def timed(fn, repeat: int = 3):
    """(best wall seconds over ``repeat`` runs, the last result)."""
    best, out = float("inf"), None
    for _ in range(max(1, repeat)):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


def scale_unavailable() -> str | None:
    """The scale part pins one process (or device) per core: it needs two cores."""
    cores = len(os.sched_getaffinity(0))
    return None if cores >= 2 else f"one core here ({cores}): nothing to scale over"


def select(registry: dict[str, Part], only: str | list[str] | None, field: str = "only") -> list[Part]:
    """The parts named in ``only`` (a list, or names separated by commas), in registry order; all when None.  A
    selection that names no part ("" or ",") or an unknown part is refused, naming ``field``, the value and the parts."""
    if only is None:
        return list(registry.values())
    names = [n.strip() for n in (only.split(",") if isinstance(only, str) else only)]
    names = [n for n in names if n]
    parts = ", ".join(registry)
    if not names:
        raise errors.ValidationError(field, only, f"names no part; give one or more of {parts}, separated by commas")
    for name in names:
        if name not in registry:
            raise errors.ValidationError(field, name, f"no such part; the parts are {parts}")
    return [p for n, p in registry.items() if n in names]
