"""The layered model's rasteriser (hairlut.render._raster): coverage, perspective-correct interpolation,
eq 14 between layers, depth order between clusters, the camera in the EXR, and the CLI."""

from __future__ import annotations

import json

import numpy as np
import OpenEXR
import pytest
from click.testing import CliRunner

from hairlut.geometry.mesh import grid_triangles
from hairlut.render import FAR, Frame, draw_layers, rasterise, read_frame, sample_texture, write_frame
from hairlut.scene import Camera


def camera(projection="orthographic", res=(64, 48), eye=(0.0, 0.0, 5.0), extent=2.0, fov=40.0):
    back = np.array([0.0, 0.0, 1.0])
    return Camera(
        projection,
        np.asarray(eye, float),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 1.0, 0.0]),
        back,
        res[0],
        res[1],
        extent,
        fov,
        0.5 if projection == "perspective" else 0.0,
        20.0,
    )


def quad(corners, rows=4, cols=5):
    """A grid mesh over the bilinear patch of 4 corners (p00, p01, p10, p11): vertices (V, 3), uv (V, 2) with
    u along columns, t along rows, both in [0.1, 0.9] (clear of the texture's periodic seam)."""
    p00, p01, p10, p11 = (np.asarray(c, float) for c in corners)
    t = np.linspace(0, 1, rows)[:, None, None]
    u = np.linspace(0, 1, cols)[None, :, None]
    v = (1 - t) * ((1 - u) * p00 + u * p01) + t * ((1 - u) * p10 + u * p11)
    uv = np.stack(np.broadcast_arrays(0.1 + 0.8 * u[..., 0], 0.1 + 0.8 * t[..., 0]), -1)
    return v.reshape(-1, 3), uv.reshape(-1, 2), grid_triangles(rows, cols)


def constant(rgb, alpha, shape=(6, 8)):
    tex = np.zeros((*shape, 4), np.float32)
    tex[..., :3] = np.asarray(rgb, np.float32) * np.float32(alpha)
    tex[..., 3] = alpha
    return tex


def ramp(shape=(16, 16)):
    """A texture whose R is the texture coordinate u and G is t (linear, so bilinear sampling is exact inside)."""
    n_t, n_u = shape
    tex = np.zeros((n_t, n_u, 4), np.float32)
    tex[..., 0] = ((np.arange(n_u) + 0.5) / n_u)[None, :]
    tex[..., 1] = ((np.arange(n_t) + 0.5) / n_t)[:, None]
    tex[..., 3] = 1.0
    return tex


def one_pass(cam, verts, uv, tri, tex):
    """verts (C, K, V, 3), tex (C, K, n_t, n_u, 4): one tile the size of the frame (the one-pass reference)."""
    C = verts.shape[0]
    return rasterise(cam, verts, tri, uv, tex, tile=(cam.height, cam.width), origins=np.zeros((C, 2), np.int32))[:2]


def two_pass(cam, verts, uv, tri, tex):
    """The same frame through the fragment plan (camera pass) and the per-frame composite."""
    C = verts.shape[0]
    return draw_layers(cam, verts, tri, uv, tex, tile=(cam.height, cam.width), origins=np.zeros((C, 2), np.int32))[:2]


@pytest.fixture(params=["one_pass", "two_pass"])
def draw(request):
    """Every exactness test runs on both renderers."""
    return {"one_pass": one_pass, "two_pass": two_pass}[request.param]


