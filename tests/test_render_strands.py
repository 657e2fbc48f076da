"""The strand render against closed forms: one straight strand side-on (the Gaussian's chord
integral), a uniform slab of strands (Beer–Lambert), and the camera matrix against where a strand is drawn."""

import math

import jax.numpy as jnp
import numpy as np
import pytest

from hairlut import errors
from hairlut.geometry import Strands
from hairlut.recipes import resolve
from hairlut.render import crossings, render_level, segments_of
from hairlut.scene import CAMERA, make_camera


def _camera(points, **keys):
    cam = resolve(CAMERA, {"view": [0.0, 0.0, 1.0], **keys}, "camera.")
    return make_camera(cam, points)


def _render(strands, camera, kappa, level=0):
    segs = segments_of(strands, kappa)
    lit = jnp.ones((segs.n, 1, 3), jnp.float32)
    return render_level(segs, camera, lit, np.array([[0.0, 0.0, 1.0]]), level=level, shadows=False), segs


def test_straight_strand_alpha_is_the_chord_integral():
    r, kappa = 0.25, 2 / math.pi
    x = np.linspace(-6.0, 6.0, 25)
    pts = np.stack([x, np.zeros_like(x), np.zeros_like(x)], 1)
    strands = Strands(pts, np.array([len(x)]), thickness=np.full(len(x), 2 * r))
    cam = _camera(pts, look_at=[0.0, 0.0, 0.0], extent=2.0, resolution=[64, 48])
    img, _ = _render(strands, cam, kappa)
    rows = np.arange(48) + 0.5
    d = np.abs((1 - 2 * rows / 48) * 1.0)  # world y of each pixel row's centre
    expected = 1 - np.exp(-(kappa / r) * r * math.sqrt(math.pi) * np.exp(-(d**2) / r**2))
    alpha = img[:, 8:56, 3]  # columns well inside the strand (x in [-1, 1])
    assert np.abs(alpha - expected[:, None]).max() < 1e-4
    assert expected.max() > 0.6 and expected.min() < 1e-6  # the test spans the whole profile


def test_uniform_slab_is_beer_lambert():
    r, h, n_z, kappa = 0.25, 0.2, 6, 0.02
    ys = np.arange(-4.0, 4.0 + 1e-9, h)
    lines = []
    for k in range(n_z):
        for y in ys:
            x = np.linspace(-6.0, 6.0, 7)
            lines.append(np.stack([x, np.full_like(x, y), np.full_like(x, k * h)], 1))
    strands = Strands.from_list(lines, thickness=[np.full(7, 2 * r)] * len(lines))
    cam = _camera(np.concatenate(lines), look_at=[0.0, 0.0, 0.0], extent=2.0, resolution=[32, 32])
    img, _ = _render(strands, cam, kappa)
    rho, length = math.pi * r * r / (h * h), n_z * h
    expected = math.exp(-(kappa / r) * rho * length)
    assert 0.2 < expected < 0.9
    assert np.abs((1 - img[..., 3]) - expected).max() < 1e-4


def test_alpha_is_exact_at_any_step_count():
    """Cutting the support into more steps moves no optical depth: α is the same at every level."""
    o = jnp.array([[0.0, 0.3, 5.0]], jnp.float32)
    d = jnp.array([[0.0, 0.0, -1.0]], jnp.float32)
    seg = (jnp.array([[-1.0, 0.0, 0.0]]), jnp.array([[1.0, 0.0, 0.0]]), jnp.array([2.0]), jnp.array([0.2]), jnp.array([3.0]))
    totals = [float(crossings(o, d, *seg, 0.0, n)[0].sum()) for n in (1, 2, 8, 32)]
    exact = 3.0 * 0.2 * math.sqrt(math.pi) * math.exp(-0.09 / 0.04)
    assert np.allclose(totals, exact, rtol=1e-5)


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_matrix_projects_a_strand_where_it_is_drawn(projection):
    """A short strand's centre, projected with the camera's 4 × 4 world-to-clip matrix, lands on the pixel
    of the strand render's α peak."""
    c = np.array([0.7, -0.4, 0.2])
    pts = np.stack([c - [0.05, 0, 0], c + [0.05, 0, 0]])
    box = np.array([[-2.0, -2.0, -1.0], [2.0, 2.0, 1.0]])
    strands = Strands(pts, np.array([2]), thickness=np.full(2, 0.1))
    cam = _camera(np.concatenate([pts, box]), projection=projection, view=[0.3, 0.2, 1.0], resolution=[96, 80])
    img, _ = _render(strands, cam, 2 / math.pi)
    clip = cam.matrix @ np.append(c, 1.0)
    ndc = clip[:3] / clip[3]
    px, py = (ndc[0] + 1) / 2 * cam.width, (1 - ndc[1]) / 2 * cam.height
    iy, ix = np.unravel_index(np.argmax(img[..., 3]), img.shape[:2])
    assert abs(ix + 0.5 - px) <= 1.0 and abs(iy + 0.5 - py) <= 1.0
    assert -1 < ndc[2] < 1


