"""The distribution ships every package on disk, and the library never imports click."""

import ast
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_is_listed():
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(conf["packages"])
    on_disk = {"hairlut_cli"} | {
        ".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "hairlut").rglob("__init__.py")
    }
    assert on_disk == listed
    assert conf["package-dir"] == {"hairlut": "hairlut", "hairlut_cli": "cli"}


def test_library_does_not_import_click_or_print():
    for path in (ROOT / "hairlut").rglob("*.py"):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                assert not any(n.split(".")[0] in {"click", "hairlut_cli"} for n in names), path
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) in {"print", "exit"}:
                raise AssertionError(f"{path}:{node.lineno} calls {node.func.id}")


def test_lazy_public_api():
    import subprocess
    import sys

    code = "import sys, hairlut; assert 'jax' not in sys.modules; from hairlut import SHTables; print(SHTables.__module__)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "hairlut.shtables._tables", out.stderr