def test_constant_alpha_quad_renders_exactly_that_alpha(draw):
    """Interior pixels take the texture's α bit for bit (no shared edge drawn twice or missed); outside is empty."""
    cam = camera(res=(64, 48))
    a = np.float32(0.37)
    v, uv, tri = quad([(-0.71, -0.53, 0), (0.66, -0.5, 0), (-0.7, 0.61, 0), (0.69, 0.58, 0)], rows=5, cols=7)
    rgba, depth = draw(cam, v[None, None], uv, tri, constant([0.2, 0.5, 0.9], a)[None, None])
    x, y, _ = cam.project(v)
    cx, cy = np.meshgrid(np.arange(64) + 0.5, np.arange(48) + 0.5)
    xmin, xmax, ymin, ymax = x.min(), x.max(), y.min(), y.max()
    # the quad is nearly axis-aligned: a pixel 1.5 px inside its vertex box is surely inside it
    inner = (cx > xmin + 1.5) & (cx < xmax - 1.5) & (cy > ymin + 1.5) & (cy < ymax - 1.5)
    outer = (cx < xmin - 0.5) | (cx > xmax + 0.5) | (cy < ymin - 0.5) | (cy > ymax + 0.5)
    assert inner.sum() > 500
    assert np.all(rgba[inner, 3] == a)
    assert np.all(rgba[inner, :3] == (np.array([0.2, 0.5, 0.9], np.float32) * a))
    assert np.all(rgba[outer] == 0) and np.all(depth[outer] == np.float32(FAR))
    assert set(np.unique(rgba[..., 3])) <= {np.float32(0), a}  # nowhere a double layer 1 − (1 − α)²
    assert np.allclose(depth[inner], 5.0, atol=1e-5)


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_projected_point_lands_where_drawn_and_interpolation_is_perspective_correct(projection, tmp_path, draw):
    """A tilted quad with a (u, t) ramp texture: at a pixel, the drawn (u, t) is that of the quad point the pixel's
    ray hits (perspective-correct), and a quad point projected with the camera matrix stored in the EXR lands on
    the pixel whose drawn (u, t) is its own."""
    cam = camera(projection, res=(96, 80), eye=(0.1, -0.05, 4.0), extent=2.4, fov=45.0)
    p00, p01, p10 = np.array([-0.9, -0.8, -0.6]), np.array([0.9, -0.7, 0.7]), np.array([-0.8, 0.9, -0.5])
    corners = [p00, p01, p10, p01 + p10 - p00]  # a planar parallelogram: (u, t) is affine on it
    v, uv, tri = quad(corners, rows=2, cols=2)
    rgba, depth = draw(cam, v[None, None], uv, tri, ramp()[None, None])
    write_frame(Frame(rgba, depth, cam, {"method": "test"}), tmp_path / "f.exr")
    back = read_frame(tmp_path / "f.exr").camera
    assert np.array_equal(back.matrix, cam.matrix)
    e1, e2 = p01 - p00, p10 - p00
    n = np.cross(e1, e2)
    rng = np.random.default_rng(1)
    checked = 0
    for _ in range(200):
        s, r = rng.uniform(0.05, 0.95, 2)  # (u, t) fractions on the parallelogram
        p = p00 + s * e1 + r * e2
        M = back.matrix  # the stored matrix, applied by hand
        c = M @ np.append(p, 1.0)
        px = (c[0] / c[3] + 1) / 2 * back.width
        py = (1 - c[1] / c[3]) / 2 * back.height
        i, j = int(py), int(px)
        got_u, got_t = rgba[i, j, 0], rgba[i, j, 1]
        # the pixel's own centre: where its ray meets the triangle's plane, in (u, t)
        o, d = cam.rays(np.array(j + 0.5), np.array(i + 0.5))
        lam = ((p00 - o) @ n) / (d @ n)
        q = o + lam * d - p00
        A = np.stack([e1, e2], 1)
        su, rt = np.linalg.lstsq(A, q, rcond=None)[0]
        if not (0.01 < su < 0.99 and 0.01 < rt < 0.99):
            continue
        assert got_u == pytest.approx(0.1 + 0.8 * su, abs=2e-4)
        assert got_t == pytest.approx(0.1 + 0.8 * rt, abs=2e-4)
        # and the projected point's own (u, t) is within the pixel's footprint of what was drawn there
        du = np.hypot(*(np.linalg.lstsq(A, (o + lam * d) - p, rcond=None)[0]))
        assert du < 0.05
        assert depth[i, j] == pytest.approx(float(cam.depth(o + lam * d)), abs=1e-4)
        checked += 1
    assert checked > 40