def test_segments_need_positive_extinction():
    pts = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    with pytest.raises(errors.ValidationError, match="trace.extinction"):
        segments_of(Strands(pts, np.array([2]), thickness=np.full(2, 0.1)), 0.0)


def test_cli_render_strands(tmp_path):
    """`hairlut render --strands` on a tiny scene: an EXR with R, G, B, A and Z, the camera in ``hairlut:camera``
    (its matrix projects a strand point onto a drawn pixel), converged, the bound and each level's change stored."""
    import json

    import OpenEXR
    from click.testing import CliRunner

    from hairlut.render import read_frame
    from hairlut_cli.main import cli
    from tests.test_render_layered import TINY

    scene = tmp_path / "tiny.toml"
    scene.write_text(
        TINY.replace("resolution = [48, 40]", "resolution = [24, 20]").replace("radius = 0.006", "radius = 0.025")
        + '[shadows]\nmethod = "none"\n'
    )
    out = tmp_path / "strands.exr"
    r = CliRunner().invoke(
        cli, ["render", str(scene), "--strands", "--bound", "0.05", "--max-level", "1", "--out", str(out), "--json"]
    )
    assert r.exit_code == 0, r.output
    rep = json.loads(r.output[r.output.index("{") :])
    assert rep["method"] == "strands" and rep["converged"], rep["levels"] and rep["bound"] == 0.05
    f = OpenEXR.File(str(out), separate_channels=True)
    assert sorted(f.channels()) == ["A", "B", "G", "R", "Z"]
    cam = json.loads(f.header()["hairlut:camera"])
    assert cam["projection"] == "orthographic" and cam["resolution"] == [24, 20] and np.shape(cam["world_to_clip"]) == (4, 4)
    fr = read_frame(out)
    assert fr.info["bound"] == 0.05 and fr.info["levels"][-1]["change_from_previous"]["alpha_rmse"] < 0.05
    a = fr.rgba[..., 3]
    assert 0.02 < (a > 0.01).mean() < 0.95 and a.max() <= 1.0 + 1e-6
    # the stored matrix puts the cluster's centre on a covered pixel
    clip = np.asarray(cam["world_to_clip"]) @ np.array([0.03, 0.0, 0.05, 1.0])
    x, y = (clip[0] / clip[3] + 1) / 2 * 24, (1 - clip[1] / clip[3]) / 2 * 20
    assert a[int(y), int(x)] > 0.05


