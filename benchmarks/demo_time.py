"""``hairlut demo`` cold and warm: its wall time with an empty table cache and compilation cache, then again.

    python -m benchmarks.demo_time [--runs cold warm]

Runs the installed ``hairlut`` console script (beside this interpreter) from the repository's root, into a
temporary output folder, table cache and XDG cache (so that JAX's persistent compilation cache starts empty: cold
means cold).  The planner's needed-only bake against a full bake is the plan part of ``hairlut bench``
(``hairlut.bench.needed_only_bake``, ``full_bake``, ``database_coverage``).  Writes results/demo_time.json.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ._common import ROOT, save


def demo_runs(folder: Path, runs=("cold", "warm")) -> dict:
    """Wall seconds of each of ``runs`` of ``hairlut demo`` in a row, sharing ``folder``'s caches."""
    exe = Path(sys.executable).with_name("hairlut")
    cmd = [str(exe), "demo", "--out", str(folder / "out"), "--cache", str(folder / "cache"), "--no-progress"]
    env = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = str(folder / "xdg")  # a fresh compilation cache: cold means cold
    out = {}
    for run in runs:
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True, cwd=ROOT, env=env)
        out[run] = time.perf_counter() - t0
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", nargs="+", default=["cold", "warm"], help="labels of the runs, in order")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        got = demo_runs(Path(tmp), args.runs)
    print("hairlut demo: " + ", ".join(f"{k} {v:.1f} s" for k, v in got.items()))
    save("demo_time", {"runs": got})
    return got


if __name__ == "__main__":
    main()
