"""Part ``scale``: a bake over 1 and 2 local devices and 1 and 2 jax.distributed processes (loopback), each
process pinned to its cores (:func:`scaling_study`; needs two cores).

Each configuration runs ``hairlut bake hrir`` in fresh processes, each pinned to its cores with ``taskset -c``
(``os.sched_setaffinity`` where taskset is missing), ``JAX_NUM_CPU_DEVICES`` set:

* ``plain 1 dev``        one process, one device, core 0: the baseline;
* ``dist 1 x 1``         the same bake through ``--distributed`` (one process, ``--merge virtual``), core 0:
                         what the distributed path costs on the same core;
* ``plain 2 dev``        one process, two devices, cores 0 and 1;
* ``2 x plain (pair)``   two independent plain bakes of the whole recipe at once, ``taskset -c 0`` and ``-c 1``:
                         what two processes reach on this machine with no distributed runtime at all;
* ``dist 2 x 1 virtual`` two jax.distributed processes on loopback, one device each, ``taskset -c 0`` and
                         ``-c 1``; ``dist 2 x 1 copy`` the same with ``--merge copy``.

The configurations run interleaved, ``repeat`` rounds (the machine is shared: a round sees one load for all of
them).  Per configuration: the steady throughput (sectors per second, summed over processes) as best of the rounds
and median, taken at each process's median block (a block that meets a new array shape compiles, and every process
compiles for itself: ``compile_cpu_s``); the bake's own seconds (the slowest process's report); the leader's time
to write the final asset; bytes per sector; each process's peak memory (``os.wait4``).  Ratios are of the best
rates; ``x_base_range`` is the spread of the same ratio taken round by round.  Because other work may hold the
pinned cores, each block's CPU time is recorded too: ``cores_got`` (CPU seconds per wall second of a median block,
summed over processes), ``cpu_rate`` (sectors per CPU-second) and ``x_base_full_cores`` (sectors per CPU-second
times the configuration's cores against the same for one core: the speed-up if every pinned core were given in
full; derived, not a wall-clock figure).
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .. import errors
from ._figure import Figure
from ._parts import Context

PART = "scale"
#: The bake each child process runs: the installed CLI, as a user runs ``hairlut bake hrir``.
CODE = "import sys; from hairlut_cli.main import cli; cli(sys.argv[1:])"
#: name, devices per process, the cores of each process, how (plain: one bake; dist: --distributed; pair: independent
#: plain bakes of the whole recipe, one per core, at once: what two processes can reach on this machine), merge
CONFIGS = [
    ("plain 1 dev", 1, [{0}], "plain", None),
    ("dist 1 x 1", 1, [{0}], "dist", "virtual"),
    ("plain 2 dev", 2, [{0, 1}], "plain", None),
    ("2 x plain (pair)", 1, [{0}, {1}], "pair", None),
    ("dist 2 x 1 virtual", 1, [{0}, {1}], "dist", "virtual"),
    ("dist 2 x 1 copy", 1, [{0}, {1}], "dist", "copy"),
]
#: (config, baseline): the distributed path against plain bakes on the same cores
SAME_CORES = [
    ("dist 1 x 1", "plain 1 dev"),
    ("dist 2 x 1 virtual", "plain 2 dev"),
    ("dist 2 x 1 copy", "plain 2 dev"),
    ("dist 2 x 1 virtual", "2 x plain (pair)"),
    ("dist 2 x 1 copy", "2 x plain (pair)"),
]
BLOCK = 4
TRACE = {"angles": {"views": 16, "lights": 16}, "trace": {"pixels": 32, "steps": 32}, "sectors": {"grid": [16, 16]}}


def scale_unavailable() -> str | None:
    """The scale part pins one process (or device) per core: it needs two cores."""
    cores = len(os.sched_getaffinity(0))
    return None if cores >= 2 else f"one core here ({cores}): nothing to scale over"


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _pinned(cmd: list[str], cores: set[int]):
    """(command, preexec): ``taskset -c CORES cmd``, or sched_setaffinity in the child where taskset is missing."""
    if shutil.which("taskset"):
        return ["taskset", "-c", ",".join(map(str, sorted(cores))), *cmd], None
    return cmd, lambda: os.sched_setaffinity(0, cores)


def _toml(recipe: dict) -> str:
    lines = []
    for section, body in recipe.items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in body.items()]
    return "\n".join(lines) + "\n"


def _bake(recipe: Path, out: Path, devices: int, cores: list[set[int]], how: str, merge: str | None) -> dict:
    """One configuration's bake: its processes started at once, each pinned; their reports summed."""
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_NUM_CPU_DEVICES": str(devices)}
    port, n = _port(), len(cores)

    def cmd(k):
        dest = out.with_name(f"{out.stem}-{k}{out.suffix}") if how == "pair" else out
        base = [
            sys.executable,
            "-c",
            CODE,
            "bake",
            "hrir",
            "--recipe",
            str(recipe),
            "--out",
            str(dest),
            "--no-progress",
            "--json",
            "--block",
            str(BLOCK),
        ]
        return base + (
            [
                "--distributed",
                "--coordinator",
                f"127.0.0.1:{port}",
                "--num-processes",
                str(n),
                "--process-id",
                str(k),
                "--merge",
                merge,
            ]
            if how == "dist"
            else []
        )

    t0 = time.perf_counter()
    procs = []
    for k, cs in enumerate(cores):
        c, pre = _pinned(cmd(k), cs)
        procs.append(subprocess.Popen(c, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, preexec_fn=pre))
    outs, peaks = [], []
    for p in procs:
        outs.append(p.stdout.read())
        _, status, usage = os.wait4(p.pid, 0)  # this child's own peak memory
        p.returncode = os.waitstatus_to_exitcode(status)
        peaks.append(usage.ru_maxrss / 1024)
    wall = time.perf_counter() - t0
    if any(p.returncode for p in procs):
        raise errors.HairlutError(
            f"scaling bake failed: devices={devices} cores={cores} merge={merge} (exit {[p.returncode for p in procs]})"
        )
    reports = [json.loads(o[o.index("\n{") + 1 if not o.startswith("{") else 0 :]) for o in outs]
    lead = reports[0]
    med_cpu = [statistics.median(r["block_cpu_seconds"]) for r in reports]
    return {
        "bake_s": max(r["seconds"] for r in reports),
        "wall_s": wall,
        "assemble_s": lead.get("assemble_s"),
        "blocks_s": [r["blocks_s"] for r in reports],
        # steady: each process's median block (blocks that meet a new shape compile, the first above all)
        "steady_rate": sum(BLOCK / statistics.median(r["block_seconds"]) for r in reports),
        # CPU-time normalised: sectors per CPU-second of a median block, and the cores it received
        "cpu_rate": sum(r["computed"] for r in reports) / sum(len(r["block_cpu_seconds"]) * m for r, m in zip(reports, med_cpu)),
        "cores_got": sum(m / statistics.median(r["block_seconds"]) for r, m in zip(reports, med_cpu)),
        # the CPU seconds of blocks beyond a median block's: compilation, which every process does for itself
        "compile_cpu_s": sum(sum(r["block_cpu_seconds"]) - len(r["block_cpu_seconds"]) * m for r, m in zip(reports, med_cpu)),
        "peak_rss_mib": max(peaks),
        "bytes": lead["bytes"],
        "sectors": sum(r["units"] for r in reports),
    }


