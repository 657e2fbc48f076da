"""report.md: one section per part, one table per (part, table) with each figure beside its
same-run baseline as a ratio, the plot beside it, and a headline table across parts."""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

from ._figure import Figure, tables
from ._machine import machine_line


def portable(text: str) -> str:
    """``text`` without this machine's absolute paths, so that a report kept in the documentation names none: the
    folder hairlut is installed in (a clone's root, or site-packages) and the working folder are dropped (paths
    below them read relative), the temporary folder reads ``$TMPDIR`` and the home folder ``~``."""
    roots = {
        str(Path(__file__).resolve().parents[2]): "",
        os.getcwd(): "",
        tempfile.gettempdir(): "$TMPDIR/",
        str(Path.home()): "~/",
    }
    for root, short in sorted(roots.items(), key=lambda kv: -len(kv[0])):
        if root.strip(os.sep):
            text = text.replace(root.rstrip(os.sep) + os.sep, short)
    return text


def _num(x, fmt: str) -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def _seconds(x) -> str:
    if x is None:
        return "-"
    return f"{x * 1e3:.3g} ms" if x < 1 else f"{x:.3g} s"


def _cell(x: str) -> str:
    return str(x).replace("|", "\\|")


def _knobs(k: dict) -> str:
    return ", ".join(f"{a}={format(b, '.3g') if isinstance(b, float) else b}" for a, b in k.items() if b is not None) or "-"


def _marks(f: Figure) -> str:
    return " ".join(m for m, on in (("baseline", f.baseline), ("paper", f.paper), ("Pareto", f.pareto)) if on)


def table_md(rows: list[Figure]) -> str:
    """The markdown table of one (part, table)."""
    head = ["setting", "knobs", "time", "× baseline time", _cell(rows[0].error_name), "× baseline error", ""]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for f in rows:
        out.append(
            "| "
            + " | ".join(
                _cell(c)
                for c in [
                    f.label,
                    _knobs(f.knobs),
                    _seconds(f.seconds),
                    _num(f.time_ratio, ".3g"),
                    _num(f.error, ".3g"),
                    _num(f.error_ratio, ".3g"),
                    _marks(f),
                ]
            )
            + " |"
        )
    return "\n".join(out)


def headline(figures: list[Figure]) -> list[dict]:
    """Per table: the baseline, the fastest setting with at most the baseline's error, the most accurate one."""
    out = []
    for (part, name), rows in tables(figures).items():
        base = next(f for f in rows if f.baseline)
        timed = [f for f in rows if f.seconds is not None and f.error is not None]
        ok = [f for f in timed if base.error is not None and f.error <= base.error]
        fast = min(ok, key=lambda f: f.seconds, default=None)
        best = min(timed, key=lambda f: (f.error, f.seconds), default=None)
        out.append({"part": part, "table": name, "error_name": base.error_name, "baseline": base, "fastest": fast, "best": best})
    return out


def headline_md(figures: list[Figure]) -> str:
    rows = [
        "| part | table | baseline (time, error) | fastest at ≤ baseline error (× time) | most accurate (error, × time) |",
        "|---|---|---|---|---|",
    ]
    for h in headline(figures):
        b, fa, be = h["baseline"], h["fastest"], h["best"]
        shown = f", {h['error_name']} {_num(b.error, '.3g')}" if b.error is not None else ""
        cells = [
            h["part"],
            h["table"],
            f"{b.label} ({_seconds(b.seconds)}{shown})",
            f"{fa.label} ({_num(fa.time_ratio, '.3g')}×)" if fa else "-",
            f"{be.label} ({_num(be.error, '.3g')}, {_num(be.time_ratio, '.3g')}×)" if be else "-",
        ]
        rows.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return "\n".join(rows)


def report_md(
    results: dict, figures: list[Figure], plots: dict[tuple[str, str], str], images: dict[tuple[str, str], str] | None = None
) -> str:
    """The whole report.md text: plots referenced relative to it, no local path (:func:`portable`), so that it
    can be a page of the documentation as it is (``hairlut bench --out docs/bench``)."""
    m = results["machine"]
    gpu = any(d.get("platform") == "gpu" for d in m.get("devices", []))
    lines = [
        "# hairlut bench",
        "",
        f"{'Quick' if results['quick'] else 'Full'} run, {results['seconds']:.0f} s, on "
        f"{'a GPU' if gpu else 'the CPU'}: {machine_line(m)}.",
        "",
        "Every time is a warm best-of-N wall time on this machine; every ratio is against the baseline "
        "measured in the same run (marked `baseline`), so load on a shared machine cancels to first order. "
        "`paper` marks the papers' own settings; `Pareto` the settings no other one beats in both time "
        "and error.",
        "",
    ]
    if results.get("partial"):
        pr = results["partial"]
        lines += [
            f"**Partial run**: interrupted (Ctrl-C) while `{pr['interrupted']}` ran; not run: "
            f"{', '.join(f'`{n}`' for n in pr['not_run']) or 'none'}. The figures below are those of the parts "
            "that finished.",
            "",
        ]
    lines += ["## Headline", "", headline_md(figures), ""]
    grouped = tables(figures)
    for name, info in results["parts"].items():
        lines += [f"## {name}: {info['title']}", ""]
        if info["status"] != "ok":
            lines += [f"*{info['status']}*: {info['reason']}", ""]
            continue
        lines += [f"({info['seconds']:.1f} s)", ""]
        lines += [f"- {n}" for n in info.get("notes", [])]
        lines += [""] if info.get("notes") else []
        for (part, tname), rows in grouped.items():
            if part != name:
                continue
            lines += [f"### {tname}", "", table_md(rows), ""]
            if (part, tname) in plots:
                lines += [f"![{part}: {tname}]({plots[(part, tname)]})", ""]
        for (part, title), path in (images or {}).items():
            if part == name:
                lines += [f"### {title}", "", f"![{part}: {title}]({path})", ""]
    return portable("\n".join(lines))
