"""Opacity shadow maps (kim thesis §6.2): analytic slab, monotonicity, Beer–Lambert step and slice
independence, rotation equivariance, an exact brute-force column integral, input validation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut import errors
from hairlut.geometry import Strands
from hairlut.shadows import OpacityMaps, light_frame, opacity_shadow_maps


def _hair(seed=7, n=60, v=12):
    """Random-walk strands hanging from a unit disk (y-up), roughly 3 units long."""
    rng = np.random.default_rng(seed)
    root = np.c_[rng.uniform(-1, 1, n), np.zeros(n), rng.uniform(-1, 1, n)]
    steps = rng.normal(0, 0.12, (n, v - 1, 3)) + np.array([0.0, -0.25, 0.0])
    pts = root[:, None, :] + np.concatenate([np.zeros((n, 1, 3)), np.cumsum(steps, axis=1)], axis=1)
    return Strands.from_padded(pts)


def _grid_of_strands(n=16, pitch=0.1, length=1.0, v=9):
    """n × n straight strands along z (the light is +z), centred in cells of ``pitch``, plus two
    vanishingly short guard strands at the cell grid's corners so that texel edges fall between strands."""
    c = (np.arange(n) + 0.5) * pitch
    x, y = np.meshgrid(c, c, indexing="ij")
    z = np.linspace(0.0, length, v)
    lines = [np.c_[np.full(v, xi), np.full(v, yi), z] for xi, yi in zip(x.ravel(), y.ravel())]
    guard = np.c_[np.zeros(v), np.zeros(v), np.linspace(0, 1e-12, v)]
    lines += [guard, guard + [n * pitch, n * pitch, 0.0]]
    return Strands.from_list(lines)


# -- (1) analytic slab ---------------------------------------------------------------------------
def test_uniform_grid_along_light_gives_linear_opacity():
    n, pitch, kappa, width = 16, 0.1, 0.7, 0.02
    s = _grid_of_strands(n, pitch)
    m = opacity_shadow_maps(s, [0, 0, 1], n_slices=8, resolution=8, kappa=kappa, width=width)
    assert isinstance(m, OpacityMaps) and m.shape == (8, 11, 11)  # 8 texels + 1 padding each side (+1 edge)
    np.testing.assert_allclose(m.light, [0, 0, 1], atol=1e-15)
    rho = width / pitch**2  # projected fibre area per unit area per unit depth
    # every full texel holds 2 × 2 strands: Ω_i = ρ × (depth of slice i below the top)
    depth_below_top = m.depths - m.near
    np.testing.assert_allclose(m.maps[:, 1:9, 1:9], rho * depth_below_top[:, None, None] * np.ones((8, 8)), rtol=1e-9)
    # interior points at any depth: τ = exp(−κ ρ d) (bilinear and depth interpolation exact for a uniform slab)
    rng = np.random.default_rng(0)
    p = np.c_[rng.uniform(0.2, 1.4, (200, 2)), rng.uniform(0.0, 1.0, 200)]
    d = 1.0 - p[:, 2]
    np.testing.assert_allclose(m.at(p), np.exp(-kappa * rho * d), rtol=1e-9, atol=1e-12)


def test_total_deposit_equals_length_times_width():
    s = _hair()
    m = opacity_shadow_maps(s, [0.2, 1.0, -0.4], n_slices=5, resolution=24, width=0.3)
    assert m.maps[-1].sum() * m.spacing**2 == pytest.approx(0.3 * s.lengths().sum(), rel=1e-12)
    assert np.all(np.diff(m.maps, axis=0) >= 0)