def _spread(rounds: list[dict], name: str, base: str) -> list[float]:
    """The ratio name/base of the steady rates taken round by round: (min, median, max)."""
    ratios = [r[name]["steady_rate"] / r[base]["steady_rate"] for r in rounds]
    return [min(ratios), statistics.median(ratios), max(ratios)]


def scaling_study(sectors: int = 256, repeat: int = 3, progress=None) -> dict:
    """:data:`CONFIGS` over ``repeat`` interleaved rounds of a ``sectors``-sector bake of :data:`TRACE` (module
    docstring).  Returns ``{"sectors", "recipe", "block", "rounds", "load_before", "load_after", "rows",
    "same_cores"}``: a row per configuration (``config``, ``devices``, ``processes``, ``cores``, ``merge``,
    ``rate_best``, ``rate_median``, ``x_base``, ``x_base_range``, ``bake_s``, ``wall_s``, ``assemble_s``,
    ``cpu_rate``, ``cores_got``, ``compile_cpu_s``, ``bytes_per_sector``, ``peak_rss_mib``, ``rates``,
    ``full_cores_rate``, ``x_base_full_cores``) and the distributed path's cost against plain bakes on the same
    cores.  Refused (:class:`hairlut.errors.ResourceError`) on fewer than two cores."""
    reason = scale_unavailable()
    if reason:
        raise errors.ResourceError(f"scaling: {reason}")
    say = progress or (lambda message: None)
    load_before = os.getloadavg()
    recipe_doc = {**TRACE, "sectors": {**TRACE["sectors"], "count": sectors}}
    rounds = []
    with tempfile.TemporaryDirectory(prefix="hairlut-scale-") as tmp:
        recipe = Path(tmp) / "r.toml"
        recipe.write_text(_toml(recipe_doc))
        for i in range(repeat):
            got = {}
            for name, devices, cores, how, merge in CONFIGS:
                got[name] = _bake(recipe, Path(tmp) / f"{name.replace(' ', '_')}-{i}.h5", devices, cores, how, merge)
                say(f"scale: round {i + 1}/{repeat} {name}: {got[name]['steady_rate']:.2f} sectors/s")
            rounds.append(got)
    base = "plain 1 dev"
    rows = []
    for name, devices, cores, how, merge in CONFIGS:
        runs = [r[name] for r in rounds]
        best = max(runs, key=lambda r: r["steady_rate"])
        rows.append(
            {
                "config": name,
                "devices": devices,
                "processes": len(cores),
                "cores": "+".join(",".join(map(str, sorted(c))) for c in cores),
                "merge": merge or "copy",
                "rate_best": best["steady_rate"],
                "rate_median": statistics.median(r["steady_rate"] for r in runs),
                "x_base": best["steady_rate"] / max(r[base]["steady_rate"] for r in rounds),
                "x_base_range": _spread(rounds, name, base),
                "bake_s": min(r["bake_s"] for r in runs),
                "wall_s": min(r["wall_s"] for r in runs),
                "assemble_s": min((r["assemble_s"] for r in runs if r["assemble_s"] is not None), default=None),
                "cpu_rate": max(r["cpu_rate"] for r in runs),
                "cores_got": statistics.median(r["cores_got"] for r in runs),
                "compile_cpu_s": min(r["compile_cpu_s"] for r in runs),
                "bytes_per_sector": best["bytes"] / best["sectors"] if how != "pair" else None,  # a pair bakes it twice
                "peak_rss_mib": max(r["peak_rss_mib"] for r in runs),
                "rates": [r["steady_rate"] for r in runs],
            }
        )
    for r in rows:  # if every pinned core were given in full: sectors per CPU-second times the cores
        r["full_cores_rate"] = r["cpu_rate"] * len(r["cores"].replace("+", ",").split(","))
        r["x_base_full_cores"] = r["full_cores_rate"] / rows[0]["full_cores_rate"]
    by = {r["config"]: r for r in rows}
    costs = []
    for name, ref in SAME_CORES:
        lo, mid, hi = _spread(rounds, ref, name)
        costs.append(
            {
                "config": name,
                "against": ref,
                "rate_cost": by[ref]["rate_best"] / by[name]["rate_best"] - 1,
                "rate_cost_median": mid - 1,
                "rate_cost_range": [lo - 1, hi - 1],
                "bake_s_cost": by[name]["bake_s"] / by[ref]["bake_s"] - 1,
            }
        )
    return {
        "sectors": sectors,
        "recipe": recipe_doc,
        "block": BLOCK,
        "rounds": repeat,
        "load_before": load_before,
        "load_after": os.getloadavg(),
        "rows": rows,
        "same_cores": costs,
    }


