"""The content-addressed cache: reuse by recipe hash, safe concurrent bakes, prune."""

import json
import os
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from hairlut.assets import Axis, Variable, read_table, write_table
from hairlut.bake.cache import asset_path, ensure, entries, prune

from . import _tables  # noqa: F401  (declares the test kind kk_lobes)


def _bake_lobes(recipe, calls):
    def bake(path):
        calls.append(path)
        x = np.linspace(0, 1, recipe["n"])
        write_table(
            path,
            "kk_lobes",
            recipe,
            [Axis("x", x, "1", "x"), Axis("p", [1.0], "1", "p")],
            [Variable("diffuse", x, ("x",), "1", "d"), Variable("specular", x[None], ("p", "x"), "1", "s")],
        )

    return bake


def test_reuse_and_rebake(tmp_path):
    calls = []
    r1, r2 = {"n": 5}, {"n": 6}
    p1, s1 = ensure("kk_lobes", r1, _bake_lobes(r1, calls), tmp_path)
    p1b, s1b = ensure("kk_lobes", r1, _bake_lobes(r1, calls), tmp_path)
    p2, s2 = ensure("kk_lobes", r2, _bake_lobes(r2, calls), tmp_path)
    assert (s1, s1b, s2) == ("baked", "reused", "baked") and p1 == p1b != p2 and len(calls) == 2
    assert p1 == asset_path("kk_lobes", r1, tmp_path)
    raw = p1.read_bytes()
    p1.write_bytes(raw[: len(raw) // 2])  # a damaged cache entry is rebaked, not trusted
    assert ensure("kk_lobes", r1, _bake_lobes(r1, calls), tmp_path)[1] == "baked"
    assert read_table(p1)["diffuse"].shape == (5,)
    assert {e.path for e in entries(tmp_path)} == {p1, p2}


def test_prune(tmp_path):
    calls = []
    for n in (3, 4):
        ensure("kk_lobes", {"n": n}, _bake_lobes({"n": n}, calls), tmp_path)
    stale = tmp_path / ".x.h5.123.abcd.tmp"
    stale.write_bytes(b"partial")
    fresh = tmp_path / ".y.h5.124.abcd.tmp"
    fresh.write_bytes(b"being written")
    os.utime(stale, (time.time() - 7200, time.time() - 7200))
    assert prune(tmp_path) == [stale]
    assert fresh.exists() and len(entries(tmp_path)) == 2
    assert len(prune(tmp_path, kinds=["sh_tables"])) == 0
    gone = prune(tmp_path, everything=True)
    assert entries(tmp_path) == [] and len([p for p in gone if p.suffix == ".h5"]) == 2


def test_two_processes_bake_one_file(tmp_path, hairlut_exe):
    env = {**os.environ, "HAIRLUT_CACHE": str(tmp_path)}
    cmd = [hairlut_exe, "bake", "sh", "--p", "4", "--set", "dense.t_resolution=8", "--json"]
    procs = [subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1] for o in outs]
    docs = [json.loads(o[0]) for o in outs]
    assert sorted(d["status"] for d in docs) == ["baked", "reused"]
    assert docs[0]["out"] == docs[1]["out"]
    path = Path(docs[0]["out"])
    assert read_table(path, kind="sh_tables")["dense/rs"].shape[0] == 6 * 64
    assert [p.name for p in tmp_path.iterdir() if p.suffix == ".h5"] == [path.name]


def test_ls_lists_garbage_and_misnamed_files_as_such(tmp_path):
    """Issue 29 m10: ``cache ls`` hid a garbage entry and listed another recipe's file under the hash in its name."""
    from click.testing import CliRunner

    from hairlut_cli.main import cli

    good, other = (ensure("kk_lobes", {"n": n}, _bake_lobes({"n": n}, []), tmp_path)[0] for n in (5, 6))
    misnamed = tmp_path / "kk_lobes-0123456789abcdef.h5"
    misnamed.write_bytes(other.read_bytes())  # another recipe's file under a name its hash does not give
    garbage = tmp_path / "kk_lobes-fedcba9876543210.h5"
    garbage.write_bytes(b"not a table")
    by_path = {e.path: e for e in entries(tmp_path)}
    assert {p: e.status for p, e in by_path.items()} == {good: "ok", other: "ok", misnamed: "foreign", garbage: "corrupt"}
    assert by_path[misnamed].recipe_hash == by_path[other].recipe_hash  # listed under its own recipe's hash
    assert other.name in by_path[misnamed].fault and "HDF5" in by_path[garbage].fault

    res = CliRunner().invoke(cli, ["cache", "ls", "--cache", str(tmp_path)])
    assert res.exit_code == 0, res.output
    rows = {next(w for w in line.split() if w.startswith(str(tmp_path))): line for line in res.output.splitlines()[:-1]}
    assert rows[str(garbage)].startswith("corrupt") and rows[str(misnamed)].startswith("foreign")
    assert by_path[other].recipe_hash[:16] in rows[str(misnamed)] and other.name in rows[str(misnamed)]
    assert rows[str(good)].startswith("ok") and res.output.splitlines()[-1].startswith("4 assets (1 foreign, 1 corrupt)")
    listed = json.loads(CliRunner().invoke(cli, ["cache", "ls", "--cache", str(tmp_path), "--json"]).output)
    assert {Path(e["path"]): e["status"] for e in listed} == {p: e.status for p, e in by_path.items()}

    prune(tmp_path, everything=True)
    assert garbage.exists() and not good.exists()  # what fails validation may not be hairlut's: never deleted


def test_a_corrupt_cache_entry_is_called_corrupt_not_missing(tmp_path):
    """Issue 29 m10: ``synth`` called a corrupt cache entry "not in the cache"."""
    from hairlut import errors
    from hairlut.planner import find_assets, plan

    from ._synth_fixtures import scene

    sc = scene()
    step = next(s for s in plan(sc, tmp_path).steps if s.kind is not None and s.action == "bake")
    with pytest.raises(errors.AssetNotFoundError, match="not in the cache"):
        find_assets(sc, tmp_path)
    Path(step.path).write_bytes(b"\x89HDF\r\n\x1a\n garbage")
    with pytest.raises(errors.CorruptAssetError) as exc:
        find_assets(sc, tmp_path)
    assert exc.value.path == step.path and "unusable" in str(exc.value) and "not in the cache" not in str(exc.value)
