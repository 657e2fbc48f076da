"""PNG plots of run time against error (log–log), the Pareto front drawn, the papers' settings and
the baseline marked, with matplotlib (Agg: no display needed)."""

from __future__ import annotations

import re
from pathlib import Path

from ..assets import atomic_path
from ._figure import Figure


def plottable(rows: list[Figure]) -> list[Figure]:
    """The figures a log–log plot can show: positive time and error."""
    return [f for f in rows if f.seconds is not None and f.error is not None and f.seconds > 0 and f.error > 0]


def slug(*names: str) -> str:
    return "-".join(re.sub(r"[^a-z0-9]+", "_", n.lower()).strip("_") for n in names)


def plot_table(rows: list[Figure], path: Path, title: str) -> Path | None:
    """One time-against-error plot of a table's figures; None when fewer than two can be shown."""
    pts = plottable(rows)
    if len(pts) < 2:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=110)
    rest = [f for f in pts if not (f.paper or f.baseline)]
    ax.scatter([f.seconds for f in rest], [f.error for f in rest], s=22, c="tab:blue", label="setting", zorder=3)
    front = sorted((f for f in pts if f.pareto), key=lambda f: f.seconds)
    if front:
        xs, ys = [front[0].seconds], [front[0].error]
        for f in front[1:]:
            xs += [f.seconds, f.seconds]
            ys += [ys[-1], f.error]
        ax.plot(xs, ys, "-", c="tab:green", lw=1.2, label="Pareto front", zorder=2)
        ax.scatter(
            [f.seconds for f in front], [f.error for f in front], s=60, facecolors="none", edgecolors="tab:green", zorder=4
        )
    for sel, style in (
        (lambda f: f.baseline, dict(marker="s", c="tab:orange", s=50, label="same-run baseline")),
        (lambda f: f.paper, dict(marker="*", c="tab:red", s=120, label="paper's setting")),
    ):
        chosen = [f for f in pts if sel(f)]
        if chosen:
            ax.scatter([f.seconds for f in chosen], [f.error for f in chosen], zorder=5, **style)
    for f in pts:
        ax.annotate(
            f.label if len(f.label) <= 40 else f.label[:38] + "…",
            (f.seconds, f.error),
            fontsize=6,
            xytext=(3, 3),
            textcoords="offset points",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("run time (s, warm)")
    ax.set_ylabel(rows[0].error_name)
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return path
