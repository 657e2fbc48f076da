"""Bakes across local devices and jax.distributed processes; virtual assets over parts; the parts folder's safety."""

import hashlib
import json
import os
import shutil
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
from hairlut.assets.parts import MARKER, locked, part_name, parts_dir
from hairlut.assets.virtual_write import check_virtual
from hairlut.hrir import bake, load_hrir_db

RECIPE = "[sectors]\ncount = 12\ngrid = [8, 8]\n[angles]\nviews = 4\nlights = 3\n[trace]\npixels = 8\nsteps = 12\n"
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


def _h5dump_agrees(path, dataset: str, shape: str) -> None:
    """HDF5's own reader sees ``dataset`` of ``path`` with ``shape`` and no NaN; skipped where h5dump is not
    installed (Debian hdf5-tools; `.ci/run` installs it), after every other check of the test has run."""
    if shutil.which("h5dump") is None:
        pytest.skip("h5dump (Debian hdf5-tools) not installed; every other check of this test passed")
    dump = subprocess.run(["h5dump", "-d", dataset, str(path)], capture_output=True, text=True, timeout=120)
    assert dump.returncode == 0 and f"DATASPACE  SIMPLE {{ {shape} )" in dump.stdout and "nan" not in dump.stdout.lower()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(devices: int) -> dict:
    return {**os.environ, "JAX_PLATFORMS": "cpu", "JAX_NUM_CPU_DEVICES": str(devices)}


def _cmd(recipe, out, *extra):
    return [
        sys.executable,
        "-c",
        CODE,
        "bake",
        "hrir",
        "--recipe",
        str(recipe),
        "--out",
        str(out),
        "--block",
        "4",
        "--no-progress",
        *extra,
    ]


def _launch(recipe, out, port, *extra, devices=2):
    return [
        subprocess.Popen(
            _cmd(
                recipe,
                out,
                "--distributed",
                "--coordinator",
                f"127.0.0.1:{port}",
                "--num-processes",
                "2",
                "--process-id",
                str(k),
                "--json",
                *extra,
            ),
            env=_env(devices),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for k in range(2)
    ]


def _finish(procs, timeout=300):
    outs = [p.communicate(timeout=timeout) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1][-2000:] for o in outs]
    # the report is the JSON document on stdout; gloo (JAX's CPU collectives) prints its own lines there too
    return [json.loads(o[0][o[0].index("\n{") + 1 if not o[0].startswith("{") else 0 :]) for o in outs]


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
    assert [d["process"] for d in docs] == [0, 1] and [d["unit_range"] for d in docs] == [[0, 4], [4, 12]]
    assert all(d["computed"] == d["units"] for d in docs)
    _assert_same_data(tmp_path / "one.h5", out)  # virtual datasets read through to the parts, bit for bit
    with h5py.File(out, "r") as f:
        assert f["reflectance"].is_virtual and not f["features"].is_virtual
    assert len(check_virtual(out)) == 3 and (parts_dir(out) / MARKER).is_file()
    db = load_hrir_db(out)
    assert db.reflectance.shape == (12, 4, 3, 8)
    # --merge copy: one self-contained file, byte-identical to a one-process bake
    copy = tmp_path / "copy.h5"
    _finish(_launch(recipe, copy, _free_port(), "--merge", "copy"))
    assert _sha(copy) == _sha(tmp_path / "one.h5") and not parts_dir(copy).exists()
    _h5dump_agrees(out, "/alpha", "( 12, 4, 8")


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
    from hairlut.bake.cache import is_valid  # the one validity rule, which the bake's own reuse check calls too

    digest = ref["recipe_hash"]
    assert not is_valid(out, "hrir_db", digest)
    parts[1].write_bytes(saved)
    assert is_valid(out, "hrir_db", digest)


