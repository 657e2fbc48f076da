"""Scaling of a bake: 1 and 2 local devices, 1 and 2 jax.distributed processes (loopback), cores pinned.

Each configuration runs `hairlut bake hrir` in fresh processes, each pinned to its cores with
``taskset -c`` (``os.sched_setaffinity`` where taskset is missing), JAX_NUM_CPU_DEVICES set:

* ``plain 1 dev``        one process, one device, core 0: the baseline;
* ``dist 1 x 1``         the same bake through ``--distributed`` (one process, ``--merge virtual``), core 0:
                         what the distributed path costs on the same core;
* ``plain 2 dev``        one process, two devices, cores 0 and 1;
* ``2 x plain (pair)``   two independent plain bakes of the whole recipe at once, ``taskset -c 0`` and ``-c 1``:
                         what two processes reach on this machine with no distributed runtime at all;
* ``dist 2 x 1 virtual`` two jax.distributed processes on loopback, one device each, ``taskset -c 0`` and
                         ``-c 1``; ``dist 2 x 1 copy`` the same with ``--merge copy``.

The configurations run interleaved, ``--repeat`` rounds (the machine is shared: a round sees one
load for all of them).  Per configuration: the steady throughput (sectors per second, summed over
processes) as best of the rounds and median, taken at each process's median block: a block that
meets a new array shape compiles (the first, and a few more as sector sizes vary), and every
process compiles for itself, which ``compile CPU-s`` (the CPU seconds beyond median blocks)
shows; the bake's own seconds (the slowest process's report: imports excluded); the leader's time
to write the final asset; bytes per sector; each process's peak memory (``os.wait4``).  Ratios are
of the best rates; ``range`` is the spread of the same ratio taken round by round.  Because other
work may hold the pinned cores, each block's CPU time is recorded too: ``cores got`` (CPU seconds
per wall second of a median block, summed over processes), ``sectors/CPU-s``, and ``x 1 core,
full cores``: sectors per CPU-second times the configuration's cores against the same for one
core, the speed-up if every pinned core were given in full (derived, not a wall-clock figure).

Then the time to assemble the final asset, virtual datasets against a copy, from the same parts, at
a few part counts (``--sizes`` sectors in blocks of each of ``--blocks``), as the leader of a 2-process
bake takes it (``hairlut.bake.sharding.finish``: its own parts' indexes in memory, the other process's share
file), wall and CPU seconds (the machine is shared: CPU seconds are the work), per part and per sector,
and what indexing a part costs each process while it bakes.  The parts are baked with the ASSEMBLY
recipe: the production's density grid (32 × 32, which the feature index reads) and float16, with one
view, one light, 2 px and 2 steps, so that 65,536 sectors bake in minutes (``--keep DIR`` keeps them for
a rerun); the copy is timed up to ``--copy-max`` sectors.  ``--repeat 0`` runs the assembly and the
projection alone.

Then the projected time of the production database (65,536 sectors, 64 × 64 angles, 64 px, float16:
34.9 GB) on 8 H200s, term by term and labelled "projected, not measured on a GPU": the device time from
the last H200 rate (issue 15, commit 937d29b: 94 default sectors/s, host-bound then), scaled by a
production sector's tracing work; the host's work per sector measured now on this CPU with the
production's shapes (``host_terms``: serial inputs and HDF5/checks/index, and the chunk filters, which
the chunk writer runs on every core, divided over the GPU machine's 16 cores); the disk (this machine's
write bandwidth); and the virtual assembly measured at 65,536 sectors.  A bake overlaps device, host and
disk, so projected = max(device, host, write) + assembly.

    .venv/bin/python benchmarks/scaling.py [--sectors 256] [--repeat 3] [--sizes 1024] [--blocks 1,4,64]
"""

from __future__ import annotations

import argparse
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

from _assembly import assembly, print_assembly
from _common import save, table
from _projection import GPUS, PRODUCTION, host_terms, work, write_bandwidth, projection as production_projection

