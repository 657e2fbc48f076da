"""Part ``scale``: a bake over 1 and 2 local devices and 1 and 2 jax.distributed processes
(``benchmarks/scaling.py``, run as a subprocess; needs two cores or two devices)."""

from __future__ import annotations

from ._figure import Figure
from ._parts import Context, scale_unavailable
from ._scripts import run_script, script_missing

PART = "scale"


def unavailable() -> str | None:
    return script_missing("scaling.py") or scale_unavailable()


def run(ctx: Context) -> list[Figure]:
    sectors = 16 if ctx.quick else 64
    doc = run_script("scaling.py", ["--sectors", str(sectors)], ctx.workdir / "scaling.json",
                     timeout=900 if ctx.quick else 1500)
    figs = []
    for i, r in enumerate(doc["rows"]):
        figs.append(Figure(PART, "hrir bake across devices and processes (time per sector; bitwise-equal outputs)",
                           f"{r['config']} ({r['merge']})", 1.0 / r["steady_rate"], None, "-",
                           {"devices": r["devices"], "processes": r["processes"]}, baseline=i == 0,
                           extra={k: r.get(k) for k in ("bake_s", "wall_s", "assemble_s", "peak_rss_mib", "x_base")}))
    ctx.note(PART, f"benchmarks/scaling.py --sectors {sectors}: steady seconds per sector (the inverse of the steady "
                   "throughput); a bake does not depend on the device count, so there is no error column; load average "
                   f"{doc.get('load')}")
    return figs
