"""The distribution ships every package on disk and the example inputs, the library never imports click, and an
installed wheel (not a clone) runs every part of ``hairlut bench``."""

import ast
import json
import os
import shutil
import site
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_is_listed():
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(conf["packages"])
    on_disk = {"hairlut_cli", "hairlut.examples"} | {
        ".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "hairlut").rglob("__init__.py")
    }
    assert on_disk == listed
    assert conf["package-dir"] == {"hairlut": "hairlut", "hairlut_cli": "cli", "hairlut.examples": "tables"}


def test_the_example_inputs_are_shipped():
    """Every recipe, scene and groom (with its licence) of tables/ matches a package-data pattern of hairlut.examples,
    and nothing else there does (the baked tables in the default cache are not shipped)."""
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    patterns = conf["package-data"]["hairlut.examples"]
    tracked = {
        "hrir-default.toml",
        "sh-default.toml",
        "sh-paper.toml",
        "grooms/README.md",
        "grooms/LICENSE-sintel.txt",
        "grooms/LICENSE-ratboy.txt",
        "grooms/sintel_lite.tfx",
        "grooms/ratboy_mohawk.tfx",
        "grooms/curly.hair",
        *(f"scenes/{p.name}" for p in (ROOT / "tables" / "scenes").glob("*.toml")),
    }
    shipped = {p.relative_to(ROOT / "tables").as_posix() for pat in patterns for p in (ROOT / "tables").glob(pat)}
    assert shipped == tracked
    from hairlut.bench import example

    assert example("scenes/sintel-groom.toml").is_file() and example("grooms/sintel_lite.tfx").is_file()
    assert example("scenes/curly-groom.toml").is_file() and example("grooms/curly.hair").is_file()  # the demo's


def test_the_bench_runs_no_script_by_path():
    """hairlut.bench holds every study it runs: no code string of it names the repository's benchmarks/ folder, and
    the only path it takes from its own location is where the example inputs are."""
    for path in (ROOT / "hairlut" / "bench").glob("*.py"):
        tree = ast.parse(path.read_text(), str(path))
        docs = {
            id(n.body[0].value)
            for n in ast.walk(tree)
            if isinstance(n, (ast.Module, ast.FunctionDef, ast.ClassDef))
            and n.body
            and isinstance(n.body[0], ast.Expr)
            and isinstance(n.body[0].value, ast.Constant)
        }
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
                assert "benchmarks" not in node.value, f"{path.name}:{node.lineno}"
        assert "__file__" not in path.read_text() or path.name in ("_parts.py", "_report.py"), path.name


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


def _build_tree(dest: Path) -> Path:
    """What the wheel is built from, copied out of the clone (pip builds in the source folder, and the clone's
    tables/ may hold baked assets the package data must not pick up)."""
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, dest / name)
    skip = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info")
    for name in ("hairlut", "cli"):
        shutil.copytree(ROOT / name, dest / name, ignore=skip)
    (dest / "tables").mkdir()
    for p in (ROOT / "tables").glob("*.toml"):
        shutil.copy(p, dest / "tables" / p.name)
    for name in ("scenes", "grooms"):
        shutil.copytree(ROOT / "tables" / name, dest / "tables" / name, ignore=skip)
    return dest


@pytest.mark.slow
def test_an_installed_wheel_runs_every_bench_part(tmp_path):
    """Issue 27: `hairlut bench --quick` from a wheel installed into a fresh virtual environment, run outside the
    clone: every part runs (the scale part may be skipped for a one-core machine, never for want of a clone), and the
    report names no local path.  No network: the wheel is built without build isolation (setuptools and wheel are in
    the test extra) and installed without dependencies into a venv that sees this environment's packages through a
    .pth file (its own site-packages first, so `import hairlut` is the wheel's)."""
    pytest.importorskip("wheel")
    src, wheels, env_dir, work = (tmp_path / n for n in ("src", "wheels", "venv", "elsewhere"))
    for d in (src, wheels, work):
        d.mkdir()
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--no-input"]
    subprocess.run(
        [*pip, "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-w", str(wheels), str(_build_tree(src))],
        check=True,
        capture_output=True,
        timeout=600,
    )
    (wheel,) = wheels.glob("hairlut-*.whl")
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(env_dir)], check=True, timeout=120)
    py = env_dir / "bin" / "python"
    purelib = subprocess.run(
        [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], check=True, capture_output=True, text=True
    ).stdout.strip()
    (Path(purelib) / "_test_env.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    subprocess.run(
        [*pip, "--python", str(py), "install", "--no-deps", "--no-index", str(wheel)],
        check=True,
        capture_output=True,
        timeout=600,
    )
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "HAIRLUT_CACHE")}
    where = subprocess.run(
        [
            str(py),
            "-c",
            "import hairlut, hairlut.bench; print(hairlut.__file__); print(hairlut.bench.example('grooms/sintel_lite.tfx'))",
        ],
        cwd=work,
        env=env,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    assert all(Path(w).is_relative_to(env_dir) for w in where), where
    out = work / "bench"
    run = subprocess.run(
        [str(env_dir / "bin" / "hairlut"), "bench", "--quick", "--out", str(out), "--no-progress"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=3600,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    doc = json.loads((out / "results.json").read_text())
    one_core = len(os.sched_getaffinity(0)) < 2
    for name, info in doc["parts"].items():
        if name == "scale" and one_core:
            assert info["status"] == "skipped" and "one core" in info["reason"], info
        else:
            assert info["status"] == "ok", (name, info)
    from hairlut.bench import PARTS

    assert set(doc["parts"]) == set(PARTS)  # every registered part, as this checkout registers them
    md = (out / "report.md").read_text()
    for local in (str(tmp_path), str(ROOT), str(env_dir)):
        assert local not in md
    assert all((out / p).is_file() for p in doc["plots"].values())
