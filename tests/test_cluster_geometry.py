"""Generalized disk clusters (satf §3): splines, frames, positions, meshes, macro-clusters, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline as SciBSpline

from hairlut.errors import ValidationError
from hairlut.geometry import BSpline, ClusterBatch, ClusterGeometry, ClusterSpec, MacroCluster, fit_bspline, layer_meshes
from hairlut.geometry._bspline import uniform_knots


def clamped(n, p=3):
    return np.concatenate([np.zeros(p + 1), np.linspace(0, 1, n - p + 1)[1:-1], np.ones(p + 1)])


# an S-shaped planar trajectory (x–z plane) with an inflection in the middle
S_CURVE = np.array([[0, 0, 0], [1, 0, 1.5], [2, 0, 1.5], [3, 0, 0], [4, 0, -1.5], [5, 0, -1.5], [6, 0, 0]], float)


# -- B-splines -----------------------------------------------------------------------------------
def test_bspline_matches_scipy_values_and_derivatives(rng):
    for n, p in [(4, 3), (7, 3), (5, 2), (2, 1)]:
        ctrl = rng.normal(size=(n, 3))
        knots = np.sort(np.concatenate([np.zeros(p + 1), rng.uniform(0, 1, n - p - 1), np.ones(p + 1)]))
        ours = BSpline.make(ctrl, knots, p, dim=3)
        ref = SciBSpline(knots, ctrl, p)
        x = np.linspace(0, 1, 57)
        for d in range(p + 1):
            np.testing.assert_allclose(ours(x, d), ref(x, nu=d), atol=1e-9 * max(1, np.abs(ref(x, nu=d)).max()))


def test_unclamped_uniform_bspline_matches_scipy(rng):
    ctrl = rng.normal(size=(8, 3))
    knots = uniform_knots(8, 3)
    x = np.linspace(0, 1, 41)
    np.testing.assert_allclose(BSpline.make(ctrl, knots, dim=3)(x), SciBSpline(knots, ctrl, 3)(x), atol=1e-12)


def test_fit_bspline_reproduces_a_cubic():
    x = np.linspace(0, 1, 40)
    y = 1 + 2 * x - 3 * x**2 + 0.5 * x**3
    np.testing.assert_allclose(fit_bspline(x, y, 5)(x)[:, 0], y, atol=1e-12)


# -- positions -----------------------------------------------------------------------------------
def test_straight_cylinder_positions_are_analytic():
    # colinear but unevenly spaced control points: only an arc-length parametrisation gives z = L·t
    a_ctrl, b_ctrl, q_ctrl = [0.5, 0.9, 0.7, 0.6], [0.4, 0.3, 0.5], [0.0, 1.0, 3.0]
    spec = ClusterSpec([[0, 0, 0], [0, 0, 0.5], [0, 0, 4], [0, 0, 5], [0, 0, 8]], a_ctrl, b_ctrl, q_ctrl, normal0=[1, 0, 0])
    geom = ClusterGeometry(spec)
    assert geom.lengths[0] == pytest.approx(8.0, rel=1e-12)
    t, v, u = np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 4), np.linspace(0, 2 * np.pi, 7), indexing="ij")
    a = SciBSpline(clamped(4), np.array(a_ctrl), 3)(t)
    b = SciBSpline(clamped(3, 2), np.array(b_ctrl), 2)(t)
    q = SciBSpline(clamped(3, 2), np.array(q_ctrl), 2)(t)
    want = np.stack([a * v * np.cos(q + u), b * v * np.sin(q + u), 8.0 * t], axis=-1)
    np.testing.assert_allclose(geom.positions(t, v, u)[0], want, atol=1e-10)
    sec = geom.sections(np.linspace(0, 1, 5))
    np.testing.assert_allclose(sec.tangent[0], np.tile([0, 0, 1.0], (5, 1)), atol=1e-12)
    np.testing.assert_allclose(sec.normal[0], np.tile([1.0, 0, 0], (5, 1)), atol=1e-12)
    np.testing.assert_allclose(sec.binormal[0], np.tile([0, 1.0, 0], (5, 1)), atol=1e-12)


def test_positions_of_matches_positions_and_derivatives_match_differences(rng):
    specs = [ClusterSpec(S_CURVE + [0, 3 * i, 0], [0.3, 0.5, 0.4], [0.2, 0.3], [0, 2, 1]) for i in range(3)]
    geom = ClusterGeometry(specs)
    t, v, u = rng.uniform(0.01, 0.99, 40), rng.uniform(0, 1, 40), rng.uniform(0, 6, 40)
    cl = rng.integers(0, 3, 40)
    np.testing.assert_allclose(geom.positions_of(cl, t, v, u), geom.positions(t, v, u)[cl, np.arange(40)], atol=1e-12)
    p, pt, pu = geom.derivatives(t, v, u)
    h = 1e-5
    np.testing.assert_allclose((geom.positions(t + h, v, u) - geom.positions(t - h, v, u)) / (2 * h), pt, atol=1e-6)
    np.testing.assert_allclose((geom.positions(t, v, u + h) - geom.positions(t, v, u - h)) / (2 * h), pu, atol=1e-6)


# -- frames --------------------------------------------------------------------------------------
def _frenet_normals(ctrl, w):
    curve = SciBSpline(clamped(len(ctrl)), ctrl, 3)
    d1, d2 = curve(w, nu=1), curve(w, nu=2)
    tan = d1 / np.linalg.norm(d1, axis=1, keepdims=True)
    n = d2 - np.sum(d2 * tan, axis=1, keepdims=True) * tan
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def test_frames_orthonormal_continuous_and_never_flip_where_frenet_does():
    geom = ClusterGeometry(ClusterSpec(S_CURVE, 0.3, 0.2, normal0=[0, 1, 0]))
    t = np.linspace(0, 1, 2001)
    sec = geom.sections(t)
    tan, r, b = sec.tangent[0], sec.normal[0], sec.binormal[0]
    for vec in (tan, r, b):
        np.testing.assert_allclose(np.linalg.norm(vec, axis=1), 1.0, atol=1e-12)
    assert np.abs(np.sum(tan * r, axis=1)).max() < 1e-12
    np.testing.assert_allclose(np.cross(tan, r), b, atol=1e-12)
    # continuity: consecutive frames (Δt = 1/2000) turn by far less than a degree
    step = np.degrees(np.arccos(np.clip(np.sum(r[1:] * r[:-1], axis=1), -1, 1)))
    assert step.max() < 0.5
    # planar curve: the rotation-minimising frame keeps the plane normal, exactly, through the inflection
    np.testing.assert_allclose(r, np.tile([0, 1.0, 0], (t.size, 1)), atol=1e-9)
    # the Frenet normal of the same curve flips (turns by ~180°) at the inflection
    frenet = _frenet_normals(S_CURVE, np.linspace(0.02, 0.98, 2000))  # even count: skips w = ½, where κ = 0
    assert np.sum(frenet[1:] * frenet[:-1], axis=1).min() < -0.9


def test_frames_rotation_minimising_on_a_3d_curve():
    ctrl = S_CURVE + np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [0, 1, 0], [0, -1, 0], [0, 0, 0], [0, 1, 0]])
    geom = ClusterGeometry(ClusterSpec(ctrl, 0.3, 0.2))
    t = np.linspace(0, 1, 4001)
    sec = geom.sections(t)
    r, b = sec.normal[0], sec.binormal[0]
    dr = np.gradient(r, t, axis=0)
    # no rotation about the tangent: dr/dt has no binormal component (while r itself turns a lot)
    assert np.abs(np.sum(dr * b, axis=1)).max() < 1e-3 * np.abs(dr).max()
    assert np.abs(dr).max() > 0.5


# -- macro-clusters and batches ------------------------------------------------------------------------
def test_macro_cluster_members_are_rigid_copies(rng):
    spec = ClusterSpec(S_CURVE, [0.3, 0.5, 0.4], [0.2, 0.3], [0, 2, 1])
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    d = np.array([1.0, -2.0, 0.5])
    macro = MacroCluster(spec, np.stack([np.eye(3), q]), np.stack([np.zeros(3), d]))
    geom = ClusterGeometry(macro)
    t, v, u = rng.uniform(0, 1, 30), rng.uniform(0, 1, 30), rng.uniform(0, 6, 30)
    p = geom.positions(t, v, u)
    np.testing.assert_allclose(p[1], p[0] @ q.T + d, atol=1e-9)


def test_batch_mixes_spline_sizes_but_needs_equal_sampling(rng):
    a = ClusterSpec(S_CURVE, [0.3, 0.4, 0.2, 0.3, 0.5], 0.2, s_t=8)
    b = ClusterSpec(S_CURVE[:4] * 2, 0.3, [0.2, 0.1], [0.0, 1.0], s_t=8)  # other control counts and degrees
    both = ClusterGeometry([a, b])
    t, v, u = rng.uniform(0, 1, 20), rng.uniform(0, 1, 20), rng.uniform(0, 6, 20)
    p = both.positions(t, v, u)
    np.testing.assert_allclose(p[0], ClusterGeometry(a).positions(t, v, u)[0], atol=1e-12)
    np.testing.assert_allclose(p[1], ClusterGeometry(b).positions(t, v, u)[0], atol=1e-12)
    with pytest.raises(ValidationError) as exc:
        ClusterBatch.stack([a, ClusterSpec(S_CURVE, 0.3, 0.2, s_t=9)])
    assert exc.value.field == "specs[1]"


# -- layer meshes --------------------------------------------------------------------------------
def test_layer_meshes_lie_on_the_layers_with_outward_normals():
    spec = ClusterSpec(
        S_CURVE, [0.3, 0.5, 0.4], [0.2, 0.3], [0, 2, 1], layer_radii=(0.5, 0.8, 1.0), core_radius=0.2, s_t=6, s_u=10
    )
    geom = ClusterGeometry([spec, spec.transformed(np.eye(3), [0, 5, 0])])
    m = layer_meshes(geom, t_subdiv=2)
    rows, cols = 13, 11
    assert m.vertices.shape == (2, 3, rows * cols, 3) and m.triangles.shape == (2 * 12 * 10, 3)
    assert m.triangles.max() == rows * cols - 1
    tt, uu = np.meshgrid(np.linspace(0, 1, rows), np.linspace(0, 2 * np.pi, cols), indexing="ij")
    np.testing.assert_allclose(m.uv, np.stack([uu.ravel() / (2 * np.pi), tt.ravel()], 1))
    sec = geom.sections(tt.ravel())
    for c in range(2):
        for k, radius in enumerate(spec.layer_radii):
            rel = m.vertices[c, k] - sec.origin[c]
            x, y = np.sum(rel * sec.normal[c], 1), np.sum(rel * sec.binormal[c], 1)
            np.testing.assert_allclose(np.hypot(x / sec.a[c], y / sec.b[c]), radius, atol=1e-9)
            assert (np.sum(rel * m.normals[c, k], axis=1) > 0).all()  # outward
            tri = m.vertices[c, k][m.triangles]
            face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            assert (np.sum(face * m.normals[c, k][m.triangles].mean(axis=1), axis=1) > 0).all()  # CCW from outside
    np.testing.assert_allclose(np.linalg.norm(m.tangents, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.sum(m.tangents * m.normals, axis=-1), 0.0, atol=1e-9)


# -- properties (hypothesis) ------------------------------------------------------------------------
coords = st.floats(-2.0, 2.0, allow_nan=False)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    offsets=st.lists(st.tuples(coords, coords, coords), min_size=5, max_size=5),
    axes=st.lists(st.floats(0.05, 2.0), min_size=6, max_size=6),
    twist=st.lists(st.floats(-6, 6), min_size=3, max_size=3),
    params=st.lists(st.tuples(st.floats(0, 1), st.floats(0, 1), st.floats(0, 2 * np.pi)), min_size=16, max_size=16),
)
def test_positions_lie_within_the_layer_radii(offsets, axes, twist, params):
    ctrl = np.array([[0, 0, 3.0 * i] for i in range(5)]) + np.array(offsets)
    spec = ClusterSpec(ctrl, axes[:3], axes[3:], twist, layer_radii=(0.4, 0.7, 1.0), core_radius=0.1)
    geom = ClusterGeometry(spec)
    t, v, u = (np.array(c) for c in zip(*params))
    p = geom.positions(t, v, u)[0]
    sec = geom.sections(t)
    rel = p - sec.origin[0]
    assert np.abs(np.sum(rel * sec.tangent[0], axis=1)).max() < 1e-9 * (1 + np.abs(rel).max())  # in the normal plane
    radius = np.hypot(np.sum(rel * sec.normal[0], 1) / sec.a[0], np.sum(rel * sec.binormal[0], 1) / sec.b[0])
    np.testing.assert_allclose(radius, v, atol=1e-9)
    layer = np.searchsorted(spec.layer_radii, v)  # the layer whose shell holds v (or the core)
    bounds = np.concatenate([[spec.core_radius], spec.layer_radii])
    inside = v >= spec.core_radius
    assert (radius[inside] <= bounds[layer[inside] + 1] + 1e-9).all()
    assert (radius[inside] >= bounds[layer[inside]] - 1e-9).all()


# -- bad input -------------------------------------------------------------------------------------
GOOD = dict(trajectory=S_CURVE, half_axis_a=0.3, half_axis_b=0.2)


@pytest.mark.parametrize(
    "change, field",
    [
        (dict(trajectory={"control": S_CURVE, "knots": [0, 0, 0, 0, 0.6, 0.4, 0.8, 1, 1, 1, 1]}), "trajectory.knots"),
        (dict(half_axis_a={"control": [0.3, 0.2], "knots": [0, 0.5, 0.2, 1]}), "half_axis_a.knots"),
        (dict(half_axis_a=[0.3, -0.1, 0.2]), "half_axis_a"),
        (dict(half_axis_b=-1.0), "half_axis_b"),
        (dict(trajectory=np.where(np.arange(21).reshape(7, 3) == 4, np.nan, S_CURVE)), "trajectory"),
        (dict(trajectory=np.vstack([S_CURVE[:1], S_CURVE])), "trajectory"),
        (dict(trajectory=S_CURVE[:, :2]), "trajectory"),
        (dict(layer_radii=(0.5, 0.4, 1.0)), "layer_radii"),
        (dict(layer_radii=(0.5, 1.2)), "layer_radii"),
        (dict(core_radius=0.5, layer_radii=(0.5, 1.0)), "core_radius"),
        (dict(core_radius=-0.1), "core_radius"),
        (dict(s_t=0), "s_t"),
        (dict(s_u=0), "s_u"),
        (dict(s_v=1.5), "s_v"),
        (dict(twist=[0.0, np.inf]), "twist"),
        (dict(normal0=[2.0, 0.0, 3.0]), "normal0"),  # parallel to T′(0)
    ],
)
def test_bad_cluster_input_names_the_field(change, field):
    with pytest.raises(ValidationError) as exc:
        ClusterSpec(**(GOOD | change))
    assert exc.value.field == field


def test_bad_knots_name_the_field():
    with pytest.raises(ValidationError) as exc:
        BSpline.make(S_CURVE, knots=[0, 0, 0, 0, 0.6, 0.4, 0.8, 1, 1, 1, 1], field="trajectory", dim=3)
    assert exc.value.field == "trajectory.knots" and "non-decreasing" in exc.value.reason
    with pytest.raises(ValidationError) as exc:
        BSpline.make(
            np.vstack([S_CURVE, [[7, 0, 1]]]), knots=[0, 0, 0, 0, 0.5, 0.5, 0.5, 0.5, 1, 1, 1, 1], field="trajectory", dim=3
        )
    assert exc.value.field == "trajectory.knots" and "repeats" in exc.value.reason
    with pytest.raises(ValidationError) as exc:
        BSpline.make(S_CURVE, knots=[0, 0, 0, 0, 1, 1, 1, 1], field="trajectory", dim=3)
    assert exc.value.field == "trajectory.knots"
    with pytest.raises(ValidationError) as exc:
        BSpline.make([[0, 0, 0], [1, 1, 1]], degree=3, field="trajectory", dim=3)
    assert exc.value.field == "trajectory"


def test_bad_rigid_transform_and_queries():
    spec = ClusterSpec(**GOOD)
    with pytest.raises(ValidationError) as exc:
        MacroCluster(spec, np.diag([1.0, 1.0, -1.0])[None], np.zeros((1, 3)))
    assert exc.value.field == "rotations[0]"
    geom = ClusterGeometry(spec)
    with pytest.raises(ValidationError) as exc:
        geom.positions([0.5, np.nan], 0.5, 0.0)
    assert exc.value.field == "t"
    with pytest.raises(ValidationError) as exc:
        geom.positions_of([0, 1], 0.5, 0.5, 0.0)
    assert exc.value.field == "cluster"
    with pytest.raises(ValidationError) as exc:
        layer_meshes(geom, t_subdiv=0)
    assert exc.value.field == "t_subdiv"
