"""run.py's pytest-xdist schedule: files handed out in collection order, costliest first (tests/conftest.py)."""

import importlib.util

from .conftest import COSTLIEST_FIRST, ROOT


def test_every_costliest_file_exists():
    missing = [name for name in COSTLIEST_FIRST if not (ROOT / "tests" / name).is_file()]
    assert not missing, f"COSTLIEST_FIRST names files the suite lacks: {missing}"
    assert len(set(COSTLIEST_FIRST)) == len(COSTLIEST_FIRST)


def test_run_py_keeps_the_collection_order(monkeypatch):
    spec = importlib.util.spec_from_file_location("hairlut_run_py", ROOT / "run.py")
    run_py = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(run_py)
    monkeypatch.setenv("HAIRLUT_TEST_WORKERS", "2")
    assert run_py.test_workers() == ["-n", "2", "--dist", "loadfile", "--no-loadscope-reorder"]
    monkeypatch.setenv("HAIRLUT_TEST_WORKERS", "1")
    assert run_py.test_workers() == []