def run(ctx: Context) -> list[Figure]:
    sectors, repeat = (16, 1) if ctx.quick else (64, 2)
    doc = scaling_study(sectors, repeat, ctx.progress)
    figs = []
    for i, r in enumerate(doc["rows"]):
        figs.append(
            Figure(
                PART,
                "hrir bake across devices and processes (seconds per sector; the same bytes)",
                f"{r['config']} ({r['merge']})",
                1.0 / r["rate_best"],
                None,
                "-",
                {"devices": r["devices"], "processes": r["processes"], "cores": r.get("cores")},
                baseline=i == 0,
                extra={
                    k: r.get(k)
                    for k in (
                        "bake_s",
                        "wall_s",
                        "assemble_s",
                        "peak_rss_mib",
                        "x_base",
                        "x_base_range",
                        "cores_got",
                        "x_base_full_cores",
                    )
                },
            )
        )
    ctx.note(
        PART,
        f"{sectors} sectors, {repeat} round{'s' if repeat > 1 else ''} of every configuration: steady seconds "
        "per sector (the inverse of the best steady throughput); a bake does not depend on the device count, "
        f"so there is no error column; load average before {doc['load_before']} (a shared machine: cores_got "
        "in results.json says how much of each pinned core a run got)",
    )
    return figs