def test_eq14_between_layers_and_depth_order_between_clusters(draw):
    """Two layers of one cluster compose by eq 14 (outer over inner, whatever their order in the arrays' memory);
    two clusters compose front to back by depth, whichever comes first in the input."""
    cam = camera(res=(40, 40))
    sq = [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]
    # outward normal toward the viewer: rows along +y, columns along +x, triangles CCW for P_u × P_t (outward)
    layer = [quad([(x, y, z) for x, y in sq], rows=3, cols=3) for z in (0.0, 0.1)]  # inner k=0, outer k=1 nearer
    v = np.stack([layer[0][0], layer[1][0]])[None]
    uv, tri = layer[0][1], layer[0][2]
    c_in, a_in, c_out, a_out = np.array([1.0, 0, 0]), 0.6, np.array([0, 1.0, 0]), 0.3
    tex = np.stack([constant(c_in, a_in), constant(c_out, a_out)])[None]
    rgba, depth = draw(cam, v, uv, tri, tex)
    mid = rgba[20, 20]
    expect = c_out * a_out + (1 - a_out) * c_in * a_in  # eq 14: Ψ_1 α_1 + Ψ_0 α_0 (1 − α_1)
    assert np.allclose(mid[:3], expect, atol=1e-6)
    assert mid[3] == pytest.approx(a_out + (1 - a_out) * a_in, abs=1e-6)
    assert depth[20, 20] == pytest.approx(5.0 - 0.1, abs=1e-5)
    # clusters: the same two planes as two one-layer clusters, in both input orders
    for order in ((0, 1), (1, 0)):
        vs = np.stack([layer[i][0] for i in order])[:, None]
        ts = np.stack([constant(c_out if i else c_in, a_out if i else a_in) for i in order])[:, None]
        got, _ = draw(cam, vs, uv, tri, ts)
        assert np.allclose(got[20, 20, :3], expect, atol=1e-6)
    # a near cluster with α = 1 hides the far one entirely
    ts = np.stack([constant(c_in, 0.6), constant(c_out, 1.0)])[:, None]
    got, _ = draw(cam, np.stack([layer[0][0], layer[1][0]])[:, None], uv, tri, ts)
    assert np.allclose(got[20, 20], [0, 1, 0, 1], atol=1e-7)


def test_back_faces_compose_behind_front_faces(draw):
    """A layer's back face (outward normal away from the viewer) lies behind its front face: a closed box seen
    through its translucent front shows the back's colour attenuated by the front's α."""
    cam = camera(res=(32, 32))
    sq = [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]
    front = quad([(x, y, 0.2) for x, y in sq], rows=2, cols=2)
    backq = quad([(x, y, -0.2) for x, y in [sq[1], sq[0], sq[3], sq[2]]], rows=2, cols=2)  # mirrored: faces away
    n = len(front[0])
    # one layer mesh holding both faces; the texture is red in its left half (u < ½), blue in its right half
    v = np.concatenate([front[0], backq[0]])[None, None]
    uv = np.concatenate([front[1] * [0.5, 1.0], backq[1] * [0.5, 1.0] + [0.5, 0.0]])
    tri = np.concatenate([front[2], backq[2] + n])
    tex = np.zeros((4, 8, 4), np.float32)
    tex[:, :4] = [0.5, 0, 0, 0.5]
    tex[:, 4:] = [0, 0, 0.8, 0.8]
    rgba, depth = draw(cam, v, uv, tri, tex[None, None])
    assert np.allclose(rgba[16, 16, :3], [0.5, 0, 0.5 * 0.8], atol=1e-6)
    assert depth[16, 16] == pytest.approx(4.8, abs=1e-5)