CODE = "import sys; from hairlut_cli.main import cli; cli(sys.argv[1:])"
#: name, devices per process, the cores of each process, how (plain: one bake; dist: --distributed; pair: independent
#: plain bakes of the whole recipe, one per core, at once: what two processes can reach on this machine), merge
CONFIGS = [("plain 1 dev", 1, [{0}], "plain", None), ("dist 1 x 1", 1, [{0}], "dist", "virtual"),
           ("plain 2 dev", 2, [{0, 1}], "plain", None), ("2 x plain (pair)", 1, [{0}, {1}], "pair", None),
           ("dist 2 x 1 virtual", 1, [{0}, {1}], "dist", "virtual"), ("dist 2 x 1 copy", 1, [{0}, {1}], "dist", "copy")]
#: (config, baseline): the distributed path against plain bakes on the same cores
SAME_CORES = [("dist 1 x 1", "plain 1 dev"), ("dist 2 x 1 virtual", "plain 2 dev"), ("dist 2 x 1 copy", "plain 2 dev"),
              ("dist 2 x 1 virtual", "2 x plain (pair)"), ("dist 2 x 1 copy", "2 x plain (pair)")]
BLOCK = 4
TRACE = {"angles": {"views": 16, "lights": 16}, "trace": {"pixels": 32, "steps": 32}, "sectors": {"grid": [16, 16]}}


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


def _run(recipe: Path, out: Path, devices: int, cores: list[set[int]], how: str, merge: str | None) -> dict:
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_NUM_CPU_DEVICES": str(devices)}
    port, n = _port(), len(cores)

    def cmd(k):
        dest = out.with_name(f"{out.stem}-{k}{out.suffix}") if how == "pair" else out
        base = [sys.executable, "-c", CODE, "bake", "hrir", "--recipe", str(recipe), "--out", str(dest), "--no-progress",
                "--json", "--block", str(BLOCK)]
        return base + (["--distributed", "--coordinator", f"127.0.0.1:{port}", "--num-processes", str(n), "--process-id",
                        str(k), "--merge", merge] if how == "dist" else [])

    cmds = [cmd(k) for k in range(n)]
    t0 = time.perf_counter()
    procs = []
    for c, cs in zip(cmds, cores):
        cmd, pre = _pinned(c, cs)
        procs.append(subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                                      preexec_fn=pre))
    outs, peaks = [], []
    for p in procs:
        outs.append(p.stdout.read())
        _, status, usage = os.wait4(p.pid, 0)  # this child's own peak memory
        p.returncode = os.waitstatus_to_exitcode(status)
        peaks.append(usage.ru_maxrss / 1024)
    wall = time.perf_counter() - t0
    if any(p.returncode for p in procs):
        raise SystemExit(f"bake failed: devices={devices} cores={cores} merge={merge}")
    reports = [json.loads(o[o.index("\n{") + 1 if not o.startswith("{") else 0:]) for o in outs]
    lead = reports[0]
    return {"bake_s": max(r["seconds"] for r in reports), "wall_s": wall, "assemble_s": lead.get("assemble_s"),
            "blocks_s": [r["blocks_s"] for r in reports],
            # steady: each process's median block (blocks that meet a new shape compile, the first above all)
            "steady_rate": sum(BLOCK / statistics.median(r["block_seconds"]) for r in reports),
            # CPU-time normalised: sectors per CPU-second of a median block, and the cores it received
            "cpu_rate": sum(r["computed"] for r in reports) / sum(len(r["block_cpu_seconds"]) * statistics.median(
                r["block_cpu_seconds"]) for r in reports),
            "cores_got": sum(statistics.median(r["block_cpu_seconds"]) / statistics.median(r["block_seconds"]) for r in reports),
            # the CPU seconds of blocks beyond a median block's: compilation, which every process does for itself
            "compile_cpu_s": sum(sum(r["block_cpu_seconds"]) - len(r["block_cpu_seconds"]) * statistics.median(
                r["block_cpu_seconds"]) for r in reports),
            "peak_rss_mib": max(peaks), "bytes": lead["bytes"], "sectors": sum(r["sectors"] for r in reports)}


