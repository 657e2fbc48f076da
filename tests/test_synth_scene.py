"""Scene files: defaults, the shipped examples, and bad keys rejected with their key path."""

import copy
from pathlib import Path

import pytest

from hairlut import errors
from hairlut.scene import load_scene, resolve_scene

from ._synth_fixtures import scene

ROOT = Path(__file__).resolve().parents[1]


def test_defaults_and_normalised_directions():
    sc = resolve_scene(scene())
    assert sc.material["p_I"] == 80.0 and sc.effects["shadow"] is True
    assert abs(float((sc.view**2).sum()) - 1) < 1e-12 and sc.lights.shape == (2, 3)
    assert len(sc.specs) == 2 and sc.cluster_seeds[0] != sc.cluster_seeds[1]


def _bad(mutate):
    given = copy.deepcopy(scene())
    mutate(given)
    with pytest.raises(errors.ValidationError) as exc:
        resolve_scene(given)
    return exc.value.field


@pytest.mark.parametrize(
    "mutate, field",
    [
        (lambda g: g["material"].update(foo=1), "material.foo"),
        (lambda g: g.update(camera_typo={}), "camera_typo"),
        (lambda g: g["camera"].pop("view"), "camera.view"),
        (lambda g: g.pop("lights"), "lights.directions"),
        (lambda g: g["material"].update(kd=-0.1), "material.kd"),
        (lambda g: g["material"].update(p_I=0.0), "material.p_I"),
        (lambda g: g["material"].update(shadow_form="cubic"), "material.shadow_form"),
        (lambda g: g["material"].update(hair_color=[1.2, 0, 0]), "material.hair_color"),
        (lambda g: g["render"].update(resolution=[1, 8]), "render.resolution"),
        (lambda g: g["lights"].update(directions=[[0, 0, 0]]), "lights.directions[0]"),
        (lambda g: g["effects"].update(shadow="yes"), "effects.shadow"),
        (lambda g: g["clusters"][1].pop("trajectory"), "clusters[1].trajectory"),
        (lambda g: g["clusters"][1].update(layer_radii=[0.9, 0.5]), "clusters[1].layer_radii"),
        (lambda g: g["clusters"][0].update(s_v=2), "clusters[0].s_v"),
        (lambda g: g["clusters"][0].update(colour=1), "clusters[0].colour"),
        (lambda g: g["clusters"][1].update(s_t=5), "clusters[1]"),
        (lambda g: g.update(groom={"path": "x.tfx"}), "clusters"),
    ],
)
def test_bad_keys_name_their_path(mutate, field):
    assert _bad(mutate) == field


def test_missing_groom_file_is_an_asset_error(tmp_path):
    given = scene()
    given.pop("clusters")
    given["groom"] = {"path": "nowhere/none.tfx"}
    with pytest.raises(errors.AssetNotFoundError):
        resolve_scene(given, tmp_path)


def test_example_scenes_parse():
    sc = load_scene(ROOT / "tables/scenes/two-clusters.toml")
    assert len(sc.specs) == 2
    sg = load_scene(ROOT / "tables/scenes/sintel-groom.toml")  # the groom is in the repository: no skip
    assert sg.groom_path.resolve() == ROOT / "tables/grooms/sintel_lite.tfx" and sg.config["groom"]["clusters"] == "auto"
    rb = load_scene(ROOT / "tables/scenes/ratboy-groom.toml")
    assert rb.groom_path.resolve() == ROOT / "tables/grooms/ratboy_mohawk.tfx"
