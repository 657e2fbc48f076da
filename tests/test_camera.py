"""[camera]: bad input names its key; the 4 × 4 world-to-clip matrix against the camera's own projection."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hairlut import errors
from hairlut.recipes import resolve
from hairlut.scene import CAMERA, check_camera, frame_bytes, make_camera, resolve_scene

BASE = {
    "camera": {"view": [0.0, 0.0, 1.0]},
    "lights": {"directions": [[0.0, 1.0, 0.0]]},
    "clusters": [{"trajectory": [[0, 0, 0], [0, 1, 0], [0, 2, 0]], "half_axis_a": 0.2, "half_axis_b": 0.2}],
}
BOX = np.array([[x, y, z] for x in (-1, 1) for y in (-2, 2) for z in (-0.5, 0.5)], float)


def _scene(**cam):
    return resolve_scene({**BASE, "camera": {"view": [0.0, 0.0, 1.0], **cam}})


def _cam(**keys):
    c = resolve(CAMERA, {"view": [0.0, 0.0, 1.0], **keys}, "camera.")
    check_camera(c)
    return c


@pytest.mark.parametrize(
    "cam, key",
    [
        ({"view": [0.0, 0.0, 0.0]}, "camera.view"),
        ({"view": [float("nan"), 0.0, 1.0]}, "camera.view"),
        ({"up": [0.0, 0.0, 2.0]}, "camera.up"),
        ({"fov": 0.0}, "camera.fov"),
        ({"fov": 180.0}, "camera.fov"),
        ({"resolution": [0, 768]}, "camera.resolution"),
        ({"resolution": [768]}, "camera.resolution"),
        ({"resolution": [16384, 16384]}, "camera.resolution"),
        ({"projection": "fisheye"}, "camera.projection"),
        ({"extent": -1.0}, "camera.extent"),
        ({"position": [0.0, 1.0], "look_at": [0.0, 0.0, 0.0]}, "camera.position"),
        ({"position": [1.0, 0.0, 5.0], "look_at": [0.0, 0.0, 0.0]}, "camera.position"),
        ({"lens": 35}, "camera.lens"),
    ],
)
def test_bad_camera_names_the_key(cam, key):
    with pytest.raises(errors.ValidationError) as exc:
        _scene(**cam)
    assert exc.value.field == key


def test_too_large_a_frame_is_refused_with_the_figure(monkeypatch):
    monkeypatch.setenv("HAIRLUT_MEMORY_LIMIT", "4G")
    with pytest.raises(errors.BudgetError, match=r"GiB.*4 GiB.*HAIRLUT_MEMORY_LIMIT") as exc:
        _scene(resolution=[8192, 8192])
    assert exc.value.field == "camera.resolution"
    assert frame_bytes(8192, 8192) > 2 * 2**30


def test_defaults():
    cfg = _scene().config["camera"]
    assert cfg["projection"] == "orthographic" and cfg["resolution"][0] >= 768 and cfg["resolution"][1] >= 768


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_camera_inside_the_hair_is_refused(projection):
    with pytest.raises(errors.ValidationError) as exc:
        make_camera(_cam(projection=projection, position=[0.0, 0.0, 0.2], look_at=[0.0, 0.0, 0.0]), BOX)
    assert exc.value.field == "camera.position"


@given(
    view=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: 0.1 < np.linalg.norm(v) and abs(v[1]) < 0.95 * np.linalg.norm(v)),
    pts=st.lists(st.tuples(*[st.floats(-1, 1)] * 3), min_size=1, max_size=5),
    projection=st.sampled_from(["orthographic", "perspective"]),
    fov=st.floats(10, 120),
)
def test_matrix_agrees_with_rays(view, pts, projection, fov):
    """A point on the ray through pixel (x, y) projects, through the 4 × 4 matrix, back to (x, y); every
    fitted point lies in the frame (NDC within [-1, 1])."""
    cam = make_camera(_cam(view=list(view), projection=projection, fov=fov), BOX)
    x, y, _ = cam.project(BOX)
    assert (x >= 0).all() and (x <= cam.width).all() and (y >= 0).all() and (y <= cam.height).all()
    p = np.array(pts) * [cam.width, cam.height, 1] * 0.5 + [cam.width / 2, cam.height / 2, 0]
    o, d = cam.rays(p[:, 0], p[:, 1])
    world = o + d * (1.0 + np.abs(p[:, 2:]))
    clip = np.c_[world, np.ones(len(world))] @ cam.matrix.T
    ndc = clip[:, :2] / clip[:, 3:]
    assert np.allclose((ndc[:, 0] + 1) / 2 * cam.width, p[:, 0], atol=1e-6 * cam.width)
    assert np.allclose((1 - ndc[:, 1]) / 2 * cam.height, p[:, 1], atol=1e-6 * cam.height)
    assert math.isclose(np.linalg.norm(d[0]), 1.0, rel_tol=1e-9)


def test_view_is_derived_from_position_and_look_at():
    """Issue 29 m15: a camera with ``position`` and ``look_at`` needs no ``view``: it is the unit direction from
    look_at to the eye (and the scene's view, the online maps' angle, is that one)."""
    sc = resolve_scene({**BASE, "camera": {"projection": "perspective", "position": [3.0, 1.0, 4.0], "look_at": [0.0, 1.0, 0.0]}})
    assert np.allclose(sc.view, [0.6, 0.0, 0.8], rtol=0, atol=1e-15)
    assert np.allclose(sc.config["camera"]["view"], [0.6, 0.0, 0.8], rtol=0, atol=1e-15)
    cam = make_camera(sc.config["camera"], BOX)
    assert np.allclose(cam.eye, [3.0, 1.0, 4.0]) and np.allclose(cam.back, [0.6, 0.0, 0.8])
    # the same with a given view that agrees (any length), and coordinates near the float64 limit (no overflow)
    agree = resolve_scene({**BASE, "camera": {"view": [6.0, 0.0, 8.0], "position": [3.0, 1.0, 4.0], "look_at": [0.0, 1.0, 0.0]}})
    assert np.allclose(agree.view, sc.view)
    far = resolve_scene({**BASE, "camera": {"position": [1e308, 0.0, 1e308], "look_at": [-1e308, 0.0, -1e308]}})
    assert np.allclose(far.view, [2**-0.5, 0.0, 2**-0.5])


@pytest.mark.parametrize(
    "cam, key, words",
    [
        (
            {"position": [3.0, 1.0, 4.0], "look_at": [0.0, 1.0, 0.0], "view": [0.0, 0.0, 1.0]},
            "camera.position",
            ["camera.view [0.0, 0.0, 1.0]", "look_at [0.0, 1.0, 0.0]"],
        ),
        ({"position": [1.0, 1.0, 1.0], "look_at": [1.0, 1.0, 1.0]}, "camera.position", ["equals camera.look_at"]),
        ({"position": [1.0, 1.0, 1.0]}, "camera.view", ["missing required key", "camera.position and camera.look_at"]),
        ({"look_at": [1.0, 1.0, 1.0]}, "camera.view", ["missing required key"]),
        ({"position": [1.0, float("inf"), 1.0], "look_at": [0.0, 0.0, 0.0]}, "camera.position", ["finite"]),
    ],
)
def test_view_position_and_look_at_refusals_name_the_keys(cam, key, words):
    with pytest.raises(errors.ValidationError) as exc:
        resolve_scene({**BASE, "camera": cam})
    assert exc.value.field == key and all(w in str(exc.value) for w in words), str(exc.value)


@pytest.mark.parametrize(
    "keys, key",
    [
        ({"projection": "perspective", "fov": 1e-6}, "camera.fov"),  # the fitted eye stands ~1e8 radii away
        ({"projection": "perspective", "position": [0.0, 0.0, 1e12], "look_at": [0.0, 0.0, 0.0]}, "camera.position"),
        ({"position": [0.0, 0.0, 1e12], "look_at": [0.0, 0.0, 0.0]}, "camera.position"),
        ({"look_at": [1e9, 0.0, 0.0]}, "camera.look_at"),
        ({"extent": 1e-30}, "camera.extent"),  # a pixel 1e-32 wide
    ],
)
def test_a_camera_float32_cannot_draw_is_refused_naming_the_key(keys, key):
    """Issue 29 N2: where float32 (both renderers' precision) would lose the hair (its step at the eye's distance
    above 1/16 of the thinnest strand's radius, or a pixel narrower than 16 steps), the camera is refused naming
    the key and its value (fov 1e-6 and a position 1e12 away crashed the layered render, or drew nothing)."""
    with pytest.raises(errors.ValidationError) as exc:
        make_camera(_cam(**keys), BOX, detail=0.01)
    assert exc.value.field == key and "float32" in str(exc.value)


def test_the_float32_reach_is_where_the_step_is_a_sixteenth_of_the_detail():
    """The eye may stand up to detail / (16 ε₃₂) from the farthest hair (BOX's farthest point from the eye on the
    +z axis is 0.5 nearer than its distance, at (±1, ±2, −0.5)): just inside accepted, just outside refused."""
    detail = 1e-3
    reach = detail / (16 * float(np.finfo(np.float32).eps))
    far = lambda d: math.sqrt(1 + 4 + (d + 0.5) ** 2)  # noqa: E731
    inside, outside = reach * 0.999 - 0.5, reach * 1.001 - 0.5
    assert far(inside) < reach < far(outside)
    for projection in ("orthographic", "perspective"):
        cam = make_camera(_cam(projection=projection, position=[0.0, 0.0, inside], look_at=[0.0, 0.0, 0.0]), BOX, detail)
        assert cam.eye[2] == pytest.approx(inside)
        with pytest.raises(errors.ValidationError, match="camera.position"):
            make_camera(_cam(projection=projection, position=[0.0, 0.0, outside], look_at=[0.0, 0.0, 0.0]), BOX, detail)


@pytest.mark.parametrize("keys", [{"extent": 1e30}, {"projection": "perspective", "fov": 179.9999}])
def test_a_camera_that_shrinks_the_hair_below_a_pixel_is_legal(keys):
    """A frame that catches no hair is a correct (empty) frame, not a refusal: the hair projects within a pixel
    of the frame's centre."""
    cam = make_camera(_cam(**keys), BOX, detail=0.01)
    x, y, _ = cam.project(BOX)
    assert np.abs(x - cam.width / 2).max() < 1 and np.abs(y - cam.height / 2).max() < 1
