"""Every code block of the documentation runs (issue 29 m18), so that the README cannot drift from the code again.

README.md, DESIGN.md, docs/**/*.md (the documentation site's pages, and the files they include, such as the
generated docs/bench/report.md) and benchmarks/records.md are read for fenced ``python`` and ``sh`` blocks.  Each
runs, in the order of its document, in one scratch folder per document that holds a copy of the repository's
``tables/`` recipes, scenes and grooms and a ``.venv`` link to this interpreter's environment, with
``$HAIRLUT_CACHE`` at the scratch ``tables/`` (the README's default cache) and this venv's ``hairlut`` first on
``PATH``: a python block in this process (its traceback names the document's lines), an sh block in
``bash -e -o pipefail``.  So a block may use what the blocks before it wrote, as a reader following the document
would.

An HTML comment on the line before a block says how it runs, with a reason:
``<!-- slow: reason -->`` (a bake or a render of minutes: runs with the slow tests, and so do the blocks that use
its files) and ``<!-- no-test: reason -->`` (cannot run in CI: a GPU, a SLURM cluster, a network install, a
benchmark's many minutes).  A marker without a reason, or one that stands before no tested block, fails.
(tests/test_cli_examples.py checks the files that the CLI's own help names.)
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", ROOT / "DESIGN.md", *sorted((ROOT / "docs").rglob("*.md")), ROOT / "benchmarks" / "records.md"]
LANGUAGES = {"python": "python", "sh": "sh", "bash": "sh"}
FENCE = re.compile(r"^(\s*)```(\S*)\s*$")
MARKER = re.compile(r"^\s*<!--\s*(no-test|slow)\s*:(.*?)-->\s*$")


@dataclass(frozen=True)
class Block:
    doc: Path
    line: int  # the first line of the code, 1-based
    language: str  # as fenced: python, sh, text, ""
    code: str
    mark: str | None  # "slow", "no-test" or None
    reason: str

    @property
    def id(self) -> str:
        return f"{self.doc.relative_to(ROOT)}:{self.line}"


def blocks(doc: Path) -> list[Block]:
    """The fenced blocks of ``doc`` with the marker before each (indented fences, as in a list item, are dedented)."""
    lines = doc.read_text().splitlines()
    out, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, language = len(m.group(1)), m.group(2)
        end = next(j for j in range(i + 1, len(lines)) if lines[j].strip() == "```")
        code = "\n".join(line[indent:] for line in lines[i + 1 : end]) + "\n"
        before = next((lines[j] for j in range(i - 1, -1, -1) if lines[j].strip()), "")
        mark = MARKER.match(before)
        out.append(Block(doc, i + 2, language, code, mark and mark.group(1), mark.group(2).strip() if mark else ""))
        i = end + 1
    return out


ALL = [b for doc in DOCS for b in blocks(doc)]
TESTED = [b for b in ALL if b.language in LANGUAGES]


def test_every_marker_states_its_reason_and_stands_before_a_tested_block():
    assert len(TESTED) >= 20, "the documentation's blocks were not found"
    assert any(b.doc.parent.name == "guide" for b in TESTED), "the docs/guide pages' blocks were not found"
    for b in ALL:
        if b.mark:
            assert b.language in LANGUAGES, f"{b.id}: a {b.mark} marker before a {b.language or 'plain'} block"
            assert len(b.reason) >= 20, f"{b.id}: the {b.mark} marker must say why ({b.reason!r})"
    for doc in DOCS:
        text = doc.read_text()
        marked = len(re.findall(r"<!--\s*(?:no-test|slow)\s*:", text))
        assert marked == sum(1 for b in ALL if b.doc == doc and b.mark), f"{doc.name}: a marker stands before no block"


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """One folder per document: the repository's recipes, scenes and grooms under tables/, .venv → this venv."""
    folders = {}

    def folder(doc: Path) -> Path:
        if doc not in folders:
            f = tmp_path_factory.mktemp(doc.stem)
            (f / "tables").mkdir()
            for p in (ROOT / "tables").glob("*.toml"):
                shutil.copy(p, f / "tables" / p.name)
            for sub in ("scenes", "grooms"):
                shutil.copytree(ROOT / "tables" / sub, f / "tables" / sub)
            (f / ".venv").symlink_to(sys.prefix, target_is_directory=True)
            folders[doc] = f
        return folders[doc]

    return folder


def _param(b: Block):
    marks = {"slow": [pytest.mark.slow], "no-test": [pytest.mark.skip(reason=f"{b.id}: {b.reason}")]}.get(b.mark, [])
    return pytest.param(b, id=b.id, marks=marks)


@pytest.mark.parametrize("block", [_param(b) for b in TESTED])
def test_the_block_runs(block: Block, scratch, monkeypatch):
    folder = scratch(block.doc)
    cache = folder / "tables"
    monkeypatch.chdir(folder)
    monkeypatch.setenv("HAIRLUT_CACHE", str(cache))
    if LANGUAGES[block.language] == "python":
        code = compile("\n" * (block.line - 1) + block.code, str(block.doc), "exec")  # tracebacks name the doc's lines
        exec(code, {"__name__": f"docs_{block.doc.stem}_{block.line}"})
        return
    bindir = Path(sys.executable).parent
    if not (bindir / "hairlut").exists():
        pytest.skip(f"the hairlut console script is not installed beside {sys.executable}")
    env = {**os.environ, "HAIRLUT_CACHE": str(cache), "PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}"}
    r = subprocess.run(
        ["bash", "-e", "-o", "pipefail", "-c", block.code], cwd=folder, env=env, capture_output=True, text=True, timeout=3600
    )
    assert r.returncode == 0, f"{block.id} exited {r.returncode}:\n{block.code}\n--- output ---\n{(r.stdout + r.stderr)[-4000:]}"


def test_readme_is_a_front_door():
    """The README stays a front door (issue 27: at most 250 lines; the rest is the documentation site) and names
    run.py's two set-up commands as they are."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 250, f"README.md has {len(text.splitlines())} lines; move detail into docs/"
    run_py = (ROOT / "run.py").read_text(encoding="utf-8")
    for task in ("demo", "test"):
        assert f"python3 run.py {task}" in text and f"python3 run.py {task}" in run_py, task
