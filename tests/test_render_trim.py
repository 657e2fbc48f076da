"""Layers that stay on the hair (issue 26, deliverable 3): ``render_layered`` draws each cluster only within its own
strands' footprint through the camera (``hairlut.render._trim``), so that no α lies off the hair.

The scene: one fitted cluster of parallel vertical strands whose roots lie on a slanted scalp (y = 1 + 0.6 x).  The
fit lengthens the trajectory up to the highest root, so the cluster's start overhangs the scalp over most of its
width, and eq 7's interpolation between the first cross-sections puts a translucent sheet there: without the trim,
α lies above the scalp, away from every strand.  With it, α is zero outside the strands' projected hull (each
strand's projected centre line widened by its radius and the trim's margin, measured here by exact point–segment
distances), and unchanged inside."""

from __future__ import annotations

import numpy as np
import pytest

from hairlut import errors
from hairlut.geometry import Strands, write_strands
from hairlut.render import alpha_outside, compare, render_layered, strand_footprints, texel_margins
from hairlut.render._trim import slack
from hairlut.scene import Camera, load_scene, scene_clusters

R = 0.015  # strand radius

SCENE = """
[render]
resolution = [32, 32]
method = "direct"
[camera]
view = [0.0, 0.0, 1.0]
resolution = [48, 48]
[lights]
directions = [[0.4, 0.6, 1.0]]
[groom]
path = "scalp.hair"
clusters = 1
s_t = 2
s_u = 4
"""


def slanted_scalp(n: int = 24) -> Strands:
    """Parallel vertical strands from a slanted scalp (roots at y = 1 + 0.6 x, x in [−1, 1]) down to y = −1.5."""
    lines = []
    for i in range(n):
        x = -1.0 + 2.0 * i / (n - 1)
        y = np.linspace(1.0 + 0.6 * x, -1.5, 12)
        lines.append(np.stack([np.full_like(y, x), y, np.full_like(y, 0.08 * np.sin(2.3 * i))], 1))
    return Strands.from_list(lines, thickness=[np.full(len(line), 2 * R) for line in lines])


def segment_distance(cam, strands, w: int, h: int) -> np.ndarray:
    """(h, w): each pixel centre's distance, in pixels, to the nearest projected strand segment (exact)."""
    x, y, _ = cam.project(np.asarray(strands.points, np.float64))
    last = np.zeros(len(x), bool)
    last[strands.offsets[1:] - 1] = True
    a = np.flatnonzero(~last)
    p0 = np.stack([x[a], y[a]], 1)
    d = np.stack([x[a + 1], y[a + 1]], 1) - p0
    py, px = np.mgrid[0:h, 0:w] + 0.5
    q = np.stack([px.ravel(), py.ravel()], 1)
    s = np.clip(np.einsum("qsk,sk->qs", q[:, None] - p0[None], d) / np.einsum("sk,sk->s", d, d), 0.0, 1.0)
    return np.linalg.norm(q[:, None] - (p0[None] + s[..., None] * d[None]), axis=-1).min(1).reshape(h, w)


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    from hairlut.synth import prepare

    folder = tmp_path_factory.mktemp("scalp")
    write_strands(folder / "scalp.hair", slanted_scalp())
    (folder / "scalp.toml").write_text(SCENE)
    sc = load_scene(folder / "scalp.toml")
    prep = prepare(sc)
    return sc, render_layered(sc, prepared=prep, trim=False, repeat=0), render_layered(sc, prepared=prep, repeat=0)


def test_a_single_clusters_alpha_is_zero_outside_its_strands_projected_hull(frames):
    sc, untrimmed, trimmed = frames
    cam = trimmed.camera
    (_, strands), *rest = scene_clusters(sc)
    assert not rest  # one cluster
    r_px = R * cam.height / cam.extent  # orthographic: world units to pixels
    margin = trimmed.info["trim"]["margin_px"][0]
    assert 1.0 <= margin < 8.0  # two texels (32 texels over the cluster's length and girth), at least a pixel
    dist = segment_distance(cam, strands, cam.width, cam.height)
    hull = dist <= r_px + margin + slack() + np.sqrt(0.5)  # the footprint's tolerance, to the pixel
    a0, a1 = untrimmed.rgba[..., 3], trimmed.rgba[..., 3]
    # the overhang is there without the trim: α off the hair, above the slanted scalp
    assert a0[~hull].sum() > 0.01 * a0.sum()
    xs, ys = np.meshgrid(np.arange(cam.width) + 0.5, np.arange(cam.height) + 0.5)
    o, right, up = cam.eye, cam.right, cam.up
    wx = (xs - cam.width / 2) / cam.width * cam.extent * cam.aspect + o @ right
    wy = (cam.height / 2 - ys) / cam.height * cam.extent + o @ up
    above_scalp = wy > 1.0 + 0.6 * wx + (r_px + margin + 1.0) * cam.extent / cam.height
    assert a0[above_scalp & ~hull].sum() > 0.5 * a0[~hull].sum()  # most of it overhangs the scalp
    # with the trim: none outside the hull, and every pixel well inside it unchanged
    assert a1[~hull].max() == 0.0
    inside = dist <= r_px + margin - 1.0
    assert inside.sum() > 200 and np.array_equal(trimmed.rgba[inside], untrimmed.rgba[inside])
    info = trimmed.info["trim"]
    assert info["trimmed"] > 0 and 0.0 < info["trimmed_fraction"] < 0.5
    assert untrimmed.info["trim"] is None