@pytest.mark.slow
def test_a_killed_process_resumes_its_part(recipe, tmp_path):
    subprocess.run(_cmd(recipe, tmp_path / "one.h5", "--set", "sectors.count=16"), env=_env(1), check=True, capture_output=True)
    out = tmp_path / "db.h5"
    procs = _launch(recipe, out, _free_port(), "--set", "sectors.count=16", "--block", "2", devices=1)
    mine = parts_dir(out) / part_name(8, 10, 16, 2)  # process 1's first part (sectors 8..15)
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


def test_a_virtual_asset_of_fewer_units_than_one_block(tmp_path):
    """The default block (32) is larger than this 12-sector bake: its one part is the whole block, and the virtual
    asset over it reads as a plain bake (it used to refuse its own part as misnamed)."""
    out = tmp_path / "db.h5"
    rep = bake(SMALL, out, block=32, merge="virtual")
    assert rep["computed"] == 12 and [p.name for p in parts_dir(out).glob("part-*.h5")] == ["part-12x12-0-last.h5"]
    _assert_same_data(bake(SMALL, tmp_path / "ref.h5", block=32)["out"], out)
    assert len(check_virtual(out)) == 1


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
    stray = [tmp_path / ".db.h5.99999.dead.tmp", parts_dir(out) / f".{part_name(0, 4, 12, 4)}.99999.dead.tmp"]
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


# ----------------------------------------------------------------------------- every kind on the one shard path

SH = {"kernel": {"p": 16.0}, "dense": {"t_resolution": 4, "theta_v_steps": 5}}  # 96 tangents
HAIR_BSDF = {"grid": {"resolution": [9, 3, 2]}, "coverage": {"resolution": [2, 3]}}  # 9 sin θ rows


def tiny_scene():
    """A two-cluster procedural groom (76 non-empty sectors of 80) on a tiny trace: a scene_maps bake of seconds."""
    from hairlut.scene import resolve_scene

    from ._synth_fixtures import scene

    s = scene()
    s["strands"] = {**s["strands"], "count": 20}
    s["render"] = {**s["render"], "method": "scene", "views": 8, "terms": 1, "shading_pixels": 8}
    s["tables"] = {"hrir": {"sectors": {"grid": [8, 8]}, "trace": {"pixels": 8, "steps": 12}}}
    return resolve_scene(s)


def split_cases() -> dict:
    """kind → (recipe, options, a recipe change that gives parts of the same shapes and another recipe hash)."""
    from hairlut.planner import scene_maps_recipe

    sc = tiny_scene()
    return {
        "hrir_db": (SMALL, {"block": 4}, {"phong": {"shininess": 5.0}}),
        "sh_tables": (SH, {"block": 40, "light": "sky"}, {"kernel": {"p": 17.0}}),
        "scene_maps": (scene_maps_recipe(sc), {"block": 24, "scene": sc}, {"table": {"lights": 17}}),
        "hair_bsdf": (HAIR_BSDF, {"block": 3}, {"bsdf": {"eta": 1.6}}),
    }


def test_every_kind_bakes_the_same_data_sharded_virtual_and_whole(tmp_path):
    """Every kind in the registry is on the one shard path: a kind that cannot shard fails here."""
    from hairlut.bake import registry

    cases = split_cases()
    assert set(cases) == set(registry.kinds())
    for kind in registry.kinds():
        assert registry.get(kind).units is not None and registry.get(kind).can_shard, f"{kind} cannot shard"
        recipe, options, _ = cases[kind]
        whole = registry.bake(kind, recipe, tmp_path / f"{kind}.h5", options=options)
        assert whole["computed"] == whole["total_units"] > options["block"] and not parts_dir(whole["out"]).exists()
        virtual = registry.bake(kind, recipe, tmp_path / f"{kind}-v.h5", options=options, merge="virtual")
        shards = [
            registry.bake(kind, recipe, tmp_path / f"{kind}-{k}.h5", shard=f"{k}/2", options=options)["out"] for k in range(2)
        ]
        merged = registry.merge(shards[::-1], tmp_path / f"{kind}-m.h5")
        for other in (virtual["out"], merged["out"]):
            _assert_same_data(whole["out"], other)
        assert len(_datasets(whole["out"])) > 8  # every dataset compared, not the first
        assert len(check_virtual(virtual["out"])) == len(list(parts_dir(virtual["out"]).glob("part-*.h5"))) > 1
        registry.get(kind).load(virtual["out"])
        assert not list(tmp_path.glob("*.lock*"))  # the locks go with their holders


