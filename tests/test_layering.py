"""The house keeps its floors: DESIGN.md's floor table is the law, read from DESIGN.md itself.

Every import inside ``hairlut`` (at module level or inside a function: a deferred import is still a
dependency) goes from a floor down to a lower one (or to a unit listed before it on its own floor's line),
or stays inside its own package; no package imports
another package's private module (a name that starts with ``_``); the command line imports only public
modules; every module of ``hairlut`` sits on a floor.  The checks read the source with :mod:`ast`, so they
run without importing JAX.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "hairlut"


def floors() -> dict[str, tuple[int, int]]:
    """DESIGN.md's ``floor N  name name ...`` lines: top-level module or package → (floor, place on its line).
    A unit may import the units below its floor and those before it on its own line."""
    text = (ROOT / "DESIGN.md").read_text()
    table = {}
    for n, names in re.findall(r"^floor (\d+)\s+(.+)$", text, re.M):
        for place, name in enumerate(re.findall(r"[\w.]+", names.split("#")[0])):
            table[name] = (int(n), place)
    assert table, "DESIGN.md has no floor table"
    return table


def modules() -> dict[str, Path]:
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def imports(name: str, path: Path, known) -> list[tuple[int, str]]:
    """(line, imported module) of every hairlut import of one module, relative ones resolved."""
    out = []
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.split(".")[0] == "hairlut"]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            if base.split(".")[0] != "hairlut":
                continue
            for a in node.names:  # `from pkg import module` imports the module
                full = f"{base}.{a.name}"
                out.append((node.lineno, full if full in known else base))
    return out


def top(name: str) -> str:
    """The floor unit of a module: its top-level module or package under hairlut."""
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else "hairlut"


def is_private(name: str) -> bool:
    """Whether a module is private to its package (a component after the top-level one starts with '_')."""
    return any(p.startswith("_") and not p.startswith("__") for p in name.split(".")[2:])


def test_every_module_sits_on_a_floor():
    table = floors()
    missing = sorted({top(m) for m in modules()} - set(table) - {"hairlut"})
    assert not missing, f"add these to DESIGN.md's floor table: {missing}"


def test_no_import_runs_up_a_floor():
    table, known = floors(), modules()
    up = []
    for name, path in known.items():
        here = top(name)
        for line, target in imports(name, path, known):
            there = top(target)
            if there == here or here == "hairlut" or there == "hairlut":
                continue  # inside a package; the root's lazy map names every package by string, not import
            if table[there] >= table[here]:  # (floor, place): a lower floor, or earlier on the same line
                up.append(
                    f"{path.relative_to(ROOT)}:{line}: {here} (floor {table[here][0]}) imports {target} "
                    f"(floor {table[there][0]}{', later on the same line' if table[there][0] == table[here][0] else ''})"
                )
    assert not up, "imports that do not go down a floor:\n" + "\n".join(up)


def test_no_package_imports_another_packages_private_module():
    known = modules()
    private = []
    for name, path in known.items():
        for line, target in imports(name, path, known):
            if top(target) != top(name) and is_private(target):
                private.append(f"{path.relative_to(ROOT)}:{line}: imports {target}")
    assert not private, "\n".join(private)


def test_the_command_line_imports_public_modules_only():
    known = modules()
    private = []
    for path in sorted((ROOT / "cli").glob("*.py")):
        for line, target in imports("hairlut_cli." + path.stem, path, known):
            if is_private(target):
                private.append(f"{path.relative_to(ROOT)}:{line}: imports {target}")
    assert not private, "\n".join(private)


@pytest.mark.parametrize("case", ["up", "private"])
def test_the_checks_can_fail(case, tmp_path, monkeypatch):
    """A module that imports up a floor, or another package's private module, is found."""
    table, known = floors(), modules()
    source = {"up": "from ..synth import prepare\n", "private": "from ..hrir._io import load_hrir_db\n"}[case]
    fake = tmp_path / "fake.py"
    fake.write_text(source)
    found = imports("hairlut.geometry.fake", fake, known)
    ((line, target),) = found
    if case == "up":
        assert table[top(target)][0] > table["geometry"][0]
    else:
        assert is_private(target) and top(target) != "geometry"
