"""The HRIR-DB baker: recipe validation, the asset, resume after interruption, shards and merge."""

import hashlib
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.assets import read_exr, read_table
from hairlut.assets.parts import parts_dir
from hairlut.bake.registry import merge
from hairlut.hrir import bake, export_slice, load_hrir_db, resolve_recipe, sector_seed

SMALL = {"sectors": {"count": 10, "grid": [8, 8]}, "angles": {"views": 4, "lights": 3}, "trace": {"pixels": 8, "steps": 12}}


def _sha(path) -> str:
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


@pytest.mark.parametrize(
    "given, field",
    [
        ({"trace": {"stepz": 4}}, "trace.stepz"),
        ({"trace": {"steps": 1}}, "trace.steps"),
        ({"trace": {"self_shadow": "yes"}}, "trace.self_shadow"),
        ({"angles": {"views": True}}, "angles.views"),
        ({"phong": {"shininess": -1.0}}, "phong.shininess"),
        ({"sectors": {"grid": [8]}}, "sectors.grid"),
        ({"sectors": {"space": {"aspect": [0.5, 2.0]}}}, "sectors.space.aspect"),
        ({"sectors": {"space": {"radius_rel": [0.1, 0.01]}}}, "sectors.space.radius_rel"),
        ({"storage": {"dtype": "int8"}}, "storage.dtype"),
        ({"sectors": 3}, "sectors"),
    ],
)
def test_bad_recipes_name_the_key(given, field):
    with pytest.raises(errors.ValidationError) as exc:
        resolve_recipe(given)
    assert exc.value.field == field


def test_sector_seeds_depend_on_index_only():
    seeds = [sector_seed(7, i) for i in range(100)]
    assert len(set(seeds)) == 100 and all(0 <= s < 2**63 for s in seeds)
    assert sector_seed(7, 3) == sector_seed(7, 3) != sector_seed(8, 3)


def test_asset_layout_float16_and_exr_slice(tmp_path):
    out = tmp_path / "db.h5"
    rep = bake({**SMALL, "storage": {"dtype": "float16"}}, out, block=4)
    assert rep["computed"] == 10 and not parts_dir(out).exists()
    t = read_table(out, kind="hrir_db")
    assert t["alpha"].dtype == np.float16 and t["reflectance"].shape == (10, 4, 3, 8)
    assert t.variables["reflectance"].chunks == (1, 4, 3, 8)
    assert t.axes["theta_v"].period == pytest.approx(2 * np.pi) and t.axes["theta_l"].periodic
    err = float(t.attrs["storage_max_abs_error_reflectance"])
    ref = bake(SMALL, tmp_path / "f32.h5", block=4)
    full = load_hrir_db(ref["out"])
    assert float(read_table(ref["out"]).attrs["storage_max_abs_error_alpha"]) == 0.0
    measured = np.abs(t["reflectance"].astype(np.float64) - full.reflectance).max()
    assert measured == pytest.approx(err, rel=1e-6) and 0 < err < 1e-3
    db = load_hrir_db(out)
    assert db.features.shape == (10, 3) and np.allclose(db.stats.normalize(db.features).mean(0), 0, atol=1e-9)
    assert json.loads(t.attrs["feature_names"]) == ["rho_st", "rho_s", "rho_t"]
    exr = export_slice(ref["out"], tmp_path / "s.exr", 2, 1)
    img = read_exr(exr).part()
    assert set(img.channels) == {"Y", "A"} and img.channels["Y"].shape == (4, 8)
    np.testing.assert_array_equal(img.channels["Y"], full.reflectance[2, :, 1, :])
    with pytest.raises(errors.ValidationError):
        export_slice(ref["out"], tmp_path / "bad.exr", 10, 0)


def test_shards_merge_to_the_one_shot_bake(tmp_path):
    one = bake(SMALL, tmp_path / "one.h5", block=3)
    shards = [bake(SMALL, tmp_path / f"s{k}.h5", block=3, shard=f"{k}/3")["out"] for k in range(3)]
    assert [read_table(s).attrs["sector_start"] for s in shards] == [0, 3, 6]
    merged = merge(shards[::-1], tmp_path / "merged.h5")
    assert merged["units"] == 10
    assert _sha(one["out"]) == _sha(merged["out"])
    with pytest.raises(errors.AssetError):
        merge(shards[:1] + shards[2:], tmp_path / "gap.h5")
    with pytest.raises(errors.ValidationError):
        merge(shards[:2], tmp_path / "short.h5")
    with pytest.raises(errors.ValidationError):
        bake(SMALL, tmp_path / "x.h5", shard="3/3")


