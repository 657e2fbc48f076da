"""The environment term of the online module: analytic values, self-shadowing, cache lookup, errors."""

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.assets import read_exr, write_exr
from hairlut.planner import bake, find_assets, plan
from hairlut.scene import resolve_scene
from hairlut.synth import prepare, render_view, synthesize
from hairlut_cli.main import cli
from tests.test_plan import TINY_HRIR, _write_toml, scene


@pytest.fixture(scope="module")
def white_sky(tmp_path_factory):
    """A constant, white lat-long environment: a_0 = √(4π); the texel-centre projection leaves the
    other coefficients at ~1e-5 (the midpoint rule in θ), hence rtol 1e-4 below."""
    path = tmp_path_factory.mktemp("env") / "white.exr"
    write_exr(path, {c: np.ones((64, 128), np.float32) for c in "RGB"})
    return path


def _baked(mapping, root):
    p = plan(mapping, root)
    bake(p)
    return find_assets(mapping, root)


def test_constant_light_diffuse_is_pi_squared(tmp_path, white_sky):
    """∫ sin∠(t, ω) dω = π² over the sphere: with T = 1 and no specular, E = kd · f_dif · π²."""
    s = scene({"map": str(white_sky)}, ks_I=0.0, ks_II=0.0, kd=0.4)
    assets = _baked(s, tmp_path)
    prep = prepare(s, assets["hrir_db"], assets["sh_tables"])
    env = prep.environment
    e, clamped = env.rgb(resolve_scene(s).view)
    hair = np.asarray(resolve_scene(s).material["hair_color"])
    np.testing.assert_allclose(e, np.broadcast_to(0.4 * hair * np.pi**2, e.shape), rtol=1e-4)
    assert clamped == 0.0


def test_environment_adds_before_blending(tmp_path, white_sky):
    s = scene({"map": str(white_sky)}, ks_I=0.0, ks_II=0.0)
    assets = _baked(s, tmp_path)
    lit = render_view(prepare(s, assets["hrir_db"], assets["sh_tables"]))
    dark = render_view(prepare(scene(None, ks_I=0.0, ks_II=0.0), assets["hrir_db"]))
    hair = np.asarray(resolve_scene(s).material["hair_color"])
    for a, b in zip(lit.clusters, dark.clusters):
        np.testing.assert_allclose(a.alpha, b.alpha)
        extra = 0.5 * hair * np.pi**2  # per layer, eq 13 + E, then eq 14 with the same α
        np.testing.assert_allclose(a.rgba[..., :3], b.rgba[..., :3] + extra, rtol=1e-4, atol=1e-5)
        assert np.all(a.final[..., :3] >= b.final[..., :3] - 1e-6)


def test_self_shadowing_darkens(tmp_path):
    s_open = scene({"map": "sky"})
    s_shadow = scene({"map": "sky", "self_shadow": True, "voxels": 16})
    assets = _baked(s_open, tmp_path)
    e_open, _ = prepare(s_open, assets["hrir_db"], assets["sh_tables"]).environment.rgb([0, 0.2, 1.0])
    env = prepare(s_shadow, assets["hrir_db"], assets["sh_tables"]).environment
    assert env.self_shadow and np.all(env.b[..., 0] <= np.sqrt(4 * np.pi) + 1e-9)
    e_shadow, _ = env.rgb([0, 0.2, 1.0])
    assert e_shadow.mean() < e_open.mean()


def test_environment_needs_its_tables(tmp_path):
    s = scene({"map": "sky"})
    assets = _baked(scene(None), tmp_path)
    with pytest.raises(errors.ValidationError) as exc:
        synthesize(s, assets["hrir_db"])
    assert exc.value.field == "sh"


def test_synth_cli_finds_assets_in_cache(tmp_path):
    path = _write_toml(tmp_path / "scene.toml", scene({"map": "sky"}))
    cache = str(tmp_path / "cache")
    run = CliRunner().invoke(cli, ["synth", str(path), "--cache", cache, "--out", str(tmp_path / "o")])
    assert run.exit_code == 2 and "hairlut bake --scene" in run.output
    assert CliRunner().invoke(cli, ["bake", "--scene", str(path), "--cache", cache, "--no-progress"]).exit_code == 0
    run = CliRunner().invoke(cli, ["synth", str(path), "--cache", cache, "--out", str(tmp_path / "o")])
    assert run.exit_code == 0, run.output
    img = read_exr(tmp_path / "o" / "cluster000.exr")
    assert "layer1.R" in img.parts[0].channels


def test_demo_cold_then_warm(tmp_path):
    path = _write_toml(tmp_path / "scene.toml", scene({"map": "sky"}) | {"tables": {"hrir": TINY_HRIR}})
    args = [
        "demo",
        "--scene",
        str(path),
        "--cache",
        str(tmp_path / "cache"),
        "--out",
        str(tmp_path / "d"),
        "--no-progress",
        "--json",
    ]
    import json

    cold = json.loads(CliRunner().invoke(cli, args).output)
    warm = json.loads(CliRunner().invoke(cli, args).output)
    (c,), (w,) = cold["scenes"], warm["scenes"]
    assert {a["status"] for a in c["assets"].values()} == {"baked"}
    assert {a["status"] for a in w["assets"].values()} == {"reused"}
    assert c["accuracy"]["hrir_query_self_check"] < 1e-5 and c["accuracy"]["chebyshev_tail"] < 1e-12
    assert 0 <= w["accuracy"]["environment_clamped_fraction"] < 0.5
    assert (tmp_path / "d" / "scene" / "preview.png").is_file() and (tmp_path / "d" / "sky.exr").is_file()


def test_self_shadowed_term_is_the_quadrature_of_its_own_light(tmp_path):
    """The self-shadowed sky through the contracted tables equals the brute-force quadrature
    (hairlut.envlight.hair_radiance) of the same light bands and transmittance, b₀ (√4π × the mean
    visibility) is never negative (eq 7 sampled at every voxel), and nothing is clamped."""
    from hairlut.planner import environment_light

    s = scene({"map": "sky", "self_shadow": True, "voxels": 16})
    assets = _baked(s, tmp_path)
    env = prepare(s, assets["hrir_db"], assets["sh_tables"]).environment
    view = resolve_scene(s).view
    assert env.b[..., 0].min() > 0.0
    e, clamped = env.rgb(view)
    assert clamped == 0.0
    a = environment_light(resolve_scene(s)).coeffs
    assert env.light_diffuse**2 == len(a)  # Rd reads the light's chosen bands
    ref = env.reference(a, view, height=96)
    assert np.sqrt(np.mean((e - ref) ** 2) / np.mean(ref**2)) < 1e-3
