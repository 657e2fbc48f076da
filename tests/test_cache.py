"""The content-addressed cache: reuse by recipe hash, safe concurrent bakes, prune."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from hairlut.assets import Axis, Variable, read_table, write_table
from hairlut.cache import asset_path, ensure, entries, prune

from . import _tables  # noqa: F401  (declares the test kind kk_lobes)


def _bake_lobes(recipe, calls):
    def bake(path):
        calls.append(path)
        x = np.linspace(0, 1, recipe["n"])
        write_table(path, "kk_lobes", recipe, [Axis("x", x, "1", "x"), Axis("p", [1.0], "1", "p")],
                    [Variable("diffuse", x, ("x",), "1", "d"), Variable("specular", x[None], ("p", "x"), "1", "s")])
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
