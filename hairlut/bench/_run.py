"""Run parts, derive ratios and Pareto fronts, and write results.json, report.md and the plots."""

from __future__ import annotations

import json
import math
import tempfile
import time
import traceback
from pathlib import Path

from ..assets import atomic_write_bytes, check_writable
from ._figure import Figure, derive, tables
from ._machine import machine
from ._parts import Context, Part, select
from ._plot import plot_table, slug
from ._report import portable, report_md


def _json_safe(x):
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    if isinstance(x, dict):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    if hasattr(x, "item") and callable(x.item):  # numpy scalars
        return _json_safe(x.item())
    return x


class BenchInterrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`run_bench`: the report of the parts that finished was written, marked partial.
    ``results`` is what results.json holds (``partial``: the part interrupted and the parts not run).  A
    KeyboardInterrupt still, so a caller that does not know it stops as on any Ctrl-C."""

    def __init__(self, results: dict):
        super().__init__("interrupted")
        self.results = results


def _run_part(part: Part, ctx: Context, say) -> tuple[dict, list[Figure]]:
    """One part's record (status, reason, seconds, notes) and its figures; a failure is recorded, not raised."""
    info, got = {"title": part.title, "status": "ok", "reason": None}, []
    reason = part.unavailable()
    if reason:
        info.update(status="skipped", reason=reason)
        say(f"{part.name}: skipped ({reason})")
    else:
        say(f"{part.name}: running")
        t0 = time.perf_counter()
        try:
            got = derive(part.run(ctx))
        except Exception as exc:
            info.update(status="failed", reason=f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc(limit=6))
            say(f"{part.name}: failed ({type(exc).__name__}: {exc})")
        info["seconds"] = time.perf_counter() - t0
        say(f"{part.name}: {info['status']} in {info['seconds']:.1f} s")
    info["notes"] = ctx.notes.get(part.name, [])
    info["images"] = [title for title, _ in ctx.images.get(part.name, [])]
    return info, got


def run_bench(out, *, registry: dict[str, Part], only: str | list[str] | None = None, quick: bool = False, progress=None) -> dict:
    """Run the selected parts of ``registry`` (all when ``only`` is None; :func:`select`) and write
    ``out``/results.json, ``out``/report.md and ``out``/plots/*.png.  ``out`` is checked writable before any part
    runs.  A part that cannot run here is recorded as skipped with its reason; one that fails is recorded with its
    error and the others still run.  Returns the results document (what results.json holds).  On Ctrl-C the report
    of the parts that finished is written, marked partial (``results["partial"]``: the part interrupted and those
    not run), and :class:`BenchInterrupted` is raised."""
    parts = select(registry, only)
    out = Path(out)
    check_writable(out, folder=True)
    out.mkdir(parents=True, exist_ok=True)
    say = progress or (lambda message: None)
    start = time.perf_counter()
    figures: list[Figure] = []
    results = {"quick": quick, "machine": machine(), "partial": None, "parts": {}}
    with tempfile.TemporaryDirectory(prefix="hairlut-bench-") as tmp:
        ctx = Context(quick=quick, workdir=Path(tmp), progress=say)
        for i, part in enumerate(parts):
            t0 = time.perf_counter()
            try:
                results["parts"][part.name], got = _run_part(part, ctx, say)
            except KeyboardInterrupt:
                rest = [p.name for p in parts[i + 1 :]]
                results["partial"] = {"interrupted": part.name, "not_run": rest}
                results["parts"][part.name] = {
                    "title": part.title,
                    "status": "interrupted",
                    "seconds": time.perf_counter() - t0,
                    "reason": "Ctrl-C while it ran; its figures are not kept",
                    "notes": ctx.notes.get(part.name, []),
                }
                for p in parts[i + 1 :]:
                    results["parts"][p.name] = {"title": p.title, "status": "not run", "reason": "the run was interrupted first"}
                say(f"{part.name}: interrupted; not run: {', '.join(rest) or 'none'}")
                break
            figures += got
        images = _draw_images(out, ctx, results)
    results["seconds"] = time.perf_counter() - start
    _write(out, results, figures, images)
    if results["partial"]:
        raise BenchInterrupted(results)
    return results


def _draw_images(out: Path, ctx: Context, results: dict) -> dict[tuple[str, str], str]:
    """The parts' own figures (:meth:`Context.image`) of the parts that finished, drawn into ``out``/plots:
    {(part, title): path relative to ``out``}.  A figure that fails to draw is noted in its part, not raised."""
    drawn = {}
    for part, images in ctx.images.items():
        if results["parts"].get(part, {}).get("status") != "ok":
            continue
        for title, draw in images:
            try:
                path = draw(out / "plots" / f"{slug(part, title)}.png")
            except Exception as exc:
                results["parts"][part]["notes"].append(f"figure {title!r} not drawn ({type(exc).__name__}: {exc})")
                continue
            drawn[(part, title)] = Path(path).relative_to(out).as_posix()
    return drawn


def _write(out: Path, results: dict, figures: list[Figure], images: dict | None = None) -> None:
    """results.json, report.md, the plots of ``figures`` and the parts' own ``images`` (already drawn)."""
    plots = {}
    for (part, name), rows in tables(figures).items():
        path = plot_table(rows, out / "plots" / f"{slug(part, name)}.png", f"{part}: {name}")
        if path is not None:
            plots[(part, name)] = path.relative_to(out).as_posix()
    results["figures"] = [f.to_json() for f in figures]
    results["plots"] = {f"{p}/{n}": v for (p, n), v in {**plots, **(images or {})}.items()}
    atomic_write_bytes(out / "results.json", portable(json.dumps(_json_safe(results), indent=2)).encode())
    atomic_write_bytes(out / "report.md", report_md(results, figures, plots, images).encode())