def test_sh_dense_tables_do_not_depend_on_blocks_and_match_the_exact_tables(tmp_path):
    import numpy as np

    from hairlut.shtables import bake as bake_sh_asset
    from hairlut.shtables import compute, load_sh_tables

    a = bake_sh_asset(SH, tmp_path / "a.h5", block=7)
    b = bake_sh_asset({**SH, "dense": {**SH["dense"], "storage": "float64"}}, tmp_path / "b.h5", block=96)
    assert a["computed"] == 96 and len(_datasets(a["out"])) == len(_datasets(b["out"]))
    ref = compute(SH)
    t = load_sh_tables(b["out"]).source
    exact = load_sh_tables(b["out"])
    np.testing.assert_array_equal(t["dense/rs"], ref["dense"]["rs"])  # float64 storage: the computed numbers
    np.testing.assert_array_equal(_datasets(a["out"])["dense/rd"], ref["dense"]["rd"].astype(np.float32))
    # an independent evaluation: the tables' own rd/rs at the stored tangents, all at once
    np.testing.assert_allclose(t["dense/rd"], np.asarray(exact.rd(t["dense/t_dirs"])), rtol=0, atol=1e-13)
    np.testing.assert_allclose(
        t["dense/rs"], np.asarray(exact.rs(t["dense/t_dirs"][:, None], t.axes["theta_v"].values[None])), rtol=0, atol=1e-13
    )


def _sh_cmd(out, *extra):
    return [
        sys.executable,
        "-c",
        CODE,
        "bake",
        "sh",
        "--p",
        "16",
        "--set",
        "dense.t_resolution=4",
        "--set",
        "dense.theta_v_steps=5",
        "--light",
        "sky",
        "--block",
        "16",
        "--out",
        str(out),
        "--no-progress",
        *extra,
    ]