# -- (2) in front / outside / monotone -----------------------------------------------------------
def test_in_front_and_outside_are_unshadowed_and_tau_decreases_with_depth():
    s = _hair()
    light = np.array([0.3, 1.0, 0.1])
    m = opacity_shadow_maps(s, light, n_slices=12, resolution=32, kappa=0.2)
    ld = light / np.linalg.norm(light)
    # in front of all hair (nearer the light than D_0) and far off to the side
    np.testing.assert_array_equal(m.at(s.points + 10 * ld), 1.0)
    side = m.frame[0] * 20
    np.testing.assert_array_equal(m.at(s.points + side), 1.0)
    tau = m.at(s.points)
    assert np.all((tau >= 0) & (tau <= 1)) and tau.min() < 0.5
    # along rays away from the light τ never increases, and behind everything it is constant
    t = np.linspace(-12, 8, 90)
    rays = s.points[::7, None, :] - t[None, :, None] * ld
    tr = m.at(rays.reshape(-1, 3)).reshape(rays.shape[:2])
    assert np.all(tr[:, 0] == 1.0) and tr[:, -1].max() < 1
    assert np.all(np.diff(tr, axis=1) <= 1e-12 * tr[:, 1:])  # (x, y) along a ray move by rounding only
    np.testing.assert_allclose(tr[:, -1], tr[:, -2], rtol=1e-12)


# -- (3) Beer–Lambert: sampling step and slice count -----------------------------------------------
def test_opacity_is_independent_of_step_and_slice_count():
    s = _hair()
    light, kw = [0.5, 1.0, 0.3], dict(resolution=24, kappa=0.03)
    base = opacity_shadow_maps(s, light, n_slices=16, **kw)  # default spacing: min(texel, slice) / 4
    step = 0.25 * min(base.spacing, base.depths[0] - base.near)
    ref = base.at(s.points)
    fine = opacity_shadow_maps(s, light, n_slices=16, spacing=step / 2, **kw).at(s.points)
    slices = opacity_shadow_maps(s, light, n_slices=32, spacing=step, **kw).at(s.points)
    assert ref.min() < 0.1 and 0.4 < ref.mean() < 0.8  # the test hair does cast shadows
    # pieces that change texel move Ω locally; linear interpolation within a slice errs by up to the
    # slice's own increment (strands running along the light), but neither biases τ
    for other, tol_max, tol_rms in ((fine, 0.06, 0.015), (slices, 0.2, 0.03)):
        d = other - ref
        assert np.abs(d).max() < tol_max and np.sqrt((d**2).mean()) < tol_rms and abs(d.mean()) < 0.005
    # a per-sample alpha would double Ω with twice the samples; a length deposit keeps its total
    a = opacity_shadow_maps(s, light, n_slices=16, spacing=step, **kw).maps[-1].sum()
    b = opacity_shadow_maps(s, light, n_slices=16, spacing=step / 2, **kw).maps[-1].sum()
    assert a == pytest.approx(b, rel=1e-12)


# -- (4) rotation equivariance ---------------------------------------------------------------------
@settings(max_examples=12)
@given(st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda q: np.linalg.norm(q) > 0.2))
def test_rotating_hair_light_and_up_together_leaves_tau_unchanged(q):
    w, x, y, z = np.asarray(q) / np.linalg.norm(q)
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    s = _hair(n=30, v=8)
    light, up = np.array([0.4, 1.0, -0.2]), np.array([0.0, 0.0, 1.0])
    kw = dict(n_slices=8, resolution=16, kappa=0.5)
    a = opacity_shadow_maps(s, light, up=up, **kw)
    b = opacity_shadow_maps(Strands(s.points @ R.T, s.counts), R @ light, up=R @ up, **kw)
    np.testing.assert_allclose(b.frame, a.frame @ R.T, atol=1e-12)
    probe = np.concatenate([s.points, s.points + 0.05])
    np.testing.assert_allclose(b.at(probe @ R.T), a.at(probe), atol=1e-9)