@pytest.mark.parametrize("where", ["outside", "between_centres"])
def test_a_frame_that_catches_no_fragment_is_empty(draw, where):
    """Issue 29 N2: layers that cover no pixel centre (outside the frame, or a sliver between two rows of centres)
    make an empty frame, α = 0 and depth FAR everywhere (the camera pass crashed in order_fragments)."""
    cam = camera(res=(16, 12))
    x0, x1, y0, y1 = (5.0, 6.0, -0.5, 0.5) if where == "outside" else (-0.5, 0.5, 0.01, 0.02)  # pixel rows 1/6 apart
    v, uv, tri = quad([(x0, y0, 0.0), (x1, y0, 0.0), (x0, y1, 0.0), (x1, y1, 0.0)], rows=2, cols=2)
    rgba, depth = draw(cam, v[None, None], uv, tri, constant([1.0, 0.5, 0.2], 0.9)[None, None])
    assert rgba.shape == (12, 16, 4) and not rgba.any() and np.all(depth == FAR)


def test_sample_texture_periodic_and_clamped():
    tex = np.random.default_rng(0).random((5, 6, 4)).astype(np.float32)
    n_t, n_u = 5, 6
    # texel centres return the texel exactly; u wraps; t clamps
    for i in range(n_t):
        for j in range(n_u):
            got = np.asarray(sample_texture(tex, np.float32((j + 0.5) / n_u), np.float32((i + 0.5) / n_t)))
            assert np.allclose(got, tex[i, j], atol=1e-6)
    got = np.asarray(sample_texture(tex, np.float32(0.0), np.float32(0.0)))  # half way between columns 5 and 0
    assert np.allclose(got, 0.5 * (tex[0, 0] + tex[0, -1]), atol=1e-6)
    got = np.asarray(sample_texture(tex, np.float32(0.5 / n_u), np.float32(1.0)))
    assert np.allclose(got, tex[-1, 0], atol=1e-6)


def test_exr_holds_the_camera_attribute(tmp_path):
    cam = camera("perspective", res=(8, 6))
    rgba = np.zeros((6, 8, 4), np.float32)
    write_frame(Frame(rgba, np.full((6, 8), FAR, np.float32), cam, {"method": "x"}), tmp_path / "c.exr")
    f = OpenEXR.File(str(tmp_path / "c.exr"), separate_channels=True)
    rec = json.loads(f.header()["hairlut:camera"])
    assert rec["projection"] == "perspective" and rec["resolution"] == [8, 6]
    assert np.allclose(np.asarray(rec["world_to_clip"]), cam.matrix, rtol=0, atol=0)
    assert sorted(f.channels()) == ["A", "B", "G", "R", "Z"]


TINY = """
[render]
resolution = [8, 8]
method = "direct"
[camera]
view = [0.0, 0.2, 1.0]
resolution = [48, 40]
[lights]
directions = [[0.4, 0.6, 1.0]]
[strands]
count = 40
radius = 0.006
[[clusters]]
trajectory = [[0.0, 0.3, 0.0], [0.03, 0.0, 0.05], [0.05, -0.3, 0.04]]
half_axis_a = 0.06
half_axis_b = 0.045
s_t = 4
s_u = 4
"""


def test_cli_render_layered(tmp_path):
    from hairlut_cli.main import cli

    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY)
    out = tmp_path / "f.exr"
    r = CliRunner().invoke(cli, ["render", str(scene), "--out", str(out), "--png", "--json"])
    assert r.exit_code == 0, r.output
    rep = json.loads(r.output[r.output.index("{") :])
    assert rep["method"] == "layered" and rep["map_method"] == "direct"
    assert set(rep["seconds"]) >= {"maps", "raster", "raster_first"}
    f = read_frame(out)
    assert f.rgba.shape == (40, 48, 4) and f.camera.width == 48
    a = f.rgba[..., 3]
    assert 0.02 < (a > 0).mean() < 0.9 and a.max() <= 1.0 + 1e-6
    assert (tmp_path / "f.png").exists()
    # bad input names the key, one line, exit 2
    scene.write_text(TINY.replace("resolution = [48, 40]", "resolution = [0, 40]"))
    r = CliRunner().invoke(cli, ["render", str(scene), "--out", str(out)])
    assert r.exit_code == 2 and "camera.resolution" in r.output


