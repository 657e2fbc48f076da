"""Scaling of a bake: 1 and 2 local devices, 1 and 2 jax.distributed processes (loopback), on this machine.

Each configuration runs `hairlut bake hrir` in fresh processes (JAX_NUM_CPU_DEVICES set before JAX
starts); reported: wall time, peak resident memory per process (getrusage of the children), ratios
against the same-run one-device baseline, and the time to assemble the final asset (virtual against
copy, from the bake reports).  The machine is shared and noisy: read the ratios, not the seconds.

    .venv/bin/python benchmarks/scaling.py [--sectors 64] [--json benchmarks/results/scaling.json]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CODE = "import sys; from hairlut_cli.main import cli; cli(sys.argv[1:])"


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _run(recipe: Path, out: Path, devices: int, processes: int, merge: str | None) -> dict:
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_NUM_CPU_DEVICES": str(devices)}
    base = [sys.executable, "-c", CODE, "bake", "hrir", "--recipe", str(recipe), "--out", str(out), "--no-progress", "--json",
            "--block", "4"]
    port = _port()
    cmds = [base] if processes == 1 else [
        base + ["--distributed", "--coordinator", f"127.0.0.1:{port}", "--num-processes", str(processes),
                "--process-id", str(k)] for k in range(processes)]
    if merge:
        cmds = [c + ["--merge", merge] for c in cmds]
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    procs = [subprocess.Popen(c, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True) for c in cmds]
    outs = [p.communicate()[0] for p in procs]
    wall = time.perf_counter() - t0
    if any(p.returncode for p in procs):
        raise SystemExit(f"bake failed: devices={devices} processes={processes}")
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss  # KiB, the largest child so far
    reports = [json.loads(o[o.index("{"):]) for o in outs]
    return {"devices": devices, "processes": processes, "merge": merge or ("virtual" if processes > 1 else "copy"),
            "wall_s": wall, "bake_s": max(r["seconds"] for r in reports), "peak_rss_mib": max(peak, before) / 1024,
            "bytes": reports[0]["bytes"], "sectors": sum(r["sectors"] for r in reports)}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sectors", type=int, default=64)
    ap.add_argument("--json", default="benchmarks/results/scaling.json")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        recipe = tmp / "r.toml"
        recipe.write_text(f"[sectors]\ncount = {a.sectors}\ngrid = [16, 16]\n[angles]\nviews = 16\nlights = 16\n"
                          "[trace]\npixels = 32\nsteps = 32\n")
        rows = [_run(recipe, tmp / f"{i}.h5", d, p, m)
                for i, (d, p, m) in enumerate([(1, 1, None), (2, 1, None), (1, 2, "virtual"), (1, 2, "copy")])]
    base = rows[0]["bake_s"]
    for r in rows:
        r["speedup"] = base / r["bake_s"]
        r["bytes_per_sector"] = r["bytes"] / r["sectors"] if r["merge"] == "copy" else None
    print(f"{'devices':>7} {'procs':>5} {'merge':>7} {'bake s':>7} {'wall s':>7} {'speedup':>7} {'peak MiB':>8}")
    for r in rows:
        print(f"{r['devices']:>7} {r['processes']:>5} {r['merge']:>7} {r['bake_s']:>7.2f} {r['wall_s']:>7.2f} "
              f"{r['speedup']:>7.2f} {r['peak_rss_mib']:>8.0f}")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from _common import machine, machine_line

    print(machine_line())
    doc = {"machine": machine(), "sectors": a.sectors, "cores": os.cpu_count(), "rows": rows}
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    Path(a.json).write_text(json.dumps(doc, indent=2))
    return doc


if __name__ == "__main__":
    main()