# -- (5) brute force: exact hair length in each query's texel column, nearer the light ---------------
def _column_length(a, b, box_lo, box_hi):
    """Length of every segment a→b (E, 3), in the light frame, inside the axis-aligned box (Liang–Barsky)."""
    d = b - a
    t0, t1 = np.zeros(len(a)), np.ones(len(a))
    for k in range(3):
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (box_lo[k] - a[:, k]) / d[:, k], (box_hi[k] - a[:, k]) / d[:, k]
        par = d[:, k] == 0
        inside = (a[:, k] >= box_lo[k]) & (a[:, k] < box_hi[k])
        lo_k = np.where(par, np.where(inside, 0.0, np.inf), np.minimum(ta, tb))
        hi_k = np.where(par, np.where(inside, 1.0, -np.inf), np.maximum(ta, tb))
        t0, t1 = np.maximum(t0, lo_k), np.minimum(t1, hi_k)
    return np.clip(t1 - t0, 0, None) * np.linalg.norm(d, axis=1)


def test_matches_brute_force_column_integral():
    s = _hair(seed=3, n=80)
    light = np.array([-0.3, 1.0, 0.5])
    m = opacity_shadow_maps(s, light, n_slices=10, resolution=12, spacing=0.005)
    seg = s.segments
    qa, qb = s.points[seg[:, 0]] @ m.frame.T, s.points[seg[:, 1]] @ m.frame.T
    h = m.spacing
    piece = 0.005 / h**2  # Ω of one piece; a piece cut by a column side or the depth cap lands on one side
    rng = np.random.default_rng(5)
    _, H, W = m.shape
    hits = 0
    for _ in range(40):
        i, j = int(rng.integers(1, W - 1)), int(rng.integers(1, H - 1))
        k = int(rng.integers(0, m.shape[0]))
        lo = np.array([m.origin[0] + i * h, m.origin[1] + j * h, -np.inf])
        exact = [_column_length(qa, qb, lo, np.r_[lo[:2] + h, z]).sum() / h**2 for z in (m.near, *m.depths)]
        centre = np.array([lo[0] + h / 2, lo[1] + h / 2, m.depths[k]])
        got = m.opacity((centre @ m.frame)[None])[0]  # light frame back to world
        assert abs(got - exact[k + 1]) <= 6 * piece + 1e-9
        hits += exact[k + 1] > 0
        # between slices Ω lies between the two bracketing column integrals
        mid = centre - [0, 0, 0.37 * (m.depths[0] - m.near)]
        between = m.opacity((mid @ m.frame)[None])[0]
        assert exact[k] - 6 * piece <= between <= exact[k + 1] + 6 * piece
    assert hits > 10


# -- (6) validation --------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(light=[0, 0, 0]), "light"),
        (dict(light=[np.nan, 1, 0]), "light"),
        (dict(light=[1, 0]), "light"),
        (dict(n_slices=0), "n_slices"),
        (dict(n_slices=2.5), "n_slices"),
        (dict(resolution=0), "resolution"),
        (dict(resolution=True), "resolution"),
        (dict(kappa=-1.0), "kappa"),
        (dict(kappa=np.inf), "kappa"),
        (dict(spacing=0.0), "spacing"),
        (dict(width=-1.0), "width"),
        (dict(up=[0, 2, 0]), "up"),
        (dict(strands="hair"), "strands"),
        (dict(strands=Strands(np.zeros((0, 3)), np.zeros(0, int))), "strands"),
    ],
)
def test_bad_inputs_name_the_field(kwargs, field):
    args = dict(strands=_hair(n=4, v=4), light=[0, 1, 0])
    args.update(kwargs)
    with pytest.raises(errors.ValidationError) as info:
        opacity_shadow_maps(args.pop("strands"), args.pop("light"), **args)
    assert info.value.field == field


def test_bad_query_points_and_default_frame():
    m = opacity_shadow_maps(_hair(n=4, v=4), [0, 1, 0], resolution=4)
    with pytest.raises(errors.ValidationError) as info:
        m.at(np.zeros((3, 2)))
    assert info.value.field == "points"
    f = light_frame([0, 1, 0])  # vertical light: the default up falls back to +z
    np.testing.assert_allclose(f @ f.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(f) == pytest.approx(1.0)