@pytest.mark.parametrize("keys", ["extent = 1e30", 'projection = "perspective"\nfov = 179.9999'])
def test_cli_render_of_a_frame_with_no_hair_is_empty_and_says_so(tmp_path, keys):
    """Issue 29 N2: a legal camera whose frame catches no hair (the hair shrinks far below a pixel, about the
    frame's centre, a pixel corner of this even-sized frame) renders α = 0 everywhere with a warning line, both
    the layered model and the strand render (the layered render crashed with an IndexError)."""
    from hairlut_cli.main import cli

    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY.replace("resolution = [48, 40]", f"resolution = [24, 20]\n{keys}"))
    for extra in ([], ["--strands", "--max-level", "1"]):
        out = tmp_path / f"f{len(extra)}.exr"
        r = CliRunner().invoke(cli, ["render", str(scene), "--out", str(out), *extra])
        assert r.exit_code == 0, r.output
        assert "catches no hair" in r.stderr and r.stderr.count("\n") == 1
        f = read_frame(out)
        assert f.rgba.shape == (20, 24, 4) and not f.rgba.any() and np.all(f.depth == FAR)


def test_write_exr_attributes_round_trip_and_refusals(tmp_path):
    from hairlut import errors
    from hairlut.assets import read_exr, write_exr

    ch = {"Y": np.zeros((2, 3), np.float32)}
    write_exr(tmp_path / "a.exr", ch, attributes={"hairlut:note": '{"x": 1}'})
    img = read_exr(tmp_path / "a.exr")
    assert img.attributes == {"hairlut:note": '{"x": 1}'} and img.checksum == "verified"
    for bad in ({"hairlut:kind": "x"}, {"note": "x"}, {"hairlut:": "x"}, {"hairlut:n": 3}):
        with pytest.raises(errors.ValidationError):
            write_exr(tmp_path / "b.exr", ch, attributes=bad)
    assert not (tmp_path / "b.exr").exists()


def test_pixel_centres_exactly_on_a_shared_edge_are_drawn_once(draw):
    """A quad whose diagonal passes exactly through 48 pixel centres: each is drawn by one triangle only."""
    cam = camera(res=(64, 64), extent=2.0)
    a = np.float32(0.5)
    v, uv, tri = quad([(-0.75, -0.75, 0), (0.75, -0.75, 0), (-0.75, 0.75, 0), (0.75, 0.75, 0)], rows=2, cols=2)
    rgba, _ = draw(cam, v[None, None], uv, tri, constant([1, 1, 1], a)[None, None])
    assert set(np.unique(rgba[..., 3])) == {np.float32(0), a}
    assert int((rgba[..., 3] == a).sum()) == 48 * 48
    assert np.all(rgba[8:56, 8:56, 3] == a)