def ortho(w=40, h=30, extent=3.0) -> Camera:
    return Camera(
        "orthographic",
        np.array([0.0, 0.0, 5.0]),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 1.0, 0.0]),
        np.array([0.0, 0.0, 1.0]),
        w,
        h,
        extent,
        40.0,
        0.0,
        20.0,
    )


@pytest.mark.parametrize("margin", [0.0, 1.0, 2.5])
def test_footprint_is_the_strands_centre_lines_widened_to_the_pixel(margin, monkeypatch):
    """Pixels within radius + margin of a projected segment are kept; none beyond that plus a pixel's diagonal."""
    cam = ortho()
    lines = [np.array([[-1.0, -0.8, 0.0], [0.3, 0.9, 0.1], [1.2, 0.7, 0.0]]), np.array([[-1.3, 1.0, 0.0], [-1.2, -1.1, 0.2]])]
    s = Strands.from_list(lines, thickness=[np.full(len(line), 0.1) for line in lines])
    keep = strand_footprints(cam, [s], (cam.height, cam.width), np.zeros((1, 2), np.int32), margin)[0]
    reach = 0.05 * cam.height / cam.extent + margin
    dist = segment_distance(cam, s, cam.width, cam.height)
    assert keep[dist <= reach].all()
    assert not keep[dist > reach + slack() + np.sqrt(0.5)].any()
    # tiles: the same footprint seen through a tile at an offset
    tile = strand_footprints(cam, [s], (16, 20), np.array([[12, 9]], np.int32), margin)[0]
    assert np.array_equal(tile, keep[9:25, 12:32])
    # the samples taken a few at a time: the same footprint
    import hairlut.render._trim as trim

    monkeypatch.setattr(trim, "CHUNK", 7)
    assert np.array_equal(strand_footprints(cam, [s], (cam.height, cam.width), np.zeros((1, 2), np.int32), margin)[0], keep)


def test_texel_margins_are_two_texels_and_at_least_a_pixel():
    from hairlut.render._trim import MARGIN_TEXELS

    cam = ortho(w=40, h=40, extent=4.0)  # 10 pixels a unit
    t, u = np.meshgrid(np.linspace(0.0, 3.0, 7), np.linspace(0.0, 1.0, 11), indexing="ij")
    grid = np.stack([u, t, np.zeros_like(t)], -1)  # texels 0.5 apart along t, 0.1 along u
    m = texel_margins(cam, np.stack([grid[None], 0.01 * grid[None]]))
    assert MARGIN_TEXELS == 2.0 and m[0] == pytest.approx(10.0) and m[1] == 1.0


def test_alpha_outside_counts_the_alpha_off_the_dilated_silhouette():
    b = np.zeros((32, 32, 4))
    b[10:20, 10:20, 3] = 0.5
    a = np.zeros((32, 32, 4))
    a[10:20, 10:20, 3] = 0.3  # on the silhouette
    a[5, 14, 3] = 0.2  # 5 pixels above it: outside the 3-pixel dilation
    a[8, 14, 3] = 0.2  # 2 pixels above it: inside
    a[7, 7, 3] = 0.2  # diagonal, 3√2 > 3 pixels from the corner: outside (a disc, not a square)
    total = 100 * 0.3 + 3 * 0.2
    assert alpha_outside(a, b) == pytest.approx(0.4 / total)
    assert alpha_outside(a, b, pixels=0) == pytest.approx(0.6 / total)
    assert alpha_outside(np.zeros_like(a), b) is None
    fig, _ = compare(a.astype(np.float32), b.astype(np.float32), flip=False)
    assert fig["alpha_outside"] == pytest.approx(0.4 / total, rel=1e-6)
    fig, _ = compare(np.zeros_like(a), b, flip=False)
    assert fig["alpha_outside"] is None and "zero everywhere" in fig["alpha_outside_undefined"]


def test_trim_inputs_are_checked():
    from hairlut.render import plan_fragments

    cam = ortho()
    s = Strands.from_list([np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.0]])])
    with pytest.raises(errors.ValidationError, match="thickness"):
        strand_footprints(cam, [s], (8, 8), np.zeros((1, 2), np.int32), 1.0)
    s = Strands.from_list([np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.0]])], thickness=[np.full(2, 0.01)])
    with pytest.raises(errors.ValidationError, match="one Strands per cluster"):
        strand_footprints(cam, [s], (8, 8), np.zeros((2, 2), np.int32), 1.0)
    with pytest.raises(errors.ValidationError, match="margin"):
        strand_footprints(cam, [s], (8, 8), np.zeros((1, 2), np.int32), -1.0)
    verts = np.array([[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [-0.5, 0.5, 0.0], [0.5, 0.5, 0.0]])
    from hairlut.geometry.mesh import grid_triangles

    uv = np.array([[0.1, 0.1], [0.9, 0.1], [0.1, 0.9], [0.9, 0.9]])
    with pytest.raises(errors.ValidationError, match="keep"):
        plan_fragments(
            cam,
            verts[None, None],
            grid_triangles(2, 2),
            uv,
            (1, 1, 4, 4),
            tile=(30, 40),
            origins=np.zeros((1, 2), np.int32),
            keep=np.ones((1, 30, 39), bool),
        )
