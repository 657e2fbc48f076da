"""The procedural grooms of tests/_grooms.py (issue 26, deliverable 4): their shapes, their files, default scenes that
plan, bake, render and compare, and grooms the cluster fit cannot use, refused naming ``groom.path``."""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.bench import _grooms as g
from hairlut.geometry import Strands, read_strands, write_strands

KINDS = tuple(g.KINDS)


@pytest.fixture(scope="module")
def grooms():
    return {kind: make(seed=0) for kind, make in g.KINDS.items()}


def test_generators_are_deterministic_by_seed_and_fit_tfx(grooms):
    for kind, make in g.KINDS.items():
        s = grooms[kind]
        again, other = make(seed=0), make(seed=1)
        np.testing.assert_array_equal(s.points, again.points)
        assert not np.array_equal(s.points, other.points)
        assert s.points.dtype == np.float32 and (s.counts == s.counts[0]).all() and int(s.counts[0]) in (4, 8, 16, 32, 64)
        assert np.isfinite(s.points).all() and (s.lengths() > 0).all()
        np.testing.assert_array_equal(s.thickness, np.float32(0.2))  # 2 · the [groom] radius default 0.1
        # the roots lie on the scalp and nothing dips into the head
        r = np.linalg.norm(g.roots(s) - g.SCALP_CENTRE, axis=1)
        np.testing.assert_allclose(r, g.SCALP_RADIUS, rtol=1e-5)
        assert np.linalg.norm(s.points - g.SCALP_CENTRE, axis=1).min() > g.SCALP_RADIUS * (1 - 1e-5)
    small = g.curly(50, 16, seed=3)
    assert small.n_strands == 50 and small.n_points == 800


@pytest.mark.parametrize("kind", KINDS)
def test_a_groom_round_trips_through_hair_and_tfx(kind, grooms, tmp_path):
    s = grooms[kind]
    files = g.write_groom(tmp_path, kind, s)
    assert set(files) == {"hair", "tfx"} and all(p.suffix == f".{fmt}" for fmt, p in files.items())
    hair, tfx = read_strands(files["hair"]), read_strands(files["tfx"])
    for back in (hair, tfx):  # float32 in both formats, as generated: exact
        np.testing.assert_array_equal(back.counts, s.counts)
        np.testing.assert_array_equal(back.points, s.points)
    np.testing.assert_array_equal(hair.thickness, s.thickness)  # .hair keeps the thickness (a header default)
    assert tfx.thickness is None  # .tfx has none: a scene's [groom] radius (default 0.1) stands in for it
    pinned = np.zeros(s.n_points, bool)
    pinned[s.offsets[:-1]] = True
    np.testing.assert_array_equal(tfx.movable, ~pinned)  # the writer pins each root


def test_curls_are_curly_and_the_straight_hair_is_not(grooms):
    curly, straight = grooms["curly"], grooms["parted"]
    k_curly, k_straight = g.mean_curvature(curly), g.mean_curvature(straight)
    assert k_curly > 5 * k_straight, (k_curly, k_straight)
    # a helix of radius ρ and rise c = pitch / 2π per radian has curvature ρ / (ρ² + c²): 0.53–1.0 over the default
    # ranges; the 10-point turns cut the corners a little
    assert 0.4 < k_curly < 1.0

    # chord over arc length: a curl winds, a straight strand hangs
    def chord(s):
        p = s.as_padded().astype(np.float64)
        return np.linalg.norm(p[:, -1] - p[:, 0], axis=1) / s.lengths()

    assert np.median(chord(curly)) < 0.75 < 0.9 < np.median(chord(straight))
    # random phase: where the curl sits at the end of the ramp differs from strand to strand
    p = curly.as_padded().astype(np.float64)
    off = p[:, 8] - 0.5 * (p[:, 7] + p[:, 9])  # the bend's direction at one point of each strand
    assert np.linalg.norm(off / np.linalg.norm(off, axis=1, keepdims=True), axis=1).mean() > 0.99
    mean_dir = np.linalg.norm((off / np.linalg.norm(off, axis=1, keepdims=True)).mean(axis=0))
    assert mean_dir < 0.3, mean_dir


def test_the_parting_is_free_of_roots_and_the_hair_is_combed_away_from_it(grooms):
    s = grooms["parted"]
    r = g.roots(s)
    assert not g.in_parting(r).any()
    assert g.in_parting(g.scalp_roots(np.random.default_rng(0), 2000)[0]).mean() > 0.02  # the band is on the cap
    # both sides of the band hold roots close to it
    near = g.in_parting(r, parting_width=3 * 1.2) & ~g.in_parting(r)
    assert (r[near, 0] > 0).sum() >= 10 and (r[near, 0] < 0).sum() >= 10
    # a strand near the parting ends on its root's side
    tips = s.as_padded()[:, -1].astype(np.float64)
    assert (np.sign(tips[near, 0]) == np.sign(r[near, 0])).all()
    # long and straight
    assert s.lengths().min() > 2 * g.SCALP_RADIUS
    # a side parting moves the band
    side = g.parted(200, 16, parting_x=3.0)
    assert not g.in_parting(g.roots(side), parting_x=3.0).any() and g.in_parting(g.roots(side)).any()