def test_cli_render_strands_without_a_bound_reports_the_scene_default(tmp_path):
    """Issue 29 N1: no ``--bound`` and no ``[render] strands_bound``: the text report shows the default bound
    the render used (it formatted the option, None, and crashed after writing the EXR)."""
    from click.testing import CliRunner

    from hairlut.render import BOUND, read_frame
    from hairlut_cli.main import cli
    from tests.test_render_layered import TINY

    scene = tmp_path / "tiny.toml"
    scene.write_text(
        TINY.replace("resolution = [48, 40]", "resolution = [16, 12]").replace("radius = 0.006", "radius = 0.025")
        + '[shadows]\nmethod = "none"\n'
    )
    assert "strands_bound" not in scene.read_text()
    out = tmp_path / "ref.exr"
    r = CliRunner().invoke(cli, ["render", str(scene), "--strands", "--max-level", "1", "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert f"bound {BOUND:g})" in r.output and f"wrote {out}" in r.output
    assert read_frame(out).info["bound"] == BOUND


@pytest.mark.slow
def test_strands_bound_holds_one_level_finer(tmp_path):
    """``verify``: the converged image against one more refinement changes by less than the bound too."""
    import tomllib

    from hairlut.render import render_strands
    from hairlut.scene import resolve_scene
    from tests.test_render_layered import TINY

    cfg = tomllib.loads(
        TINY.replace("resolution = [48, 40]", "resolution = [24, 20]").replace("radius = 0.006", "radius = 0.025")
    )
    cfg["shadows"] = {"method": "none"}
    cfg.setdefault("render", {})["strands_bound"] = 0.05  # the scene's own bound, as the Ratboy scene sets it
    f = render_strands(resolve_scene(cfg, None), max_level=1, verify=True)
    assert f.info["converged"] and f.info["bound"] == 0.05
    v = f.info["verified"]
    assert v["level"] == f.info["levels"][-1]["level"] + 1 and v["holds"], v
    assert max(v["change_from_returned"].values()) < 0.05


@pytest.mark.parametrize("bad", [0.0, -0.01, float("nan"), 2.0, "tight"])
def test_a_bad_strands_bound_is_refused_naming_the_key(bad):
    import tomllib

    from hairlut.scene import resolve_scene
    from tests.test_render_layered import TINY

    cfg = tomllib.loads(TINY)
    cfg.setdefault("render", {})["strands_bound"] = bad
    with pytest.raises(errors.ValidationError, match="strands_bound"):
        resolve_scene(cfg, None)


def test_the_old_reference_bound_key_is_refused_naming_the_new_one():
    """``[render] reference_bound`` was renamed ``strands_bound`` ("reference" means an oracle only)."""
    import tomllib

    from hairlut.scene import resolve_scene
    from tests.test_render_layered import TINY

    cfg = tomllib.loads(TINY)
    cfg.setdefault("render", {})["reference_bound"] = 0.05
    with pytest.raises(errors.ValidationError, match="render.strands_bound") as exc:
        resolve_scene(cfg, None)
    assert exc.value.field == "render.reference_bound"


def test_inside_clusters_splits_strand_length_by_where_the_sectors_see_it():
    """A straight cluster along y from 0 to 1 (half-axes 0.2, core 0.25); three strands parallel to it from y = −0.5
    to 1.5, at v = 0.5, 0 (the core) and 1.5 (outside the shell): a quarter of every strand lies before the start and
    a quarter after the end, and of the middle halves only the one at v = 0.5 is kept."""
    from hairlut.geometry import ClusterSpec
    from hairlut.render import inside_clusters

    spec = ClusterSpec(np.array([[0.0, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 1.0, 0.0]]), 0.2, 0.2, core_radius=0.25)
    y = np.linspace(-0.5, 1.5, 81)
    pts = [np.stack([np.full_like(y, x), y, np.zeros_like(y)], 1) for x in (0.1, 0.0, 0.3)]
    strands = Strands(np.concatenate(pts).astype(np.float32), np.full(3, len(y)), thickness=np.full(3 * len(y), 0.01))
    kept, frac = inside_clusters([(spec, strands)])
    assert frac["before_start"] == pytest.approx(0.25, abs=0.01) and frac["after_end"] == pytest.approx(0.25, abs=0.01)
    assert frac["inside"] == pytest.approx(1 / 6, abs=0.01)
    assert frac["core"] == pytest.approx(1 / 6, abs=0.01) and frac["outside"] == pytest.approx(1 / 6, abs=0.01)
    assert sum(frac.values()) == pytest.approx(1.0)
    p = kept[0].points
    assert np.all((p[:, 1] > -0.03) & (p[:, 1] < 1.03)) and np.allclose(p[:, 0], 0.1)


def _slab(r=0.25, h=0.2, n_z=6, half=4.0):
    """Parallel strands along x, spaced ``h`` in y and z: n_z layers from z = 0 up, y in [−half, half]."""
    lines = [
        np.stack([np.linspace(-6.0, 6.0, 7), np.full(7, y), np.full(7, k * h)], 1)
        for k in range(n_z)
        for y in np.arange(-half, half + 1e-9, h)
    ]
    return Strands.from_list(lines, thickness=[np.full(7, 2 * r)] * len(lines))


def test_shadow_through_a_uniform_slab_is_beer_lambert():
    """Points under a slab of strands, light at 30° to its normal: τ = σ_t ρ L with ρ = π r²/h² the slab's mean
    density and L = n_z h / cos 30° the path through it (the layers' Gaussians sum to a constant to e^−(π r/h)²)."""
    from hairlut.render import light_index, point_depths

    r, h, n_z, kappa = 0.25, 0.2, 6, 0.02
    segs = segments_of(_slab(r, h, n_z), kappa)
    theta = math.radians(30.0)
    light = np.array([0.0, math.sin(theta), math.cos(theta)])
    rng = np.random.default_rng(3)
    pts = np.stack([rng.uniform(-3, 3, 40), rng.uniform(-1.5, 0.5, 40), np.full(40, -2.0)], 1)
    tau = point_depths(light_index(segs, light), pts, segs.device())
    expected = (kappa / r) * (math.pi * r * r / (h * h)) * (n_z * h / math.cos(theta))
    assert 0.2 < math.exp(-expected) < 0.9
    assert np.abs(np.exp(-tau) - math.exp(-expected)).max() < 1e-4
    # above the slab (and beyond its tubes' cut) the light meets nothing
    assert np.abs(point_depths(light_index(segs, light), pts + [0, 0, 4.0], segs.device())).max() < 1e-6


def _curls():
    """40 curly strands from a 2 × 2 × 2 box (radius 0.04): polylines and their segments (κ = 2/π)."""
    rng = np.random.default_rng(7)
    lines = []
    for _ in range(40):
        start = rng.uniform(-1, 1, 3)
        steps = np.cumsum(rng.normal(0, 0.15, (12, 3)) + [0.0, -0.12, 0.0], 0)
        lines.append(np.concatenate([start[None], start + steps]))
    strands = Strands.from_list(lines, thickness=[np.full(13, 0.08)] * len(lines))
    return lines, segments_of(strands, 2 / math.pi)


def test_point_shadows_equal_the_grid_at_its_nodes():
    """The exact per-point shadow rays (``point_depths``) against the light-aligned grid (``shadow_grid``, each
    node column one ray integrated from every node): the same integral at every node, to float32 rounding."""
    from hairlut.render import light_index, point_depths, shadow_grid

    rng = np.random.default_rng(7)
    _, segs = _curls()
    light = np.array([0.3, 0.8, 0.4])
    grid, origin, axes = shadow_grid(segs, light, 0.05)
    idx = np.stack([rng.integers(0, n, 3000) for n in grid.shape], 1)
    pts = origin + 0.05 * idx @ axes
    tau = point_depths(light_index(segs, light), pts, segs.device())
    g = grid[idx[:, 0], idx[:, 1], idx[:, 2]]
    assert g.max() > 1.0 and (g > 0.01).mean() > 0.1  # the nodes see real shadow
    assert np.abs(tau - g).max() < 1e-4 * max(1.0, g.max())


def test_demo_probe_is_the_change_between_the_two_levels():
    """The demo states how far its strand render level is from the next (``hairlut.demo.strands_probe``): the same
    camera at a smaller size, with the aspect kept; the change is the RMSE between the two levels rendered apart."""
    import tomllib

    from hairlut.demo import strands_probe
    from hairlut.render import render_strands, scene_strands
    from hairlut.scene import make_camera, resolve_scene
    from tests.test_render_layered import TINY

    cfg = tomllib.loads(TINY.replace("radius = 0.006", "radius = 0.025"))
    cfg["shadows"] = {"method": "none"}
    sc = resolve_scene(cfg, None)
    pr = strands_probe(sc, level=0, size=24)
    assert pr["resolution"] == [24, 20] and pr["next_level"] == 1
    pts = np.concatenate([s.points for s in scene_strands(sc)])
    cam = make_camera({**sc.config["camera"], "resolution": [24, 20]}, pts)
    a, b = (render_strands(sc, cam, levels=[lv]).rgba for lv in (0, 1))
    assert pr["change_to_next"]["alpha_rmse"] == pytest.approx(np.sqrt(np.mean((a[..., 3] - b[..., 3]) ** 2)), rel=1e-5)
    assert pr["change_to_next"]["rgb_rmse"] == pytest.approx(np.sqrt(np.mean((a[..., :3] - b[..., :3]) ** 2)), rel=1e-5)
    assert pr["change_to_next"]["alpha_rmse"] > 1e-4  # the levels differ: the test can see a wrong pair


def test_rendered_grid_shadows_converge_to_the_shadow_rays(monkeypatch):
    """A frame's shadows from the grid (cell 4 r̄ / 2^ℓ, trilinear) against the exact shadow ray per step: α is the
    same, the colours differ by the grid's interpolation, which falls at second order from level 0 to 1 (measured
    0.067 → 0.015 RMSE, against a shadow effect of 0.19)."""
    import hairlut.render._strand_march as ref

    lines, segs = _curls()
    cam = _camera(np.concatenate(lines), resolution=[32, 32])
    lit = jnp.ones((segs.n, 1, 3), jnp.float32)
    light = np.array([[0.3, 0.8, 0.4]]) / np.linalg.norm([0.3, 0.8, 0.4])
    diff = []
    for level in (0, 1):
        st = {}
        grid = render_level(segs, cam, lit, light, level=level, shadows=True, stats=st)
        assert st["shadow_source"] == "grid"
        monkeypatch.setattr(ref, "GRID_NODES", 0)
        rays = render_level(segs, cam, lit, light, level=level, shadows=True, stats=st)
        assert st["shadow_source"] == "rays"
        monkeypatch.undo()
        assert np.abs(grid[..., 3] - rays[..., 3]).max() < 1e-6
        diff.append(float(np.sqrt(np.mean((grid[..., :3] - rays[..., :3]) ** 2))))
    unshadowed = render_level(segs, cam, lit, light, level=1, shadows=False)
    assert np.sqrt(np.mean((unshadowed[..., :3] - rays[..., :3]) ** 2)) > 0.1
    assert diff[1] < diff[0] / 3, diff


def _dense_oracle(segs, cam, lit, light, level, lattice):
    """Every pixel's rays through every segment (no tiles, no first pass, no ``SEEN`` cut), the steps sorted by numpy
    and composited in float64, each step shadowed by its own exact shadow ray: what ``render_level`` computes."""
    from hairlut.render import light_index, point_depths
    from hairlut.render._strand_march import camera_array, camera_rays

    ss, steps = 1 << level, 2 << level
    tiles = np.stack(np.meshgrid(np.arange(cam.width // 8), np.arange(cam.height // 8), indexing="ij"), -1).reshape(-1, 2)
    o, d = camera_rays(
        jnp.asarray(tiles, jnp.int32),
        jnp.asarray(camera_array(cam), jnp.float32),
        tile=8,
        ss=ss,
        perspective=False,
        lattice=lattice,
    )
    o, d = np.asarray(o).reshape(-1, 3), np.asarray(d).reshape(-1, 3)
    r = np.arange(64 * ss * ss)
    py = (tiles[:, 1, None] * 8 + r // (8 * ss * ss)).reshape(-1)
    px = (tiles[:, 0, None] * 8 + (r // (ss * ss)) % 8).reshape(-1)
    dev = segs.device()
    tau, s = (
        np.asarray(a, np.float64)
        for a in crossings(jnp.asarray(o)[:, None], jnp.asarray(d)[:, None], *(a[None] for a in dev), -1e20, steps)
    )
    seg = np.broadcast_to(np.arange(segs.n)[None, :, None], tau.shape).reshape(len(o), -1)
    tau, s = tau.reshape(len(o), -1), s.reshape(len(o), -1)
    order = np.argsort(s, axis=1, kind="stable")
    tau, s, seg = (np.take_along_axis(a, order, 1) for a in (tau, s, seg))
    shade = np.zeros(tau.shape)
    hit = tau > 0
    pts = o[:, None] + s[..., None] * d[:, None]
    shade[hit] = point_depths(light_index(segs, light[0]), pts[hit], dev)
    total = np.cumsum(tau, 1)
    w = -np.expm1(-tau) * np.exp(-(total - tau))
    rgb = (w[..., None] * np.asarray(lit, np.float64)[seg, 0] * np.exp(-shade)[..., None]).sum(1)
    out = np.zeros((cam.height, cam.width, 4))
    for c, v in enumerate([*rgb.T, -np.expm1(-total[:, -1])]):
        np.add.at(out[..., c], (py, px), v / (ss * ss))
    return out


@pytest.mark.parametrize("lattice", [False, True])
def test_frame_equals_the_dense_march_to_float32_rounding(monkeypatch, lattice):
    """The tiled, first-pass-filtered frame whose crossings are found once (``step_points``) and composited from
    them (``strand_march_kernel``) equals a dense float64 march of every ray through every segment, shadows included."""
    import hairlut.render._strand_march as ref

    lines, segs = _curls()
    cam = _camera(np.concatenate(lines), resolution=[24, 16])
    lit = jnp.asarray(np.random.default_rng(1).uniform(0.2, 1.0, (segs.n, 1, 3)), jnp.float32)
    light = np.array([[0.3, 0.8, 0.4]]) / np.linalg.norm([0.3, 0.8, 0.4])
    monkeypatch.setattr(ref, "GRID_NODES", 0)  # exact shadow rays, as the oracle's
    img = render_level(segs, cam, lit, light, level=1, shadows=True, lattice=lattice)
    want = _dense_oracle(segs, cam, lit, light, 1, lattice)
    assert want[..., 3].max() > 0.5 and want[..., :3].max() > 0.2 and (want[..., 3] < 1e-6).mean() > 0.05
    assert np.abs(img[..., :4] - want).max() < 2e-5