def test_oblique_path_and_lengthen_follow_beer_lambert():
    """A ray at ψ to the cluster's axis crosses the in-plane density over 1/sin ψ times the path: α' = 1 − (1 − α)^(1/sin ψ),
    the colour per unit α kept; side-on views are unchanged; a perspective ray is taken from the eye to the texel."""
    from hairlut.render import lengthen, oblique_path

    cam = camera()  # orthographic, looking down −z
    psi = np.radians([90.0, 30.0, 0.0])
    tangent = np.stack([np.zeros(3), np.sin(psi), np.cos(psi)], -1)  # at ψ to the view axis z
    path = oblique_path(cam, tangent, np.zeros((3, 3)))
    assert path[0] == pytest.approx(1.0) and path[1] == pytest.approx(2.0)
    assert path[2] == pytest.approx(10.0)  # along the axis: capped, finite
    persp = camera("perspective", eye=(0.0, 0.0, 5.0))
    p = oblique_path(persp, np.array([[0.0, 1.0, 0.0]]), np.array([[0.0, 5.0, 0.0]]))  # the ray from the eye at 45°
    assert p[0] == pytest.approx(np.sqrt(2.0))
    rgba = np.array([[0.2, 0.1, 0.05, 0.4], [0.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.5, 1.0]], np.float32)
    out = lengthen(rgba, np.array([2.0, 3.0, 2.0]))
    assert out[0, 3] == pytest.approx(1 - 0.6**2, abs=1e-6)
    assert np.allclose(out[0, :3] / out[0, 3], rgba[0, :3] / rgba[0, 3], atol=1e-6)
    assert np.all(out[1] == 0) and out[2, 3] == 1.0 and np.allclose(out[2, :3], 0.5)
    assert np.allclose(lengthen(rgba, np.ones(3)), rgba, atol=1e-7)


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_two_pass_frame_equals_the_one_pass_reference(projection):
    """Three overlapping tube clusters of three layers, each in its own tile, random translucent textures: the
    fragment plan's frame equals the one-pass rasteriser's to float32 rounding (depth exactly), and a plan made
    once re-textures a second set of maps to the one-pass frame of those maps."""
    from hairlut.geometry import ClusterGeometry, ClusterSpec
    from hairlut.render import draw_plan, layout

    specs = [
        ClusterSpec(
            trajectory=np.array([[0.05 * c, 0.3, 0.02 * c], [0.04 + 0.03 * c, 0.0, 0.05], [0.05 - 0.02 * c, -0.3, 0.04 * c]]),
            half_axis_a=0.06,
            half_axis_b=0.045,
            layer_radii=np.array([0.4, 0.7, 1.0]),
            s_t=6,
            s_u=6,
            twist=np.array([0.0, 0.3 * c]),
        )
        for c in range(3)
    ]
    geometry = ClusterGeometry(specs)
    cam = camera(projection, res=(72, 64), eye=(0.02, 0.05, 1.5), extent=0.8, fov=35.0)
    meshes, tile, origins, _ = layout(cam, geometry, edge_pixels=6.0)
    assert tile != (cam.height, cam.width) and len(set(map(tuple, origins.tolist()))) > 1  # tiles are exercised
    rng = np.random.default_rng(3)
    texs = []
    for _ in range(2):
        t = rng.uniform(0.0, 1.0, (3, 3, 8, 10, 4)).astype(np.float32)
        t[..., 3] *= 0.7
        t[..., :3] *= t[..., 3:]
        texs.append(t)
    args = (cam, meshes.vertices, meshes.triangles, meshes.uv)
    ref, ref_depth = rasterise(*args, texs[0], tile=tile, origins=origins)[:2]
    got, depth, _, plan = draw_layers(*args, texs[0], tile=tile, origins=origins)
    assert (ref[..., 3] > 0).mean() > 0.1 and plan.info["slabs"] >= 6  # clusters and layers overlap
    assert np.abs(got - ref).max() < 2e-6
    assert np.array_equal(depth, ref_depth)
    ref2 = rasterise(*args, texs[1], tile=tile, origins=origins)[0]
    got2, _ = draw_plan(plan, texs[1])
    assert np.abs(got2 - ref2).max() < 2e-6 and np.abs(ref2 - ref).max() > 0.1
    from hairlut import errors

    with pytest.raises(errors.ValidationError, match="textures"):
        draw_plan(plan, texs[1][:, :, :4])


def test_camera_pass_refuses_above_the_memory_budget():
    """The camera pass estimates its surface buffers first and refuses, naming the camera's resolution."""
    from hairlut import errors
    from hairlut.render import plan_fragments

    cam = camera(res=(64, 48))
    v, uv, tri = quad([(-0.5, -0.5, 0), (0.5, -0.5, 0), (-0.5, 0.5, 0), (0.5, 0.5, 0)])
    with pytest.raises(errors.BudgetError, match="camera.resolution"):
        plan_fragments(cam, v[None, None], tri, uv, (1, 1, 4, 4), tile=(48, 64), origins=np.zeros((1, 2), np.int32), limit=1000)
