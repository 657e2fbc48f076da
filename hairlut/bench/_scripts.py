"""Parts measured by a script of the repository's benchmarks/ folder, run as a subprocess that
writes its records as JSON (for scripts that keep their own logic there)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

from .. import errors

ROOT = Path(__file__).resolve().parents[2]
BENCHMARKS = ROOT / "benchmarks"


def script_missing(name: str) -> str | None:
    """Why ``benchmarks/<name>`` cannot run (an installed hairlut without the repository), or None."""
    return None if (BENCHMARKS / name).is_file() else f"benchmarks/{name} is not here (run from a clone of the repository)"


def run_script(name: str, args: list[str], out: Path, *, timeout: float, env: dict | None = None) -> dict:
    """Run ``benchmarks/<name> ARGS`` and return the JSON it wrote: to ``out`` through ``--json OUT``
    when the script offers it, else its own ``benchmarks/results/<stem>.json`` (checked to be newer
    than the run's start).  A failure raises :class:`hairlut.errors.HairlutError` with the script's
    last line of output."""
    script = BENCHMARKS / name
    own = BENCHMARKS / "results" / f"{script.stem}.json"
    takes_json = re.search(r"add_argument\(\s*[\"']--json[\"']", script.read_text()) is not None
    out.parent.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, str(script), *args, *(["--json", str(out)] if takes_json else [])]
    start = time.time()
    try:
        done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired as exc:
        raise errors.HairlutError(f"benchmarks/{name}: no result within {timeout:.0f} s") from exc
    path = out if takes_json else own
    if done.returncode != 0 or not path.is_file() or path.stat().st_mtime < start:
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["no output"]
        raise errors.HairlutError(f"benchmarks/{name} exited {done.returncode}: {tail[0][:200]}")
    return json.loads(path.read_text())
