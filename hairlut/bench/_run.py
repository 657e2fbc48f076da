"""Run parts, derive ratios and Pareto fronts, and write results.json, report.md and the plots."""

from __future__ import annotations

import json
import math
import tempfile
import time
import traceback
from pathlib import Path

from ..assets import atomic_write_bytes
from ._figure import Figure, derive, tables
from ._machine import machine
from ._parts import Context, Part, select
from ._plot import plot_table, slug
from ._report import report_md


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


def run_bench(out, *, registry: dict[str, Part], only: list[str] | None = None, quick: bool = False,
              progress=None) -> dict:
    """Run the selected parts of ``registry`` (all when ``only`` is None) and write ``out``/results.json,
    ``out``/report.md and ``out``/plots/*.png.  A part that cannot run here is recorded as skipped
    with its reason; one that fails is recorded with its error and the others still run.  Returns
    the results document (what results.json holds)."""
    parts = select(registry, only)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    say = progress or (lambda message: None)
    start = time.perf_counter()
    figures: list[Figure] = []
    results = {"quick": quick, "machine": machine(), "parts": {}}
    with tempfile.TemporaryDirectory(prefix="hairlut-bench-") as tmp:
        ctx = Context(quick=quick, workdir=Path(tmp), progress=say)
        for part in parts:
            info = {"title": part.title, "status": "ok", "reason": None}
            reason = part.unavailable()
            if reason:
                info.update(status="skipped", reason=reason)
                say(f"{part.name}: skipped ({reason})")
            else:
                say(f"{part.name}: running")
                t0 = time.perf_counter()
                try:
                    got = part.run(ctx)
                    derive(got)
                    figures += got
                except Exception as exc:  # noqa: BLE001 - one failing part must not lose the others' figures
                    info.update(status="failed", reason=f"{type(exc).__name__}: {exc}",
                                traceback=traceback.format_exc(limit=6))
                    say(f"{part.name}: failed ({type(exc).__name__}: {exc})")
                info["seconds"] = time.perf_counter() - t0
                say(f"{part.name}: {info['status']} in {info['seconds']:.1f} s")
            info["notes"] = ctx.notes.get(part.name, [])
            results["parts"][part.name] = info
    results["seconds"] = time.perf_counter() - start
    plots = {}
    for (part, name), rows in tables(figures).items():
        path = plot_table(rows, out / "plots" / f"{slug(part, name)}.png", f"{part}: {name}")
        if path is not None:
            plots[(part, name)] = path.relative_to(out).as_posix()
    results["figures"] = [f.to_json() for f in figures]
    results["plots"] = {f"{p}/{n}": v for (p, n), v in plots.items()}
    atomic_write_bytes(out / "results.json", json.dumps(_json_safe(results), indent=2).encode())
    atomic_write_bytes(out / "report.md", report_md(results, figures, plots).encode())
    return results
