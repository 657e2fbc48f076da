"""The benchmark parts: what each measures, whether it can run here, the run context, and the example
inputs (recipes, scenes, grooms) the parts read."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .. import errors
from ._figure import Figure

#: Where the example inputs are: the copy an installed wheel carries (pyproject.toml maps the repository's
#: ``tables/`` recipes, scenes and grooms to the data package ``hairlut.examples``), else a clone's ``tables/``.
EXAMPLES = (Path(__file__).resolve().parents[1] / "examples", Path(__file__).resolve().parents[2] / "tables")


def example(name: str) -> Path:
    """The example input ``name``, relative to the repository's ``tables/`` folder (``"hrir-default.toml"``,
    ``"scenes/sintel-groom.toml"``, ``"grooms/sintel_lite.tfx"``): the installed wheel's copy, else the clone's.
    The scenes name their grooms relative to themselves (``../grooms/``), which both copies keep."""
    for root in EXAMPLES:
        if (root / name).is_file():
            return root / name
    raise errors.AssetNotFoundError(f"example input {name!r}: not in {' nor '.join(str(r) for r in EXAMPLES)}")


@dataclass
class Context:
    """What a part's runner gets: the size of the run, a scratch folder, and where to report."""

    quick: bool
    workdir: Path
    progress: Callable[[str], None] = lambda message: None
    notes: dict[str, list[str]] = field(default_factory=dict)
    images: dict[str, list[tuple[str, Callable[[Path], Path]]]] = field(default_factory=dict)

    def note(self, part: str, text: str) -> None:
        """A sentence for the part's section of the report (what the reference is, what was skipped)."""
        self.notes.setdefault(part, []).append(text)

    def image(self, part: str, title: str, draw: Callable[[Path], Path]) -> None:
        """A figure of the part's own beside its time-against-error plots (a heat map, say): ``draw(path)`` writes
        the PNG at ``path`` (``plots/<part>-<title>.png`` of the run's folder) and returns it; the report shows it
        under ``title`` at the end of the part's section."""
        self.images.setdefault(part, []).append((title, draw))


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
