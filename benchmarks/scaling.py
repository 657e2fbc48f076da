"""Scaling of a bake: 1 and 2 local devices, 1 and 2 jax.distributed processes (loopback), cores pinned.

Each configuration runs `hairlut bake hrir` in fresh processes, each pinned to its own cores with
``os.sched_setaffinity`` (set in the child before JAX starts, with JAX_NUM_CPU_DEVICES):

* ``plain 1 dev``      one process, one device, core {0}: the baseline;
* ``plain 2 dev``      one process, two devices, cores {0, 1};
* ``dist 2 × 1``       two jax.distributed processes on loopback, one device each, cores {0} and {1}
                       (``--merge virtual``, then ``--merge copy``).

Reported per configuration (best of ``--repeat`` runs, the machine being shared): the bake's
own seconds (the slowest process's report: Python imports excluded; compilation, tracing, the
barriers and writing included), the steady throughput (sectors per second of every process's
blocks after its first, which compiles the kernels, summed over processes; ``x base`` is its
ratio to the baseline's), the wall time of the whole command, throughput against the same-run baseline
(``x base``), the distributed path's cost in steady throughput against a plain two-device bake on the same
two cores (``vs plain``),
the time the leader took to write the final asset (``assemble``: virtual datasets over the
parts, or a copy), bytes per sector, each process's own peak resident memory (``os.wait4``) and
block-loop seconds; then virtual against copy assembly timed in-process on the same parts.
Then the projected time of the production database (65,536 sectors, 64 × 64 angles, 64 px)
from the measured one-core throughput.

    .venv/bin/python benchmarks/scaling.py [--sectors 64] [--repeat 1] [--json benchmarks/results/scaling.json]
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CODE = "import sys; from hairlut_cli.main import cli; cli(sys.argv[1:])"
#: name, devices per process, the cores of each process, merge
CONFIGS = [("plain 1 dev", 1, [{0}], None), ("plain 2 dev", 2, [{0, 1}], None),
           ("dist 2 x 1 virtual", 1, [{0}, {1}], "virtual"), ("dist 2 x 1 copy", 1, [{0}, {1}], "copy")]
BLOCK = 4
PRODUCTION = {"sectors": 65_536, "views": 64, "lights": 64, "pixels": 64}


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _pinned(cores: set[int]):
    def pin():
        os.sched_setaffinity(0, cores)
    return pin


def _run(recipe: Path, out: Path, devices: int, cores: list[set[int]], merge: str | None) -> dict:
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_NUM_CPU_DEVICES": str(devices)}
    base = [sys.executable, "-c", CODE, "bake", "hrir", "--recipe", str(recipe), "--out", str(out), "--no-progress", "--json",
            "--block", str(BLOCK)]
    port = _port()
    n = len(cores)
    cmds = [base] if n == 1 else [base + ["--distributed", "--coordinator", f"127.0.0.1:{port}", "--num-processes", str(n),
                                          "--process-id", str(k), "--merge", merge] for k in range(n)]
    t0 = time.perf_counter()
    procs = [subprocess.Popen(c, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                              preexec_fn=_pinned(cs)) for c, cs in zip(cmds, cores)]
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
            # steady throughput: every process's blocks after its first (which compiles the kernels)
            "steady_rate": sum((r["computed"] - BLOCK) / sum(r["block_seconds"][1:]) for r in reports),
            "peak_rss_mib": max(peaks), "bytes": lead["bytes"], "sectors": sum(r["sectors"] for r in reports)}


def _assembly(out: Path, repeat: int = 3) -> dict:
    """Seconds to write the final asset from the parts of the virtual bake ``out``: virtual datasets, or a copy."""
    from hairlut import registry
    from hairlut.parts import parts_dir, write_virtual
    from hairlut.sharding import header

    baker = registry.get("hrir_db")
    items = sorted((header(p, baker), p) for p in parts_dir(out).glob("part-*.h5"))
    recipe, spans = items[0][0][4], [(p, h[0], h[1]) for h, p in items]
    paths = [p for p, _, _ in spans]
    times = {"virtual": [], "copy": []}
    for i in range(repeat):
        t0 = time.perf_counter()
        axes, variables, attrs = baker.units.whole(recipe, paths)
        write_virtual(out.with_name(f"asm-v{i}.h5"), baker.kind, recipe, baker.units.axis, spans, axes, variables, attrs)
        times["virtual"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        baker.units.assemble(recipe, paths, out.with_name(f"asm-c{i}.h5"))
        times["copy"].append(time.perf_counter() - t0)
    return {"parts": len(paths), "part_bytes": sum(p.stat().st_size for p in paths),
            "virtual_s": min(times["virtual"]), "copy_s": min(times["copy"]),
            "virtual_bytes": out.with_name("asm-v0.h5").stat().st_size, "copy_bytes": out.with_name("asm-c0.h5").stat().st_size}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sectors", type=int, default=64)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--json", default="benchmarks/results/scaling.json")
    a = ap.parse_args(argv)
    if len(os.sched_getaffinity(0)) < 2:
        raise SystemExit("needs two cores")
    trace = {"views": 16, "lights": 16, "pixels": 32, "steps": 32}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        recipe = tmp / "r.toml"
        recipe.write_text(f"[sectors]\ncount = {a.sectors}\ngrid = [16, 16]\n[angles]\nviews = {trace['views']}\n"
                          f"lights = {trace['lights']}\n[trace]\npixels = {trace['pixels']}\nsteps = {trace['steps']}\n")
        parts_of = None
        for name, devices, cores, merge in CONFIGS:
            runs = [_run(recipe, tmp / f"{name.replace(' ', '_')}-{i}.h5", devices, cores, merge)
                    for i in range(a.repeat)]
            best = min(runs, key=lambda r: r["bake_s"])
            rows.append({"config": name, "devices": devices, "processes": len(cores),
                         "cores": [sorted(c) for c in cores], "merge": merge or "copy", **best,
                         "bake_s_all": [r["bake_s"] for r in runs]})
            if merge == "virtual":
                parts_of = tmp / f"{name.replace(' ', '_')}-{a.repeat - 1}.h5"  # its parts stay beside it
        asm_doc = _assembly(parts_of)
    for r in rows:
        r["x_base"] = r["steady_rate"] / rows[0]["steady_rate"]
        r["vs_plain_same_cores"] = rows[1]["steady_rate"] / r["steady_rate"] - 1 if r["processes"] > 1 else None
        r["bytes_per_sector"] = r["bytes"] / r["sectors"] if r["merge"] == "copy" else None
    print(f"{a.sectors} sectors, {trace['views']}x{trace['lights']} angles, {trace['pixels']} px, {trace['steps']} steps; "
          f"best of {a.repeat}")
    print(f"{'config':<19} {'cores':>9} {'bake s':>7} {'wall s':>7} {'sect/s':>6} {'x base':>6} {'vs plain':>8} {'assemble s':>10} "
          f"{'B/sector':>8} {'peak MiB':>8}")
    for r in rows:
        vs = f"{100 * r['vs_plain_same_cores']:+.0f}%" if r["vs_plain_same_cores"] is not None else "-"
        asm = f"{r['assemble_s']:.3f}" if r["assemble_s"] is not None else "-"
        bps = f"{r['bytes_per_sector']:.0f}" if r["bytes_per_sector"] else "-"
        print(f"{r['config']:<19} {'+'.join(''.join(map(str, c)) for c in r['cores']):>9} {r['bake_s']:>7.2f} "
              f"{r['wall_s']:>7.2f} {r['steady_rate']:>6.2f} {r['x_base']:>6.2f} {vs:>8} {asm:>10} {bps:>8} {r['peak_rss_mib']:>8.0f}")
    for r in rows:
        print(f"  {r['config']:<19} block loop of each process {', '.join(f'{b:.2f}' for b in r['blocks_s'])} s")
    asm = asm_doc
    print(f"assembly from the same {asm['parts']} parts ({asm['part_bytes'] / 2**20:.2f} MiB), best of 3, in-process: "
          f"virtual {asm['virtual_s']:.3f} s ({asm['virtual_bytes'] / 2**10:.0f} KiB written), copy {asm['copy_s']:.3f} s "
          f"({asm['copy_bytes'] / 2**10:.0f} KiB); copy/virtual {asm['copy_s'] / asm['virtual_s']:.1f}")
    # projection: tracing work scales with sectors x views x lights x pixels x steps (same rays, grid)
    work = lambda s, v, l, p, st: s * v * l * p * st  # noqa: E731
    rate = work(rows[0]["steady_rate"], trace["views"], trace["lights"], trace["pixels"], trace["steps"])
    prod = work(PRODUCTION["sectors"], PRODUCTION["views"], PRODUCTION["lights"], PRODUCTION["pixels"], trace["steps"])
    hours = prod / rate / 3600
    print(f"production database ({PRODUCTION['sectors']} sectors, 64x64 angles, 64 px, {trace['steps']} steps) at the "
          f"measured one-core rate: {hours:.0f} core-hours; on 8 such devices {hours / 8:.1f} h (no GPU was measured)")
    doc = {"sectors": a.sectors, "trace": trace, "cores": len(os.sched_getaffinity(0)), "load": os.getloadavg(),
           "rows": rows, "assembly": asm, "one_core_rate": rate, "production_core_hours": hours}
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    Path(a.json).write_text(json.dumps(doc, indent=2))
    return doc


if __name__ == "__main__":
    main()
