"""`hairlut bake sh` and `hairlut sh project` end to end."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut.assets import read_exr, read_table, write_exr
from hairlut.demo import sky
from hairlut.shtables import SHTables
from hairlut_cli.main import cli


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_layout_choices_are_envlights():
    from hairlut.envlight import LAYOUTS
    from hairlut_cli import sh

    assert sh.LAYOUTS == LAYOUTS


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    path = tmp_path_factory.mktemp("env") / "sky.exr"
    write_exr(path, sky(32))
    return path


def test_project_prints_and_writes(tmp_path, env):
    res = run("sh", "project", env, "--bands", "3", "--out", tmp_path / "l.h5", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["layout"] == "latlong" and len(doc["coeffs"]) == 9 and set(doc["band_error"]) == {"R", "G", "B"}
    assert np.allclose(read_table(tmp_path / "l.h5", kind="sh_light")["a"], doc["coeffs"])
    text = run("sh", "project", env, "--bands", "2").output
    assert "band-limiting error" in text and "4 coefficients" in text


def test_bake_with_recipe_overrides_light_and_textures(tmp_path, env):
    recipe = tmp_path / "r.toml"
    recipe.write_text("[kernel]\np = 16.0\n[dense]\nt_resolution = 4\ntheta_v_steps = 5\n")
    res = run(
        "bake",
        "sh",
        "--recipe",
        recipe,
        "--out",
        tmp_path / "sh.h5",
        "--set",
        "bands.transmittance=2",
        "--light",
        env,
        "--textures",
        tmp_path / "tex.exr",
        "--json",
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    assert doc["recipe"]["kernel"]["p"] == 16.0 and doc["recipe"]["bands"]["transmittance"] == 2
    assert doc["recipe"]["bands"]["light_specular"] == 5  # ceil(√16) + 1
    t = read_table(tmp_path / "sh.h5", kind="sh_tables")
    assert t["dense/rs"].shape == (6 * 16, 5, 25, 4) and t["light/cs"].shape == (6 * 16, 5, 4, 3)
    tex = read_exr(tmp_path / "tex.exr", kind="sh_textures")
    assert tex.part("cd").shape == (4, 24) and tex.part("cs").shape == (20, 24)
    # the texture holds Cd: texel (face +x, row 0, col 0) is t_dirs[0]
    tables = SHTables.load(tmp_path / "sh.h5")
    a = t["light/a"]
    cd = np.asarray(tables.contract(a).cd(t["dense/t_dirs"][0]))
    assert tex.channel("j0.R", part="cd")[0, 0] == pytest.approx(cd[0, 0], rel=1e-6)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--set", "kernel.p=-1"], "kernel.p=-1: the specular exponent p must be finite and > 0"),
        (["--set", "bands.nonsense=3"], "bands.nonsense"),
        (["--recipe", "missing.toml"], "no such recipe file"),
        (["--textures", "x.exr"], "textures"),
    ],
)
def test_bad_bakes_are_one_line(tmp_path, args, message):
    res = CliRunner().invoke(cli, ["bake", "sh", "--out", str(tmp_path / "x.h5"), *args])
    assert res.exit_code == 2
    assert message in res.output and len(res.output.strip().splitlines()) == 1
    assert not (tmp_path / "x.h5").exists()
