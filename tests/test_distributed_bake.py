"""Bakes across local devices and jax.distributed processes; virtual assets over parts; the parts folder's safety."""

import hashlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import pytest

from hairlut import errors
from hairlut.hrir import bake, load_hrir_db, parts_dir
from hairlut.parts import MARKER, check_virtual, locked

RECIPE = '[sectors]\ncount = 12\ngrid = [8, 8]\n[angles]\nviews = 4\nlights = 3\n[trace]\npixels = 8\nsteps = 12\n'
SMALL = {"sectors": {"count": 12, "grid": [8, 8]}, "angles": {"views": 4, "lights": 3}, "trace": {"pixels": 8, "steps": 12}}
CODE = "import sys; from hairlut_cli.main import cli; cli(sys.argv[1:])"


def _sha(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _datasets(path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda n, o: out.__setitem__(n, o[()]) if isinstance(o, h5py.Dataset) else None)  # None: visit all
    return out


def _assert_same_data(a, b):
    da, db = _datasets(a), _datasets(b)
    assert sorted(da) == sorted(db)
    for name in da:
        assert da[name].dtype == db[name].dtype and da[name].tobytes() == db[name].tobytes(), name


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(devices: int) -> dict:
    return {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_NUM_CPU_DEVICES": str(devices)}


def _cmd(recipe, out, *extra):
    return [sys.executable, "-c", CODE, "bake", "hrir", "--recipe", str(recipe), "--out", str(out), "--block", "4",
            "--no-progress", *extra]


def _launch(recipe, out, port, *extra, devices=2):
    return [subprocess.Popen(_cmd(recipe, out, "--distributed", "--coordinator", f"127.0.0.1:{port}",
                                  "--num-processes", "2", "--process-id", str(k), "--json", *extra),
                             env=_env(devices), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            for k in range(2)]


def _finish(procs, timeout=300):
    outs = [p.communicate(timeout=timeout) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1][-2000:] for o in outs]
    # the report is the JSON document on stdout; gloo (JAX's CPU collectives) prints its own lines there too
    return [json.loads(o[0][o[0].index("\n{") + 1 if not o[0].startswith("{") else 0:]) for o in outs]


@pytest.fixture
def recipe(tmp_path):
    path = tmp_path / "r.toml"
    path.write_text(RECIPE)
    return path


def test_two_local_devices_bake_the_same_bytes_as_one(recipe, tmp_path):
    for d in (1, 2):
        subprocess.run(_cmd(recipe, tmp_path / f"d{d}.h5"), env=_env(d), check=True, capture_output=True)
    assert _sha(tmp_path / "d1.h5") == _sha(tmp_path / "d2.h5")


@pytest.mark.slow
def test_two_processes_on_loopback_match_one_process(recipe, tmp_path):
    subprocess.run(_cmd(recipe, tmp_path / "one.h5"), env=_env(1), check=True, capture_output=True)
    out = tmp_path / "db.h5"
    docs = _finish(_launch(recipe, out, _free_port()))
    assert [d["process"] for d in docs] == [0, 1] and [d["sector_range"] for d in docs] == [[0, 4], [4, 12]]
    assert all(d["computed"] == d["sectors"] for d in docs)
    _assert_same_data(tmp_path / "one.h5", out)  # virtual datasets read through to the parts, bit for bit
    with h5py.File(out, "r") as f:
        assert f["reflectance"].is_virtual and not f["features"].is_virtual
    assert len(check_virtual(out)) == 3 and (parts_dir(out) / MARKER).is_file()
    dump = subprocess.run(["h5dump", "-d", "/alpha", str(out)], capture_output=True, text=True)
    assert dump.returncode == 0 and "DATASPACE  SIMPLE { ( 12, 4, 8 )" in dump.stdout and "nan" not in dump.stdout.lower()
    db = load_hrir_db(out)
    assert db.reflectance.shape == (12, 4, 3, 8)
    # --merge copy: one self-contained file, byte-identical to a one-process bake
    copy = tmp_path / "copy.h5"
    _finish(_launch(recipe, copy, _free_port(), "--merge", "copy"))
    assert _sha(copy) == _sha(tmp_path / "one.h5") and not parts_dir(copy).exists()


def test_virtual_asset_with_a_missing_or_foreign_part(tmp_path):
    out = tmp_path / "db.h5"
    bake(SMALL, out, block=4, merge="virtual")
    ref = bake(SMALL, tmp_path / "ref.h5", block=4)
    _assert_same_data(ref["out"], out)
    assert load_hrir_db(out).alpha.shape == (12, 4, 8)
    parts = sorted(parts_dir(out).glob("part-*.h5"))
    assert len(parts) == 3
    other = {**SMALL, "phong": {"shininess": 5.0}}
    bake(other, tmp_path / "o.h5", block=4, keep_parts=True)
    foreign = sorted(parts_dir(tmp_path / "o.h5").glob("part-*.h5"))[1]
    saved = parts[1].read_bytes()
    parts[1].write_bytes(foreign.read_bytes())
    with pytest.raises(errors.CorruptAssetError) as exc:
        load_hrir_db(out)
    assert exc.value.path == str(parts[1]) and "another recipe" in str(exc.value)
    parts[1].unlink()
    with pytest.raises(errors.AssetNotFoundError) as exc:
        load_hrir_db(out)
    assert exc.value.path == str(parts[1]) and "missing" in str(exc.value)
    from hairlut.cache import is_valid
    from hairlut.sharding import valid_asset

    digest = ref["recipe_hash"]
    assert not valid_asset(out, "hrir_db", digest) and not is_valid(out, "hrir_db", digest)
    parts[1].write_bytes(saved)
    assert valid_asset(out, "hrir_db", digest) and is_valid(out, "hrir_db", digest)


@pytest.mark.slow
def test_a_killed_process_resumes_its_part(recipe, tmp_path):
    subprocess.run(_cmd(recipe, tmp_path / "one.h5", "--set", "sectors.count=16"), env=_env(1), check=True,
                   capture_output=True)
    out = tmp_path / "db.h5"
    procs = _launch(recipe, out, _free_port(), "--set", "sectors.count=16", "--block", "2", devices=1)
    mine = parts_dir(out) / "part-000000008-000000010.h5"  # process 1's first part (sectors 8..15)
    deadline = time.time() + 120
    while time.time() < deadline and not mine.exists():
        time.sleep(0.05)
    for p in procs[::-1]:
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
    assert mine.exists() and not out.exists()
    kept = {p.name for p in parts_dir(out).glob("part-*.h5")}
    docs = _finish(_launch(recipe, out, _free_port(), "--set", "sectors.count=16", "--block", "2", devices=1))
    assert docs[1]["resumed"] >= 2 and docs[1]["resumed"] + docs[1]["computed"] == 8
    assert sum(d["resumed"] for d in docs) == 2 * len(kept)
    _assert_same_data(tmp_path / "one.h5", out)


def test_a_users_parts_folder_is_never_touched(tmp_path):
    out = tmp_path / "X.h5"
    mine = parts_dir(out)
    mine.mkdir()
    (mine / "notes.txt").write_text("my own notes")
    with pytest.raises(errors.ValidationError) as exc:
        bake(SMALL, out, block=4)
    assert "not made by hairlut" in str(exc.value) and (mine / "notes.txt").read_text() == "my own notes"
    assert not out.exists()
    # a symlinked parts folder or lock is refused, never written through
    target = tmp_path / "elsewhere"
    target.mkdir()
    link = tmp_path / "Y.h5"
    parts_dir(link).symlink_to(target)
    with pytest.raises(errors.ValidationError, match="symlink"):
        bake(SMALL, link, block=4)
    assert list(target.iterdir()) == []
    z = tmp_path / "Z.h5"
    (tmp_path / "Z.h5.parts.lock").symlink_to(tmp_path / "victim")
    with pytest.raises(errors.ValidationError, match="symlink"):
        bake(SMALL, z, block=4)
    assert not (tmp_path / "victim").exists()
    # hairlut's own folder with a user's file in it: the parts go, the user's file and folder stay
    w = tmp_path / "W.h5"
    bake(SMALL, w, block=4, keep_parts=True)
    (parts_dir(w) / "keep.txt").write_text("mine")
    bake(SMALL, w, block=4)
    assert [p.name for p in parts_dir(w).iterdir() if not p.name.startswith(".")] == ["keep.txt"]


def test_concurrent_bakes_of_one_output_wait_and_stray_temporaries_go(tmp_path):
    out = tmp_path / "db.h5"
    first = bake(SMALL, out, block=4, keep_parts=True)
    stray = [tmp_path / ".db.h5.99999.dead.tmp", parts_dir(out) / ".part-000000000-000000004.h5.99999.dead.tmp"]
    for p in stray:
        p.write_bytes(b"half a file")
    held = threading.Event()

    def hold():
        with locked(out):
            held.set()
            time.sleep(1.0)

    t = threading.Thread(target=hold)
    t.start()
    held.wait()
    t0 = time.perf_counter()
    rep = bake(SMALL, out, block=4)  # waits for the holder, then finds the finished asset
    t.join()
    assert time.perf_counter() - t0 >= 0.9 and rep["status"] == "reused" and rep["computed"] == 0
    assert _sha(out) == _sha(first["out"])
    rep = bake(SMALL, out, block=4)  # nobody holds the lock: a normal (resumed) bake, temporaries cleaned
    assert rep["status"] == "baked" and not any(p.exists() for p in stray)
