"""Part ``scale``: a bake over 1 and 2 local devices and 1 and 2 jax.distributed processes, each
pinned to its cores (``benchmarks/scaling.py``, run as a subprocess; needs two cores)."""

from __future__ import annotations

from ._figure import Figure
from ._parts import Context, scale_unavailable
from ._scripts import run_script, script_missing

PART = "scale"


def unavailable() -> str | None:
    return script_missing("scaling.py") or scale_unavailable()


def run(ctx: Context) -> list[Figure]:
    args = (["--sectors", "16", "--repeat", "1", "--sizes", "64", "--blocks", "4,16", "--no-projection"] if ctx.quick else
            ["--sectors", "64", "--repeat", "2", "--sizes", "256", "--blocks", "4,16,64"])
    doc = run_script("scaling.py", args, ctx.workdir / "scaling.json", timeout=900 if ctx.quick else 1500)
    figs = []
    for i, r in enumerate(doc["rows"]):
        rate = r.get("rate_best", r.get("steady_rate"))
        figs.append(Figure(PART, "hrir bake across devices and processes (seconds per sector; the same bytes)",
                           f"{r['config']} ({r['merge']})", 1.0 / rate, None, "-",
                           {"devices": r["devices"], "processes": r["processes"], "cores": r.get("cores")}, baseline=i == 0,
                           extra={k: r.get(k) for k in ("bake_s", "wall_s", "assemble_s", "peak_rss_mib", "x_base",
                                                        "x_base_range", "cores_got", "x_base_full_cores")}))
    ctx.note(PART, f"benchmarks/scaling.py {' '.join(args)}: steady seconds per sector (the inverse of the best steady "
                   "throughput); a bake does not depend on the device count, so there is no error column; load average "
                   f"before {doc.get('load_before', doc.get('load'))} (a shared machine: cores_got in results.json says "
                   "how much of each pinned core a run got)")
    return figs
