"""Progress bars on stderr for bakes: one per bake (:class:`Progress`), or one per named bake (:class:`Bars`)."""

from __future__ import annotations

import sys
import time

import click


def _clock(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    if seconds >= 3600:
        return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"
    return f"{seconds // 60}:{seconds % 60:02d}"


class Progress:
    """A one-line progress bar on stderr: units done/total, rate, ETA (rate counts only units baked now)."""

    def __init__(self, enabled: bool, width: int = 28, label: str = "hrir", unit: str = "sectors"):
        self.enabled, self.width, self.label, self.unit = enabled, width, label, unit
        self.tty = sys.stderr.isatty()
        self.start = time.perf_counter()
        self.first = None  # units already done (resumed) when baking began

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if self.first is None:
            self.first = (done, now)
        base, t0 = self.first
        rate = (done - base) / (now - t0) if done > base and now > t0 else None
        eta = (total - done) / rate if rate else None
        fill = int(self.width * done / max(total, 1))
        bar = "#" * fill + "-" * (self.width - fill)
        u = self.unit
        line = (f"{self.label} [{bar}] {done}/{total} {u}  "
                f"{'%.1f %s/s' % (rate, u) if rate else '-- %s/s' % u}  "
                f"ETA {_clock(eta) if eta is not None else '--:--'}  elapsed {_clock(now - self.start)}")
        click.echo(("\r" + line) if self.tty else line, err=True, nl=not self.tty)

    def close(self) -> None:
        if self.enabled and self.tty:
            click.echo("", err=True)


class Bars:
    """One :class:`Progress` bar per named bake, as ``hairlut.plan.bake``'s ``progress(name, done, total)``."""

    def __init__(self, enabled: bool):
        self.enabled, self.bars = enabled, {}

    def __call__(self, name: str, done: int, total: int) -> None:
        self.bars.setdefault(name, Progress(self.enabled, label=name))(done, total)

    def close(self) -> None:
        for bar in self.bars.values():
            bar.close()
