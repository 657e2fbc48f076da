#!/usr/bin/env python3
"""Set-up and run, with nothing but python3 on the machine.

    python3 run.py demo [ARGS...]   create .venv, install hairlut, run `hairlut demo ARGS`
    python3 run.py test [ARGS...]   create .venv, install hairlut, check the code with `ruff check` and
                                    `ruff format --check` (the rules: pyproject.toml [tool.ruff]), run the
                                    whole test suite (slow reference checks included) on 2 pytest-xdist workers
                                    (HAIRLUT_TEST_WORKERS=1 runs it in one process; ARGS go to pytest),
                                    then, if it passed, build the documentation site into a temporary
                                    folder with `mkdocs build --strict`: a warning fails the run
    python3 run.py hairlut ARGS...  any hairlut command inside the venv

All three share one venv, with hairlut[test,docs] installed (editable); it is (re)installed only when
pyproject.toml changes.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = Path(os.environ.get("HAIRLUT_VENV", ROOT / ".venv"))
BIN = VENV / ("Scripts" if os.name == "nt" else "bin")


def ensure_venv(extras: str) -> None:
    stamp = VENV / ".hairlut-install"
    want = hashlib.sha256((ROOT / "pyproject.toml").read_bytes() + extras.encode()).hexdigest()
    if stamp.exists() and stamp.read_text() == want:
        return
    if not (BIN / "python").exists():
        print(f"run.py: creating virtual environment {VENV}", file=sys.stderr)
        venv.EnvBuilder(with_pip=True).create(VENV)
    spec = f".[{extras}]" if extras else "."
    print(f"run.py: installing hairlut{('[' + extras + ']') if extras else ''} (editable)", file=sys.stderr)
    subprocess.run(
        [str(BIN / "python"), "-m", "pip", "install", "-q", "--disable-pip-version-check", "-e", spec], cwd=ROOT, check=True
    )
    stamp.write_text(want)


def test_workers() -> list[str]:
    """pytest-xdist options for the whole suite: ``$HAIRLUT_TEST_WORKERS`` workers (default 2, at most the CPU
    count), each test file on one worker so that its module fixtures are built once. Much of the suite's time
    is single-threaded work (XLA compilation, HDF5, forked children), so one process leaves a core of a
    2-core machine idle; the workers share one XLA compilation cache (tests/conftest.py). Files are handed out
    costliest first (tests/conftest.py ``COSTLIEST_FIRST``), not by xdist's default of most tests first, so
    that no long file starts last and keeps one worker busy alone."""
    n = int(os.environ.get("HAIRLUT_TEST_WORKERS", min(2, os.cpu_count() or 1)))
    return ["-n", str(n), "--dist", "loadfile", "--no-loadscope-reorder"] if n > 1 else []


def build_docs() -> int:
    """``mkdocs build --strict`` (mkdocs.yml) into a temporary folder: a broken link, a broken docstring or a
    public name without one fails it.  Its exit status."""
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}  # mkdocs-material's notice about MkDocs 2.0, not a finding
    with tempfile.TemporaryDirectory(prefix="hairlut-site-") as site:
        print("run.py: building the documentation site (mkdocs build --strict)", file=sys.stderr)
        # not --quiet: it hides the warnings from the count that --strict fails on
        return subprocess.run(
            [str(BIN / "python"), "-m", "mkdocs", "build", "--strict", "--site-dir", site], cwd=ROOT, env=env
        ).returncode


def main(argv: list[str]) -> int:
    if not argv or argv[0] not in {"demo", "test", "hairlut"}:
        print(__doc__, file=sys.stderr)
        return 2
    task, rest = argv[0], argv[1:]
    # Every task shares one environment, with the test and docs extras, so switching never reinstalls.
    ensure_venv("test,docs")
    if task == "test":
        for check in (["check", "."], ["format", "--check", "."]):  # the lint before the suite: seconds, not minutes
            code = subprocess.run([str(BIN / "ruff"), *check], cwd=ROOT).returncode
            if code != 0:
                return code
        cmd = [str(BIN / "python"), "-m", "pytest", *test_workers(), *rest]  # options in ARGS come later: they win
        code = subprocess.run(cmd, cwd=ROOT).returncode
        return code if code != 0 else build_docs()
    if task == "demo":
        cmd = [str(BIN / "hairlut"), "demo", *rest]
    else:
        cmd = [str(BIN / "hairlut"), *rest]
    return subprocess.run(cmd, cwd=ROOT).returncode


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