def test_the_crop_is_short_dense_and_stands_up(grooms):
    s, curly = grooms["crop"], grooms["curly"]
    assert s.lengths().max() < 0.25 * g.SCALP_RADIUS < 0.1 * grooms["parted"].lengths().min()
    density = s.n_strands / g.cap_area(80.0)
    assert density > 1.3 * curly.n_strands / g.cap_area(75.0)
    p = s.as_padded().astype(np.float64)
    tangent = (p[:, 1] - p[:, 0]) / np.linalg.norm(p[:, 1] - p[:, 0], axis=1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip(np.sum(tangent * g.root_normals(s), axis=1), -1, 1)))
    assert angle.max() < 15.0, angle.max()
    # dense: a root's nearest neighbour is close (under a strand's length)
    r = g.roots(s)
    d = np.linalg.norm(r[:, None] - r[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    assert np.median(d.min(axis=1)) < 0.5 * s.lengths().mean()


def test_the_scene_file_holds_only_groom_camera_and_lights(tmp_path):
    from hairlut.scene import load_scene

    scenes = g.groom_scenes(tmp_path, sizes={k: {"n_strands": 20, "points": 8} for k in KINDS}, resolution=(40, 30))
    assert set(scenes) == set(KINDS)
    for kind, path in scenes.items():
        raw = tomllib.loads(path.read_text())
        assert raw == {
            "groom": {"path": f"{kind}.hair"},
            "camera": {"view": g.VIEWS["front"], "resolution": [40, 30]},
            "lights": {"directions": [g.LIGHT]},
        }
        sc = load_scene(path)
        assert sc.groom_path.resolve() == (tmp_path / f"{kind}.hair").resolve()
        assert sc.config["groom"]["clusters"] == "auto" and sc.config["render"]["method"] == "auto"  # defaults
        assert (tmp_path / f"{kind}.tfx").is_file()
    tfx = g.groom_scenes(tmp_path / "t", ("crop",), "tfx", view=g.VIEWS["side"])["crop"]
    assert tomllib.loads(tfx.read_text())["groom"]["path"] == "crop.tfx"
    # a groom outside the scene's folder is named by its absolute path
    outside = g.write_scene(tmp_path / "elsewhere/s.toml", tmp_path / "crop.hair")
    assert load_scene(outside).groom_path.resolve() == (tmp_path / "crop.hair").resolve()


@pytest.mark.parametrize("kind", KINDS)
def test_the_fitted_camera_sees_every_groom_from_every_view(kind, grooms):
    """The fitted orthographic eye lies just past the hair's nearest point along the view: for an oblique view that
    can be inside the hair's axis-aligned box (it was refused as 'inside the hair's bounds' for the curly groom from
    the front view) but never behind any hair."""
    from hairlut.recipes import resolve
    from hairlut.scene import CAMERA, make_camera

    pts = grooms[kind].points
    for view in g.VIEWS.values():
        for projection in ("orthographic", "perspective"):
            cam = make_camera(resolve(CAMERA, {"view": view, "resolution": [32, 32], "projection": projection}), pts)
            assert (cam.depth(pts) > 0).all()
            x, y, _ = cam.project(pts)
            assert (x >= 0).all() and (x <= 32).all() and (y >= 0).all() and (y <= 32).all()  # all in the frame


def test_hair_and_tfx_copies_plan_the_same_sectors(tmp_path):
    """The .tfx copy has no thickness and takes the default [groom] radius 0.1; the .hair copy carries 2 · 0.1: the
    same strands, so the same fitted clusters and sectors (the per-groom table's key is the file's hash, so it differs)."""
    from hairlut.planner import plan
    from hairlut.scene import load_scene, scene_sectors

    g.write_groom(tmp_path, "curly", g.curly(120, 16))
    seen = []
    for fmt in g.FORMATS:
        scene = g.write_scene(tmp_path / f"curly-{fmt}.toml", tmp_path / f"curly.{fmt}", resolution=(32, 32))
        p = plan(scene, tmp_path / "cache")
        assert p.step("scene_maps").action == "bake" and p.step("map_method").details["live"] > 0
        seen.append(scene_sectors(load_scene(scene)))
    for name in ("strands", "aspect", "v_range", "radius_rel", "theta_v"):
        np.testing.assert_array_equal(getattr(seen[0], name), getattr(seen[1], name), err_msg=name)


def _cli(*args):
    from hairlut_cli.main import cli

    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.mark.slow
@pytest.mark.parametrize("kind, fmt", [("curly", "hair"), ("parted", "tfx"), ("crop", "hair")])
def test_a_default_scene_plans_bakes_renders_and_compares(kind, fmt, tmp_path):
    """Issue 26: a scene of only [groom] path, a camera and a light goes through `hairlut plan`, `bake --scene`,
    `render` (layered), `render --strands` and `compare` without error, on every generated groom (small: 300 strands,
    16 points, 32² pixels, the strand render's level 0 only; ~50 s a groom on the shared 2-core CPU)."""
    size = {"n_strands": 300, "points": 16 if kind != "crop" else 8}
    scene = g.groom_scenes(tmp_path, (kind,), fmt, sizes={kind: size}, resolution=(32, 32))[kind]
    cache = tmp_path / "cache"
    r = _cli("plan", scene, "--cache", cache, "--json")
    assert r.exit_code == 0, r.output
    r = _cli("bake", "--scene", scene, "--cache", cache, "--no-progress")
    assert r.exit_code == 0, r.output
    layered, strands = tmp_path / "layered.exr", tmp_path / "strands.exr"
    r = _cli("render", scene, "--cache", cache, "--out", layered)
    assert r.exit_code == 0, r.output
    r = _cli("render", scene, "--strands", "--max-level", 0, "--out", strands)
    assert r.exit_code == 0, r.output
    r = _cli("compare", layered, strands, "--json")
    assert r.exit_code == 0, r.output
    figures = json.loads(r.output[r.output.index("{") :])
    assert figures["alpha_mean_a"] > 0.02 and figures["alpha_mean_b"] > 0.02  # both frames hold hair
    assert all(math.isfinite(v) for v in figures.values() if isinstance(v, float))
    assert 0 <= figures["flip_mean"] <= 1


# ----------------------------------------------------------------------------- bad grooms


def _bad_grooms():
    line = np.array([[0.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, -2.0, 0.0], [0.0, -3.0, 0.0]], np.float32)
    flat = np.repeat(np.arange(6, dtype=np.float32)[:, None, None], 4, axis=1).repeat(3, axis=2)
    mixed = g.curly(12, 4, seed=5).as_padded().copy()
    mixed[7] = mixed[7, 0]
    return {
        "one strand": (Strands.from_padded(line[None]), "the groom holds 1 strand"),
        "zero-length strands": (Strands.from_padded(flat), "6 of 6 strands have no length (strand 0: its 4 points"),
        "one zero-length strand": (Strands.from_padded(mixed), "1 of 12 strands has no length (strand 7:"),
    }


@pytest.mark.parametrize("fmt", g.FORMATS)
@pytest.mark.parametrize("case", list(_bad_grooms()))
def test_a_groom_the_fit_cannot_use_is_refused_naming_groom_path(case, fmt, tmp_path):
    from hairlut.planner import plan

    strands, words = _bad_grooms()[case]
    groom = tmp_path / f"bad.{fmt}"
    write_strands(groom, strands)
    scene = g.write_scene(tmp_path / "bad.toml", groom, resolution=(32, 32))
    with pytest.raises(errors.ValidationError) as exc:
        plan(scene, tmp_path / "cache")
    assert exc.value.field == "groom.path" and exc.value.value.endswith(f"bad.{fmt}")
    assert words in exc.value.reason
    r = _cli("plan", scene, "--cache", tmp_path / "cache")
    assert r.exit_code == 2
    assert r.output.startswith("hairlut: error: groom.path=") and r.output.count("\n") == 1 and words in r.output


def test_a_groom_without_strands_is_refused_naming_groom_path(tmp_path):
    from hairlut.planner import plan

    write_strands(tmp_path / "none.hair", Strands(np.zeros((0, 3), np.float32), np.zeros(0, np.int64)))
    scene = g.write_scene(tmp_path / "none.toml", tmp_path / "none.hair")
    with pytest.raises(errors.ValidationError, match="groom.path=.*the groom holds 0 strands"):
        plan(scene, tmp_path / "cache")


def test_resampling_a_strand_without_length_keeps_it_in_place():
    """fit.resample_strands spread a zero-length strand toward the next strand's root (its arc-length keys all 0):
    such a strand gave k-means a fake length."""
    from hairlut.geometry import resample_strands

    pts = np.array([[1.0, 1.0, 1.0]] * 4 + [[5.0, 0.0, 0.0], [5.0, 2.0, 0.0], [5.0, 4.0, 0.0], [5.0, 6.0, 0.0]])
    res = resample_strands(Strands(pts, [4, 4]), 5)
    np.testing.assert_array_equal(res[0], np.ones((5, 3)))
    np.testing.assert_allclose(res[1, :, 1], [0.0, 1.5, 3.0, 4.5, 6.0])