@pytest.mark.slow
def test_two_processes_on_loopback_bake_the_sh_tables_of_one(tmp_path):
    subprocess.run(_sh_cmd(tmp_path / "one.h5"), env=_env(1), check=True, capture_output=True)
    out = tmp_path / "sh.h5"
    port = _free_port()
    procs = [
        subprocess.Popen(
            _sh_cmd(
                out,
                "--distributed",
                "--coordinator",
                f"127.0.0.1:{port}",
                "--num-processes",
                "2",
                "--process-id",
                str(k),
                "--json",
            ),
            env=_env(2),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for k in range(2)
    ]
    docs = _finish(procs)
    assert [d["unit_range"] for d in docs] == [[0, 48], [48, 96]] and all(d["computed"] == 48 for d in docs)
    _assert_same_data(tmp_path / "one.h5", out)
    with h5py.File(out, "r") as f:
        assert f["dense/rs"].is_virtual and f["light_group/cs"].is_virtual and not f["gaunt"].is_virtual
    assert len(check_virtual(out)) == 6
    _h5dump_agrees(out, "/dense/rd", "( 96, 9, 9")


def test_inspect_reads_an_own_virtual_asset_and_names_a_missing_or_foreign_part(tmp_path):
    from click.testing import CliRunner

    from hairlut.assets import read_table
    from hairlut.shtables import bake as bake_sh_asset
    from hairlut_cli.main import cli

    out = tmp_path / "sh.h5"
    bake_sh_asset(SH, out, block=40, merge="virtual")
    res = CliRunner().invoke(cli, ["inspect", str(out), "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["kind"] == "sh_tables" and read_table(out, kind="sh_tables")["dense/rs"].shape[0] == 96
    parts = sorted(parts_dir(out).glob("part-*.h5"))
    other = tmp_path / "o.h5"
    bake_sh_asset({**SH, "kernel": {"p": 17.0}}, other, block=40, keep_parts=True)
    saved = parts[1].read_bytes()
    parts[1].write_bytes(sorted(parts_dir(other).glob("part-*.h5"))[1].read_bytes())
    for run_it in (lambda: CliRunner().invoke(cli, ["inspect", str(out)]),):
        res = run_it()
        assert res.exit_code == 2 and str(parts[1]) in res.output and "another recipe" in res.output
        assert len(res.output.strip().splitlines()) == 1
    with pytest.raises(errors.ForeignReferenceError):  # the readers' own rule refuses it too
        read_table(out, kind="sh_tables")
    parts[1].unlink()
    res = CliRunner().invoke(cli, ["inspect", str(out)])
    assert res.exit_code == 2 and str(parts[1]) in res.output and "missing" in res.output
    # a part reached through a symlink, or a source outside the parts folder, is refused as well
    parts[1].symlink_to(parts_dir(other) / parts[1].name)
    with pytest.raises(errors.CorruptAssetError, match="symlink"):
        check_virtual(out)
    parts[1].unlink()
    parts[1].write_bytes(saved)
    assert len(check_virtual(out)) == 3
    outside = tmp_path / "elsewhere.h5"
    with h5py.File(out, "r") as f:
        shape, dtype = f["dense/rd"].shape, f["dense/rd"].dtype
    (tmp_path / "part-copy.h5").write_bytes(saved)
    with h5py.File(outside, "w") as f:
        f.attrs.update({k: v for k, v in h5py.File(out, "r").attrs.items()})
        layout = h5py.VirtualLayout(shape=shape, dtype=dtype)
        layout[40:80] = h5py.VirtualSource("part-copy.h5", "dense/rd", shape=(40, *shape[1:]))
        f.create_virtual_dataset("dense/rd", layout, fillvalue=0)
    with pytest.raises(errors.CorruptAssetError, match="outside the asset's parts folder"):
        check_virtual(outside)
    res = CliRunner().invoke(cli, ["inspect", str(outside)])
    assert res.exit_code == 2 and "outside" in res.output


def test_lock_files_go_and_prune_removes_only_the_unused_ones(tmp_path):
    from hairlut.bake.cache import prune

    bake(SMALL, tmp_path / "db.h5", block=4)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["db.h5"]
    left = [tmp_path / "a.h5.lock", tmp_path / "b.h5.parts.lock", tmp_path / "b.h5.parts.lock.1"]
    for p in left:
        p.write_text("")  # what a killed process leaves
    with locked(tmp_path / "c.h5"):
        held = tmp_path / "c.h5.parts.lock"
        assert held.exists()
        assert set(prune(tmp_path, dry_run=True)) == set(left) and all(p.exists() for p in left)
        assert set(prune(tmp_path)) == set(left) and not any(p.exists() for p in left)
        assert held.exists()  # a bake holds it
    assert not held.exists()


def test_a_part_of_an_older_format_is_baked_again(tmp_path):
    out = tmp_path / "db.h5"
    ref = bake(SMALL, out, block=4, keep_parts=True)
    old = sorted(parts_dir(out).glob("part-*.h5"))[1]
    with h5py.File(old, "r+") as f:
        del f.attrs["storage_max_abs_error_alpha"]  # as parts written before the storage errors were recorded
    first = ref["out"]
    saved = Path(first).read_bytes()
    out.unlink()
    rep = bake(SMALL, out, block=4)
    assert rep["computed"] == 4 and rep["resumed"] == 8
    assert Path(out).read_bytes() == saved