def test_interrupted_bake_resumes_to_identical_bytes(tmp_path):
    ref = bake(SMALL, tmp_path / "ref.h5", block=5)  # the block size does not change the bytes either
    out = tmp_path / "db.h5"

    class Stop(Exception):
        pass

    def die(done, total):
        if done >= 6:
            raise Stop

    with pytest.raises(Stop):
        bake(SMALL, out, block=3, progress=die)
    assert not out.exists() and len(list(parts_dir(out).glob("part-*.h5"))) == 2
    seen = []
    rep = bake(SMALL, out, block=3, progress=lambda d, t: seen.append((d, t)))
    assert rep["resumed"] == 6 and rep["computed"] == 4 and seen[-1] == (10, 10)
    assert seen[0] == (6, 10) and all(d > 6 for d, _ in seen[1:])  # the resumed sectors once, before any work
    assert _sha(ref["out"]) == _sha(out)


def test_stale_or_damaged_parts_are_baked_again(tmp_path):
    out = tmp_path / "db.h5"
    bake(SMALL, out, block=5, keep_parts=True)
    parts = sorted(parts_dir(out).glob("part-*.h5"))
    parts[0].write_bytes(parts[0].read_bytes()[:200])  # truncated by a crash of the disk
    rep = bake(SMALL, out, block=5)
    assert rep["resumed"] == 5 and rep["computed"] == 5
    other = {**SMALL, "phong": {"shininess": 5.0}}
    bake(other, tmp_path / "o.h5", block=5, keep_parts=True)
    os.replace(tmp_path / "o.h5.parts", parts_dir(out))
    assert bake(SMALL, out, block=5)["computed"] == 10  # parts of another recipe are not reused


def test_cli_bake_merge_and_progress(tmp_path):
    from hairlut_cli.hrir import hrir_cmd, hrir_slice_cmd, merge_cmd

    recipe = tmp_path / "r.toml"
    recipe.write_text("[sectors]\ncount = 6\ngrid = [8, 8]\n[angles]\nviews = 4\nlights = 2\n[trace]\npixels = 8\nsteps = 8\n")
    runner = CliRunner()
    res = runner.invoke(hrir_cmd, ["--recipe", str(recipe), "--out", str(tmp_path / "a.h5"), "--block", "2", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["computed"] == 6
    assert "6/6 sectors" in res.stderr and "ETA" in res.stderr
    for k in range(2):
        res = runner.invoke(
            hrir_cmd,
            ["--recipe", str(recipe), "--out", str(tmp_path / f"s{k}.h5"), "--shard", f"{k}/2", "--block", "2", "--no-progress"],
        )
        assert res.exit_code == 0, res.output
    res = runner.invoke(merge_cmd, [str(tmp_path / "s0.h5"), str(tmp_path / "s1.h5"), "--out", str(tmp_path / "m.h5")])
    assert res.exit_code == 0, res.output
    assert _sha(tmp_path / "a.h5") == _sha(tmp_path / "m.h5")
    res = runner.invoke(
        hrir_slice_cmd, [str(tmp_path / "m.h5"), "--sector", "1", "--light", "0", "--out", str(tmp_path / "x.exr")]
    )
    assert res.exit_code == 0 and (tmp_path / "x.exr").exists()
    res = runner.invoke(hrir_cmd, ["--out", str(tmp_path / "b.h5"), "--set", "trace.steps=0"])
    assert res.exit_code != 0 and isinstance(res.exception, errors.ValidationError)


@pytest.mark.slow
def test_sigkill_and_rerun_gives_identical_bytes(tmp_path):
    """A real process killed with SIGKILL mid-bake; the same command finishes the job."""
    recipe = tmp_path / "r.toml"
    recipe.write_text(
        "[sectors]\ncount = 48\ngrid = [16, 16]\n[angles]\nviews = 16\nlights = 16\n[trace]\npixels = 32\nsteps = 48\n"
    )
    code = "import sys; from hairlut_cli.hrir import hrir_cmd; hrir_cmd(sys.argv[1:])"
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}

    def cmd(out):
        return [sys.executable, "-c", code, "--recipe", str(recipe), "--out", str(out), "--block", "4", "--no-progress"]

    subprocess.run(cmd(tmp_path / "ref.h5"), check=True, env=env, capture_output=True)
    out = tmp_path / "db.h5"
    proc = subprocess.Popen(cmd(out), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and len(list(parts_dir(out).glob("part-*.h5"))) < 2:
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    done = len(list(parts_dir(out).glob("part-*.h5")))
    assert 2 <= done < 12 and not out.exists()
    res = subprocess.run(cmd(out) + ["--json"], check=True, env=env, capture_output=True, text=True)
    report = json.loads(res.stdout)
    assert report["resumed"] >= 8 and report["computed"] > 0
    assert _sha(tmp_path / "ref.h5") == _sha(out)
