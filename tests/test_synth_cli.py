"""``hairlut synth``: a scene against a small baked HRIR-DB writes the documented EXR channels and PNGs."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.assets import read_exr
from hairlut_cli.synth import synth_cmd

SCENE = """
[render]
resolution = [12, 8]
preview_size = 32
[camera]
view = [0.0, 0.0, 1.0]
[lights]
directions = [[0.3, 0.6, 1.0]]
[material]
k_threshold = inf
[shadows]
method = "smap"
[strands]
count = 40
radius = 0.006
[[clusters]]
trajectory = [[0.0, 1.0, 0.0], [0.05, 0.5, 0.1], [0.1, 0.0, 0.1]]
half_axis_a = 0.08
half_axis_b = 0.06
layer_radii = [0.6, 1.0]
core_radius = 0.2
s_t = 4
s_u = 4
"""


@pytest.fixture(scope="session")
def small_db(tmp_path_factory):
    from hairlut.hrir import bake

    out = tmp_path_factory.mktemp("synthdb") / "db.h5"
    bake(
        {
            "sectors": {"count": 16, "grid": [8, 8]},
            "angles": {"views": 4, "lights": 4},
            "trace": {"pixels": 8, "steps": 8, "self_shadow": False},
        },
        out,
    )
    return out


def test_cli_writes_exr_channels_and_png(tmp_path, small_db):
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    out = tmp_path / "out"
    r = CliRunner().invoke(synth_cmd, [str(scene), "--db", str(small_db), "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output + repr(r.exception)
    report = json.loads(r.output)
    assert report["clusters"] == 1 and len(report["exr"]) == 1
    img = read_exr(out / "cluster000.exr", kind="synth_maps")
    names = set(img.part().channels)
    want = {f"layer{k}.{c}" for k in range(2) for c in ("re", "A", "s", "R", "G", "B")} | set("RGBA")
    assert want <= names
    a = img.channel("A")
    assert a.shape == (8, 12) and np.all((a >= 0) & (a <= 1))
    for k in range(2):
        alpha = img.channel(f"layer{k}.A")
        assert np.all((alpha >= 0) & (alpha <= 1))
    np.testing.assert_allclose(img.channel("layer1.s"), 1.0)  # nothing is outside the outer layer
    for png in ("cluster000.png", "preview.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_rejects_bad_scene(tmp_path, small_db):
    scene = tmp_path / "bad.toml"
    scene.write_text(SCENE.replace("[material]", "[material]\nks_III = 0.2"))
    r = CliRunner().invoke(synth_cmd, [str(scene), "--db", str(small_db), "--out", str(tmp_path / "o")])
    assert isinstance(r.exception, errors.ValidationError) and r.exception.field == "material.ks_III"


def test_write_outputs_two_lights(tmp_path):
    from hairlut.synth import synthesize, write_outputs

    from ._synth_fixtures import scene, synthetic_db

    files = write_outputs(synthesize(scene(), synthetic_db()), tmp_path)
    assert len(files["exr"]) == 2 and len(files["png"]) == 2
    img = read_exr(files["exr"][1], kind="synth_maps")
    assert {"layer0.re", "layer0.re_l1", "layer1.re_l1"} <= set(img.part().channels)
    assert "hairlut:recipe" in img.part().header or img.recipe is not None
