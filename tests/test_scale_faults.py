"""Faults on the one shard path, for every kind in the registry: an interrupted or killed bake resumes to the
data of an uninterrupted one; a virtual asset's missing or foreign part is an error that names the part."""

import os
import signal
import subprocess
import sys

import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.assets.parts import parts_dir
from hairlut.bake import registry
from hairlut.bake.cache import is_valid
from hairlut_cli.main import cli

from .test_distributed_bake import _assert_same_data, split_cases

KINDS = ["hair_bsdf", "hrir_db", "scene_maps", "sh_tables"]


@pytest.fixture(scope="module")
def cases():
    return split_cases()


def test_these_cases_cover_every_kind():
    assert sorted(KINDS) == sorted(registry.kinds())


def _merged(recipe: dict, change: dict) -> dict:
    out = {**recipe}
    for k, v in change.items():
        out[k] = _merged(out.get(k, {}), v) if isinstance(v, dict) else v
    return out


def _parts(out) -> list:
    return sorted(parts_dir(out).glob("part-*.h5"))


@pytest.mark.parametrize("kind", KINDS)
def test_a_missing_or_foreign_part_is_an_error_naming_it(kind, cases, tmp_path):
    recipe, options, change = cases[kind]
    out = tmp_path / "v.h5"
    rep = registry.bake(kind, recipe, out, options=options, merge="virtual")
    parts = _parts(out)
    assert len(parts) >= 3
    registry.bake(kind, _merged(recipe, change), tmp_path / "o.h5", options={**options, "keep_parts": True})
    foreign = _parts(tmp_path / "o.h5")[1]
    load = registry.get(kind).load
    saved = parts[1].read_bytes()
    parts[1].write_bytes(foreign.read_bytes())  # same shapes, another recipe
    with pytest.raises(errors.CorruptAssetError) as exc:
        load(out)
    assert exc.value.path == str(parts[1]) and "another recipe" in str(exc.value)
    res = CliRunner().invoke(cli, ["inspect", str(out)])
    assert res.exit_code == 2 and str(parts[1]) in res.output and "another recipe" in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert not is_valid(out, kind, rep["recipe_hash"])  # the cache would bake it again
    parts[1].unlink()
    with pytest.raises(errors.AssetNotFoundError) as exc:
        load(out)
    assert exc.value.path == str(parts[1]) and "missing" in str(exc.value)
    res = CliRunner().invoke(cli, ["inspect", str(out)])
    assert res.exit_code == 2 and str(parts[1]) in res.output and "missing" in res.output
    parts[1].write_bytes(saved)
    load(out)
    assert is_valid(out, kind, rep["recipe_hash"])


class Interrupted(Exception):
    pass


@pytest.mark.parametrize("kind", KINDS)
def test_an_interrupted_bake_resumes_to_the_same_data(kind, cases, tmp_path):
    recipe, options, _ = cases[kind]
    ref = registry.bake(kind, recipe, tmp_path / "ref.h5", options=options)
    out = tmp_path / "db.h5"

    def stop(done, total):
        if done >= 2 * options["block"]:
            raise Interrupted

    with pytest.raises(Interrupted):
        registry.bake(kind, recipe, out, options=options, progress=stop)
    assert not out.exists() and len(_parts(out)) == 2
    rep = registry.bake(kind, recipe, out, options=options)
    assert rep["resumed"] == 2 * options["block"] and rep["computed"] == ref["computed"] - rep["resumed"]
    _assert_same_data(ref["out"], out)


KILL = """
import os, signal, sys
from hairlut.bake import registry
from tests.test_distributed_bake import split_cases

kind, out = sys.argv[1], sys.argv[2]
recipe, options, _ = split_cases()[kind]

def die(done, total):
    if done >= 2 * options["block"]:
        os.kill(os.getpid(), signal.SIGKILL)

registry.bake(kind, recipe, out, options=options, progress=die)
"""


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_a_killed_bake_resumes_to_the_same_data(kind, cases, tmp_path):
    recipe, options, _ = cases[kind]
    out = tmp_path / "db.h5"
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    run = subprocess.run(
        [sys.executable, "-c", KILL, kind, str(out)],
        cwd=root,
        capture_output=True,
        text=True,
        env={**os.environ, "JAX_PLATFORMS": "cpu"},
        timeout=600,
    )
    assert run.returncode == -signal.SIGKILL, run.stderr[-2000:]
    assert not out.exists() and len(_parts(out)) == 2
    rep = registry.bake(kind, recipe, out, options=options)
    ref = registry.bake(kind, recipe, tmp_path / "ref.h5", options=options)
    assert rep["resumed"] == 2 * options["block"] and rep["computed"] == ref["computed"] - rep["resumed"]
    _assert_same_data(ref["out"], out)
