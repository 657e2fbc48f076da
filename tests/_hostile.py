"""Shared pieces of the hostile-file tests (``test_hostile_files``, ``test_hostile_bitflips``): small real
tables written by hairlut, and the edits and CLI check the cases use."""

import h5py
import pytest
from click.testing import CliRunner

from hairlut.assets import recipe_hash
from hairlut.hrir import bake as bake_hrir
from hairlut.shtables import bake_sh, write_sh_tables
from hairlut_cli.main import cli

SMALL_HRIR = {"sectors": {"count": 6, "grid": [8, 8]}, "angles": {"views": 4, "lights": 3}, "trace": {"pixels": 8, "steps": 12}}


@pytest.fixture(scope="module")
def sh_file(tmp_path_factory):
    res = bake_sh({"kernel": {"p": 9.0}, "bands": {"light_diffuse": 2, "transmittance": 2}})
    return write_sh_tables(tmp_path_factory.mktemp("sh") / "sh.h5", res["tables"], res["info"])


@pytest.fixture(scope="module")
def hrir_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("hrir") / "db.h5"
    bake_hrir(SMALL_HRIR, out, block=6)
    return out


def copy(src, dst):
    dst.write_bytes(open(src, "rb").read())
    return dst


def poke(path, fn):
    with h5py.File(path, "r+") as f:
        fn(f)
    return path


def set_recipe(f, recipe_text):
    """Replace the stored recipe and make its hash consistent (the checksum passes)."""
    f.attrs["recipe"] = recipe_text
    f.attrs["recipe_hash"] = recipe_hash(recipe_text)


def cli_fails(*args):
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("hairlut: error:"), res.output
    assert res.exception is None or isinstance(res.exception, SystemExit)
    return lines[0]
