"""Progress bars on stderr for bakes, drawn by ``rich.progress``: one per bake (:class:`Progress`), or one per named
bake (:class:`Bars`).

The library knows nothing of them: a bake calls ``progress(done, total)`` (``hairlut.bake.protocol``), first once with the
units already done (resumed from an earlier bake's parts) and then as it goes; the planner's bake calls
``progress(name, done, total)``.  A bar shows the units done of the total, the units resumed, the rate and ETA of
the units baked in this run (resumed ones left out) and the time elapsed.  On a terminal the bars are live; when
stderr is not a terminal (a log file, a pipe) each call prints one plain line with the same figures instead.
"""

from __future__ import annotations

import sys
import time
from datetime import timedelta

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, ProgressColumn, TextColumn, TimeElapsedColumn
from rich.progress import Progress as RichProgress
from rich.table import Column
from rich.text import Text


def _clock(seconds: float) -> str:
    return str(timedelta(seconds=max(0, int(round(seconds)))))


class _Rate(ProgressColumn):
    """Units per second baked in this run (the ``rate`` field, None before a unit is)."""

    def render(self, task) -> Text:
        rate = task.fields["rate"]
        return Text(f"{rate:.1f}/s" if rate else "--/s")


class _Eta(ProgressColumn):
    """The time left at this run's rate."""

    def render(self, task) -> Text:
        rate = task.fields["rate"]
        return Text("ETA " + (_clock((task.total - task.completed) / rate) if rate else "--:--"))


def _columns(tty: bool) -> list:
    bar = [BarColumn(bar_width=None)] if tty else []  # the terminal's width less the figures (Progress(expand=True))

    def text(fmt: str) -> TextColumn:
        return TextColumn(fmt, table_column=Column(no_wrap=True))

    return [
        text("{task.description}"),
        *bar,
        MofNCompleteColumn(table_column=Column(no_wrap=True)),
        text("{task.fields[unit]}"),
        text("{task.fields[resumed]}"),
        _Rate(table_column=Column(no_wrap=True)),
        _Eta(table_column=Column(no_wrap=True)),
        text("elapsed"),
        TimeElapsedColumn(table_column=Column(no_wrap=True)),
    ]


def _unit_of(name: str) -> str:
    """What a planner step's bake counts: its kind's ``Baker.unit`` (the asset steps are named after their kind)."""
    from hairlut import errors
    from hairlut.bake import registry

    try:
        return registry.get(name).unit or "units"
    except errors.ValidationError:
        return "units"


class Bars:
    """One bar per named bake, as ``hairlut.plan.bake``'s ``progress(name, done, total)``; all on one display.
    ``unit``: what every bar counts (default: the unit of the table kind each bar is named after)."""

    def __init__(self, enabled: bool, unit: str | None = None):
        self.enabled, self.unit = enabled, unit
        self.tty = sys.stderr.isatty()
        # force_terminal: our own test of stderr decides, not FORCE_COLOR or TTY_COMPATIBLE in the environment
        self.console = Console(stderr=True, force_terminal=self.tty, force_jupyter=False, width=None if self.tty else 160)
        self.rich = RichProgress(*_columns(self.tty), console=self.console, refresh_per_second=4, expand=self.tty)
        self.tasks = {}  # name: (task id, units done at the first call, its time)
        self.live = False

    def __call__(self, name: str, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if name not in self.tasks:
            task = self.rich.add_task(
                name,
                total=total,
                completed=done,
                unit=self.unit or _unit_of(name),
                rate=None,
                resumed=f"resumed {done}" if done else "",
            )
            self.tasks[name] = task, done, now
        task, base, t0 = self.tasks[name]
        rate = (done - base) / (now - t0) if done > base and now > t0 else None
        self.rich.update(task, completed=done, total=total, rate=rate)
        if self.tty:
            if not self.live:
                self.rich.start()
                self.live = True
        else:
            self.console.print(self.rich.make_tasks_table([t for t in self.rich.tasks if t.id == task]))

    def close(self) -> None:
        if self.live:
            self.rich.stop()  # the bars stay on screen as they ended
            self.live = False


class Progress(Bars):
    """A single bar, as a bake's ``progress(done, total)``."""

    def __init__(self, enabled: bool, label: str = "hrir", unit: str = "sectors"):
        super().__init__(enabled, unit)
        self.label = label

    def __call__(self, done: int, total: int) -> None:
        super().__call__(self.label, done, total)
