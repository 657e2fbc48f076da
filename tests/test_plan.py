"""The scene planner: one test per rule, reuse through the cache, re-bakes, bad scenes, the CLI."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.bake.cache import entries
from hairlut.planner import bake, find_assets, plan
from hairlut.scene import grid_coverage, resolve_scene, scene_sectors
from hairlut.shtables import band_truncation_error, specular_band_rule
from hairlut_cli.main import cli
from tests._synth_fixtures import scene as base_scene

TINY_HRIR = {
    "sectors": {"count": 12, "grid": [8, 8]},
    "angles": {"views": 4, "lights": 4},
    "trace": {"pixels": 8, "steps": 8, "self_shadow": False},
}


def scene(env=None, tables=None, **material):
    """A tiny scene whose maps come from the SATF (``render.method = "satf"``: these tests are about the
    hrir_db rules; the map methods' own rules are in test_map_methods.py)."""
    s = base_scene(**material)
    s["render"] = {**s.get("render", {}), "method": "satf"}
    s["tables"] = {"hrir": TINY_HRIR, **(tables or {})}
    if env is not None:
        s["environment"] = env
    return s


def actions(p):
    return {s.name: s.action for s in p.steps}


def test_no_environment_light_no_sh_tables(tmp_path):
    p = plan(scene(), tmp_path)
    sh = p.step("sh_tables")
    assert sh.action == "skip" and "no environment light" in sh.reason
    assert actions(p)["transmittance"] == "skip" and actions(p)["hrir_db"] == "bake"


def test_zero_ks_bakes_no_rs_and_zero_kd_no_rd(tmp_path):
    p = plan(scene({"map": "sky"}, ks_I=0.0, ks_II=0.0), tmp_path)
    sh = p.step("sh_tables")
    assert sh.action == "bake" and sh.recipe["kernel"]["specular"] is False and "no Rs" in sh.reason
    p = plan(scene({"map": "sky"}, kd=0.0), tmp_path)
    assert p.step("sh_tables").recipe["kernel"]["diffuse"] is False and "no Rd" in p.step("sh_tables").reason
    p = plan(scene({"map": "sky"}, kd=0.0, ks_I=0.0, ks_II=0.0), tmp_path)
    assert p.step("sh_tables").action == "skip"


@pytest.mark.parametrize("p_exp", [9.0, 49.0, 100.0])
def test_exponent_sets_light_bands_and_reports_truncation(tmp_path, p_exp):
    from hairlut.planner import environment_bands

    p = plan(scene({"map": "sky"}, p_I=p_exp), tmp_path)
    sh = p.step("sh_tables")
    bands = sh.recipe["bands"]["light_specular"]
    eb = sh.details["environment_bands"]
    assert eb == environment_bands(p.scene) and bands == eb["bands"] and eb["rule"] == specular_band_rule(p_exp)
    assert eb["error"] <= 0.015 < eb["rule_error"] or bands <= eb["rule"]  # auto meets the default tolerance
    tighter = plan(scene({"map": "sky", "tolerance": eb["error"] * 0.5}, p_I=p_exp), tmp_path).step("sh_tables")
    assert tighter.recipe["bands"]["light_specular"] > bands  # a tighter tolerance needs more bands
    err = sh.details["specular_truncation_error"]
    assert err == pytest.approx(band_truncation_error(p_exp, bands)) and 0 <= err < 1
    assert f"{bands} light bands" in sh.reason and f"{100 * eb['error']:.1f} %" in sh.reason
    wider = plan(scene({"map": "sky", "bands": bands + 4}, p_I=p_exp), tmp_path).step("sh_tables")
    assert wider.details["specular_truncation_error"] < err  # more bands keep more of the lobe
    assert wider.details["environment_bands"]["error"] < eb["error"]  # and more of the radiance


def test_angle_coverage():
    assert grid_coverage(np.array([0.1]), 8) == pytest.approx(2 / 8)  # one cell: its two nodes
    assert grid_coverage(np.array([2 * np.pi - 0.01]), 8) == pytest.approx(2 / 8)  # wraps to node 0
    assert grid_coverage(np.linspace(0, 2 * np.pi, 100, endpoint=False), 8) == 1.0


def test_sector_space_fits_the_scene(tmp_path):
    sc = resolve_scene(scene())
    ss = scene_sectors(sc)
    space = plan(sc, tmp_path).step("hrir_db").recipe["sectors"]["space"]
    assert space["s_u"] == [4, 4]
    for key, values in (
        ("aspect", ss.aspect),
        ("v_inner", ss.v_range[:, 0]),
        ("radial_extent", ss.v_range[:, 1] - ss.v_range[:, 0]),
        ("strands", ss.strands),
        ("radius_rel", ss.radius_rel[np.isfinite(ss.radius_rel)]),
    ):
        lo, hi = space[key]
        assert lo <= values.min() and values.max() <= hi, key
    unrestricted = plan(scene(tables={"restrict": False}), tmp_path).step("hrir_db").recipe["sectors"]["space"]
    assert (
        unrestricted["s_u"] == [4, 32] and "as given" in plan(scene(tables={"restrict": False}), tmp_path).step("hrir_db").reason
    )


def test_transmittance_only_with_environment_and_self_shadow(tmp_path):
    assert plan(scene(), tmp_path).step("transmittance").action == "skip"
    assert plan(scene({"map": "sky"}), tmp_path).step("transmittance").action == "skip"
    t = plan(scene({"map": "sky", "self_shadow": True, "voxels": 16}), tmp_path).step("transmittance")
    assert t.action == "run" and t.details["voxels"] == 16


def test_switched_off_terms_do_no_online_work(tmp_path):
    a = actions(plan(scene(ks_II=0.0), tmp_path))
    assert a["secondary"] == "skip" and "noise" not in a and a["primary"] == "run"
    sc = resolve_scene(scene(ks_II=0.0))
    assert sc.effects["secondary"] is False and sc.effects["noise"] is False
    s = base_scene()
    s["effects"] = {"secondary": False, "shadow": False}
    a = actions(plan(s | {"tables": {"hrir": TINY_HRIR}}, tmp_path))
    assert a["secondary"] == "skip" and a["s_map"] == "skip"
    assert actions(plan(scene(k_shadow=0.0), tmp_path))["s_map"] == "skip"
    assert "two HRIRs" in plan(scene(k_threshold=0.0), tmp_path).step("uniformity").reason


def test_bake_then_nothing_new_and_one_parameter_change(tmp_path):
    sky = {"map": "sky"}
    p = plan(scene(sky, p_I=9.0), tmp_path)
    assert actions(p)["hrir_db"] == actions(p)["sh_tables"] == "bake"
    done = bake(p)
    assert {d["status"] for d in done.values()} == {"baked"}
    files = sorted(e.path for e in entries(tmp_path))
    assert len(files) == 2
    again = plan(scene(sky, p_I=9.0), tmp_path)
    assert actions(again)["hrir_db"] == actions(again)["sh_tables"] == "reuse"
    assert {d["status"] for d in bake(again).values()} == {"reused"}
    assert sorted(e.path for e in entries(tmp_path)) == files  # nothing new
    changed = plan(scene(sky, p_I=16.0), tmp_path)  # touches the SH recipe only
    assert actions(changed)["sh_tables"] == "bake" and actions(changed)["hrir_db"] == "reuse"
    assert actions(plan(scene(sky, p_I=9.0, ks_II=0.1), tmp_path))["sh_tables"] == "reuse"  # not in any recipe
    assets = find_assets(scene(sky, p_I=9.0), tmp_path)
    assert set(assets) == {"hrir_db", "sh_tables"} and all(a.is_file() for a in assets.values())
    with pytest.raises(errors.AssetNotFoundError, match="hairlut bake --scene"):
        find_assets(scene(sky, p_I=16.0), tmp_path)


def test_covering_database_is_reused(tmp_path):
    space = {
        "strands": [0, 1000],
        "radius_rel": [1e-3, 10.0],
        "aspect": [1e-3, 1.0],
        "v_inner": [0.0, 0.9],
        "radial_extent": [1e-3, 1.0],
        "s_u": [1, 64],
    }
    wide = scene(tables={"restrict": False, "hrir": {**TINY_HRIR, "sectors": {**TINY_HRIR["sectors"], "space": space}}})
    bake(plan(wide, tmp_path))
    step = plan(scene(), tmp_path).step("hrir_db")
    assert step.action == "reuse" and "contains the scene's" in step.reason


@pytest.mark.parametrize(
    "patch, field",
    [
        ({"tables": {"hrir": {"sectors": {"count": -1}}}}, "tables.hrir.sectors.count"),
        ({"tables": {"bogus": 1}}, "tables.bogus"),
        ({"environment": {"bands": 0}}, "environment.bands"),
        ({"environment": {"voxels": 4}}, "environment.voxels"),
        ({"environment": {"up": "x"}}, "environment.up"),
    ],
)
def test_bad_scenes_name_the_key(tmp_path, patch, field):
    s = scene()
    for k, v in patch.items():
        s[k] = {**s.get(k, {}), **v}
    with pytest.raises(errors.ValidationError) as exc:
        plan(s, tmp_path)
    assert exc.value.field == field


def test_missing_environment_map(tmp_path):
    with pytest.raises(errors.AssetNotFoundError):
        plan(scene({"map": "nowhere/env.exr"}), tmp_path)


def test_cli_plan_and_bake_scene(tmp_path):
    path = _write_toml(tmp_path / "scene.toml", scene())
    cache = str(tmp_path / "cache")
    run = CliRunner().invoke(cli, ["plan", str(path), "--cache", cache, "--json"])
    assert run.exit_code == 0, run.output
    doc = json.loads(run.output)
    assert {s["name"]: s["action"] for s in doc["steps"]}["hrir_db"] == "bake" and doc["totals"]["bake_seconds"] > 0
    run = CliRunner().invoke(cli, ["bake", "--scene", str(path), "--cache", cache, "--no-progress"])
    assert run.exit_code == 0, run.output
    assert "baked hrir_db" in run.output and "skip  sh_tables" in run.output
    run = CliRunner().invoke(cli, ["plan", str(path), "--cache", cache])
    assert run.exit_code == 0 and "reuse hrir_db" in run.output
    bad = _write_toml(tmp_path / "bad.toml", scene() | {"environment": {"bands": 0}})
    run = CliRunner().invoke(cli, ["plan", str(bad), "--cache", cache])
    assert run.exit_code == 2 and "environment.bands" in run.output


def _write_toml(path, mapping):
    lines = []

    def emit(prefix, table):
        scalars = {
            k: v
            for k, v in table.items()
            if not isinstance(v, dict) and not (isinstance(v, list) and v and isinstance(v[0], dict))
        }
        if prefix:
            lines.append(f"[{prefix}]")
        for k, v in scalars.items():
            lines.append(f"{k} = {json.dumps(v)}")
        for k, v in table.items():
            if isinstance(v, dict):
                emit(f"{prefix}.{k}" if prefix else k, v)
            elif isinstance(v, list) and v and isinstance(v[0], dict):
                for item in v:
                    lines.append(f"[[{prefix + '.' if prefix else ''}{k}]]")
                    lines.extend(f"{kk} = {json.dumps(vv)}" for kk, vv in item.items())

    emit("", mapping)
    path.write_text("\n".join(lines) + "\n")
    return path