def _spread(rounds: list[dict], name: str, base: str, key=lambda r: r["steady_rate"]) -> list[float]:
    """The ratio name/base taken round by round: (min, median, max)."""
    ratios = [key(r[name]) / key(r[base]) for r in rounds]
    return [min(ratios), statistics.median(ratios), max(ratios)]


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sectors", type=int, default=256, help="sectors of the scaling rounds (256: compilation amortised)")
    ap.add_argument("--repeat", type=int, default=3, help="interleaved rounds of every configuration")
    ap.add_argument("--sizes", default="1024", help="database sizes (sectors) of the assembly timing")
    ap.add_argument("--blocks", default="1,4,64", help="sectors per part of the assembly timing")
    ap.add_argument("--copy-max", type=int, default=4096, help="time the copy only up to this many sectors")
    ap.add_argument("--keep", type=Path, help="bake the assembly's parts here and keep them (a rerun resumes them)")
    ap.add_argument("--no-projection", action="store_true", help="skip the host measurement and the projection")
    ap.add_argument("--name", default="scaling", help="results/<name>.json")
    a = ap.parse_args(argv)
    if len(os.sched_getaffinity(0)) < 2:
        raise SystemExit("needs two cores")
    load_before = os.getloadavg()
    rounds = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        recipe = tmp / "r.toml"
        recipe.write_text(_toml({**TRACE, "sectors": {**TRACE["sectors"], "count": a.sectors}}))
        for i in range(a.repeat):
            got = {}
            for name, devices, cores, how, merge in CONFIGS:
                got[name] = _run(recipe, tmp / f"{name.replace(' ', '_')}-{i}.h5", devices, cores, how, merge)
                print(f"round {i + 1}/{a.repeat} {name}: {got[name]['steady_rate']:.2f} sectors/s, "
                      f"bake {got[name]['bake_s']:.1f} s", file=sys.stderr)
            rounds.append(got)
        sizes = [int(s) for s in a.sizes.split(",") if s]
        blocks = [int(g) for g in a.blocks.split(",") if g]
        asm = assembly(sizes, blocks, tmp, repeat=2, copy_max=a.copy_max, keep=a.keep)
        hosts = None if a.no_projection else {**host_terms(tmp), "write_bytes_per_s": write_bandwidth(tmp)}
    print_assembly(asm)
    if not rounds:  # --repeat 0: the assembly and the projection only
        doc = {"assembly": asm, "load_before": load_before, "load_after": os.getloadavg(),
               "projection": production_projection(asm, hosts) if hosts else None}
        save(a.name, doc)
        return doc
    base = "plain 1 dev"
    rows = []
    for name, devices, cores, how, merge in CONFIGS:
        runs = [r[name] for r in rounds]
        best = max(runs, key=lambda r: r["steady_rate"])
        rows.append({"config": name, "devices": devices, "processes": len(cores), "cores": "+".join(
            ",".join(map(str, sorted(c))) for c in cores), "merge": merge or "copy",
            "rate_best": best["steady_rate"], "rate_median": statistics.median(r["steady_rate"] for r in runs),
            "x_base": best["steady_rate"] / max(r[base]["steady_rate"] for r in rounds),
            "x_base_range": _spread(rounds, name, base), "bake_s": min(r["bake_s"] for r in runs),
            "wall_s": min(r["wall_s"] for r in runs), "assemble_s": min((r["assemble_s"] for r in runs if r["assemble_s"]
                                                                        is not None), default=None),
            "cpu_rate": max(r["cpu_rate"] for r in runs), "cores_got": statistics.median(r["cores_got"] for r in runs),
            "compile_cpu_s": min(r["compile_cpu_s"] for r in runs),
            "bytes_per_sector": best["bytes"] / best["sectors"] if how != "pair" else None,  # a pair bakes it twice
            "peak_rss_mib": max(r["peak_rss_mib"] for r in runs),
            "rates": [r["steady_rate"] for r in runs]})
    for r in rows:  # if every pinned core were given in full: sectors per CPU-second times the cores
        r["full_cores_rate"] = r["cpu_rate"] * len(r["cores"].replace("+", ",").split(","))
        r["x_base_full_cores"] = r["full_cores_rate"] / rows[0]["full_cores_rate"]
    by = {r["config"]: r for r in rows}
    costs = []
    for name, ref in SAME_CORES:
        rate = by[ref]["rate_best"] / by[name]["rate_best"] - 1
        lo, mid, hi = _spread(rounds, ref, name)
        bake = by[name]["bake_s"] / by[ref]["bake_s"] - 1
        costs.append({"config": name, "against": ref, "rate_cost": rate, "rate_cost_median": mid - 1,
                      "rate_cost_range": [lo - 1, hi - 1], "bake_s_cost": bake})
    print(f"{a.sectors} sectors, {TRACE['angles']['views']}x{TRACE['angles']['lights']} angles, {TRACE['trace']['pixels']} px, "
          f"{TRACE['trace']['steps']} steps, blocks of {BLOCK}; {a.repeat} interleaved rounds; load average before "
          f"{load_before[0]:.1f} on {os.cpu_count()} cores (a shared machine)\n")
    print(table(rows, [("config", "config", ""), ("cores", "cores", ""), ("rate_best", "sectors/s best", ".2f"),
                       ("rate_median", "median", ".2f"), ("x_base", "x 1 core", ".2f"), ("cores_got", "cores got", ".2f"),
                       ("cpu_rate", "sectors/CPU-s", ".2f"), ("x_base_full_cores", "x 1 core, full cores", ".2f"),
                       ("compile_cpu_s", "compile CPU-s", ".1f"),
                       ("bake_s", "bake s", ".1f"),
                       ("assemble_s", "assemble s", ".3f"), ("bytes_per_sector", "B/sector", ".0f"),
                       ("peak_rss_mib", "peak MiB", ".0f")]))
    print()
    for r in rows[1:]:
        lo, mid, hi = r["x_base_range"]
        print(f"  {r['config']:<19} x 1 core: best rates {r['x_base']:.2f}; round by round median {mid:.2f} "
              f"(range {lo:.2f}..{hi:.2f})")
    for c in costs:
        lo, hi = c["rate_cost_range"]
        print(f"  {c['config']:<19} against {c['against']} on the same cores: throughput cost, best rates "
              f"{100 * c['rate_cost']:+.0f}%, round by round median {100 * c['rate_cost_median']:+.0f}% (range "
              f"{100 * lo:+.0f}..{100 * hi:+.0f}%); whole-bake seconds {100 * c['bake_s_cost']:+.0f}%")
    bench = {**TRACE, "sectors": {**TRACE["sectors"], "count": a.sectors}}
    per_sector = work(bench) / a.sectors
    core_rate = by[base]["rate_best"] * per_sector  # work per second, one core
    prod_work = work(PRODUCTION)
    print(f"\nproduction database from this run's one-core CPU rate: {prod_work / core_rate / 3600:.0f} core-hours; 8 such "
          f"devices {prod_work / core_rate / GPUS / 3600:.1f} h (linear scaling assumed)")
    projection = {**(production_projection(asm, hosts) if hosts else {}), "one_core_s": prod_work / core_rate,
                  "cpu_cores_8_s": prod_work / core_rate / GPUS}
    doc = {"sectors": a.sectors, "recipe": bench, "block": BLOCK, "rounds": a.repeat, "load_before": load_before,
           "load_after": os.getloadavg(), "rows": rows, "same_cores": costs, "assembly": asm, "projection": projection}
    save(a.name, doc)
    return doc


if __name__ == "__main__":
    main()
