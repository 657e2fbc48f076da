"""Exact SH convolution tables: known values, brute force, rotation, stability, bad input."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut import errors
from hairlut.sh import real_sh
from hairlut.shtables import SHTables, bake_sh, reference_r, resolve_recipe, specular_band_rule, write_sh_tables

PI = math.pi
Z = np.array([0.0, 0.0, 1.0])


@pytest.fixture(scope="module")
def paper():
    return bake_sh({"kernel": {"p": 49.0}})["tables"]


def lm(l, m):
    return l * l + l + m


def test_known_values_with_tangent_along_z(paper):
    rd = np.asarray(paper.rd(Z))
    expect = {
        (lm(0, 0), lm(0, 0)): PI / 4,
        (lm(1, 0), lm(1, 0)): 3 * PI / 16,
        (lm(1, 1), lm(1, 1)): 9 * PI / 32,
        (lm(1, -1), lm(1, -1)): 9 * PI / 32,
        (lm(0, 0), lm(2, 0)): -math.sqrt(5) * PI / 32,
        (lm(2, 0), lm(2, 0)): 25 * PI / 128,
        (lm(2, 1), lm(2, 1)): 15 * PI / 64,
        (lm(2, -1), lm(2, -1)): 15 * PI / 64,
        (lm(2, 2), lm(2, 2)): 75 * PI / 256,
        (lm(2, -2), lm(2, -2)): 75 * PI / 256,
    }
    for (i, j), value in expect.items():
        assert rd[i, j] == pytest.approx(value, abs=1e-12), (i, j)
        assert rd[j, i] == pytest.approx(value, abs=1e-12), (j, i)
    np.testing.assert_allclose(rd, rd.T, atol=1e-14)


@pytest.mark.parametrize("seed", range(4))
def test_matches_brute_force_off_grid(paper, seed):
    rng = np.random.default_rng(seed)
    t = rng.normal(size=3)
    t /= np.linalg.norm(t)
    tv = float(rng.uniform(0, PI))
    ref_d = reference_r(t, tv, 49.0, 2, 2, specular=False)
    ref_s = reference_r(t, tv, 49.0, 7, 2, specular=True)
    np.testing.assert_allclose(np.asarray(paper.rd(t)), ref_d, atol=1e-10)
    np.testing.assert_allclose(np.asarray(paper.rs(t, tv)), ref_s, atol=1e-10)


@pytest.mark.parametrize("tv", [0.0, PI / 2, PI, 1e-9, PI - 1e-9])
def test_edges_of_theta_v_and_poles(paper, tv):
    for t in (Z, -Z, np.array([1.0, 0, 0])):
        got = np.asarray(paper.rs(t, tv))
        assert np.all(np.isfinite(got))
        np.testing.assert_allclose(got, reference_r(t, tv, 49.0, 7, 2), atol=1e-10)


def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _sh_rotation(lmax, rot, rng):
    """Matrix D with Y(R d) = D Y(d), fitted by least squares on random directions (exact for a rotation)."""
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    y = np.asarray(real_sh(lmax, d))
    yr = np.asarray(real_sh(lmax, d @ rot.T))
    return np.linalg.lstsq(y, yr, rcond=None)[0].T


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_rotation_equivariance(paper, seed):
    rng = np.random.default_rng(seed)
    rot = _rotation(rng)
    t = rng.normal(size=3)
    t /= np.linalg.norm(t)
    tv = float(rng.uniform(0, PI))
    d_light = _sh_rotation(7, rot, rng)
    d_trans = d_light[:9, :9]
    # R(R t) = D_light R(t) D_trans^T  (the kernel only depends on ω·t)
    for got, base, dl in ((paper.rd(rot @ t), paper.rd(t), d_light[:9, :9]), (paper.rs(rot @ t, tv), paper.rs(t, tv), d_light)):
        np.testing.assert_allclose(np.asarray(got), dl @ np.asarray(base) @ d_trans.T, atol=1e-9)


def random_vertices(rng, n):
    """Light (64, RGB), transmittance (n, 9), unit tangents (n, 3) and θ′ (n,)."""
    t = rng.normal(size=(n, 3))
    return rng.normal(size=(64, 3)), rng.normal(size=(n, 9)), t / np.linalg.norm(t, axis=1, keepdims=True), rng.uniform(0, PI, n)


def test_contract_and_radiance_match_the_tables(paper, rng):
    a, b, t, tv = random_vertices(rng, 5)
    c = paper.contract(a)
    rd = np.asarray(paper.rd(t))
    rs = np.asarray(paper.rs(t, tv))
    cd = np.einsum("ic,tij->tjc", a[:9], rd)
    cs = np.einsum("ic,tij->tjc", a, rs)
    np.testing.assert_allclose(np.asarray(c.cd(t)), cd, atol=1e-12)
    np.testing.assert_allclose(np.asarray(c.cs(t, tv)), cs, atol=1e-12)
    expect = np.einsum("tj,tjc->tc", b, 0.7 * cd + 0.3 * cs)
    np.testing.assert_allclose(np.asarray(paper.radiance(a, b, t, tv, kd=0.7, ks=0.3)), expect, atol=1e-12)
    single = paper.radiance(a[:, 0], b, t, tv, kd=0.7, ks=0.3)
    assert single.shape == (5,)


@pytest.mark.parametrize("p", [1.0, 2.5, 10.0, 100.0, pytest.param(1000.0, marks=pytest.mark.slow)])
def test_exponents_from_1_to_1000(p, rng):
    res = bake_sh({"kernel": {"p": p}, "bands": {"light_specular": "auto"}})
    tables, info = res["tables"], res["info"]
    assert tables.bands.light_specular == math.ceil(math.sqrt(p)) + 1
    assert info["chebyshev_tail"] < 1e-12 or p == 2.5  # fractional p converges algebraically
    t = rng.normal(size=3)
    t /= np.linalg.norm(t)
    for tv in (0.0, float(rng.uniform(0, PI)), PI):
        got = np.asarray(tables.rs(t, tv))
        assert np.all(np.isfinite(got))
        ref = reference_r(t, tv, p, tables.bands.light_specular - 1, 2, n_theta=400)
        np.testing.assert_allclose(got, ref, atol=1e-10 * max(1.0, np.abs(ref).max()))
    assert 0 <= info["truncation_error"] < 1


def test_band_rule_and_truncation_error_fall_with_more_bands():
    assert [specular_band_rule(p) for p in (1, 4, 49, 50, 1000)] == [2, 3, 8, 9, 33]
    errs = [
        bake_sh({"kernel": {"p": 49.0, "diffuse": False}, "bands": {"light_specular": n}})["info"]["truncation_error"]
        for n in (4, 8, 12)
    ]
    assert errs[0] > errs[1] > errs[2]


def test_float32_gap_is_bounded(paper, rng):
    t = rng.normal(size=(50, 3))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    tv = rng.uniform(0, PI, 50)
    exact = np.asarray(paper.rs(t, tv))
    f32 = exact.astype(np.float32).astype(np.float64)
    assert np.abs(f32 - exact).max() <= 1e-7 * np.abs(exact).max()


def test_asset_round_trip_is_exact(tmp_path, paper):
    res = bake_sh({"kernel": {"p": 49.0}, "dense": {"t_resolution": 3, "theta_v_steps": 5}})
    path = write_sh_tables(tmp_path / "sh.h5", res["tables"], res["info"], res["dense"])
    back = SHTables.load(path)
    t = np.array([0.6, 0.0, 0.8])
    np.testing.assert_array_equal(np.asarray(back.rd(t)), np.asarray(res["tables"].rd(t)))
    np.testing.assert_allclose(np.asarray(back.rs(t, 0.7)), np.asarray(res["tables"].rs(t, 0.7)), atol=1e-15)
    dense = res["dense"]
    np.testing.assert_allclose(dense["rs"][4, 2], np.asarray(paper.rs(dense["t_dirs"][4], dense["theta_v"][2])), atol=1e-13)


@pytest.mark.parametrize(
    "recipe, field",
    [
        ({"kernel": {"p": 0}}, "kernel.p"),
        ({"kernel": {"p": -3.0}}, "kernel.p"),
        ({"kernel": {"p": float("nan")}}, "kernel.p"),
        ({"bands": {"light_diffuse": 0}}, "bands.light_diffuse"),
        ({"bands": {"light_specular": "many"}}, "bands.light_specular"),
        ({"bands": {"transmittance": 2.5}}, "bands.transmittance"),
        ({"kernel": {"diffuse": False, "specular": False}}, "kernel"),
        ({"kernel": {"pp": 3}}, "kernel.pp"),
        ({"dense": {"t_resolution": -1}}, "dense.t_resolution"),
    ],
)
def test_bad_recipes_name_the_key(recipe, field):
    with pytest.raises(errors.ValidationError) as info:
        resolve_recipe(recipe)
    assert info.value.field == field


def test_bad_queries(paper):
    with pytest.raises(errors.ValidationError, match="t"):
        paper.rd(np.array([0.0, 0.0, 2.0]))
    with pytest.raises(errors.ValidationError):
        paper.rd(np.array([0.0, 0.0, 0.0]))
    with pytest.raises(errors.ValidationError):
        paper.rd(np.array([np.nan, 0.0, 1.0]))
    with pytest.raises(errors.ValidationError, match="theta_v"):
        paper.rs(Z, 4.0)
    with pytest.raises(errors.ValidationError, match="theta_v"):
        paper.rs(Z, np.nan)
    with pytest.raises(errors.ValidationError, match="a="):
        paper.contract(np.ones(9))
    with pytest.raises(errors.ValidationError, match="b="):
        paper.radiance(np.ones(64), np.ones(4), Z, 0.5)


def test_float32_radiance_is_close(paper, rng):
    a, b, t, tv = random_vertices(rng, 200)
    c = paper.contract(a)
    exact = np.asarray(c.radiance(b, t, tv, 0.5, 0.5))
    fast = np.asarray(c.radiance(b, t, tv, 0.5, 0.5, dtype="float32"))
    assert fast.dtype == np.float32
    assert np.abs(fast - exact).max() <= 1e-5 * np.abs(exact).max()
    with pytest.raises(errors.ValidationError, match="dtype"):
        c.radiance(b, t, tv, dtype="float16")


@pytest.mark.parametrize("n", [129, 500, 2001])
def test_newton_gauss_legendre_is_exact_to_degree_2n_minus_1(n):
    """The O(n²) rule used above 128 nodes (exponents up to 10⁶ need thousands) integrates every
    Legendre polynomial of degree ≤ 2n − 1 exactly: Σ w P_j(x) = 2 δ_j0, and matches leggauss."""
    from numpy.polynomial import legendre

    from hairlut.shtables._zonal import gauss_legendre_newton

    x, w = gauss_legendre_newton(n)
    moments = legendre.legvander(x, 2 * n - 1).T @ w
    expect = np.zeros(2 * n)
    expect[0] = 2.0
    assert np.all(np.diff(x) > 0) and np.abs(moments - expect).max() < 1e-14
    x0, w0 = np.polynomial.legendre.leggauss(n)
    assert np.abs(x - x0).max() < 1e-15 and np.abs(w - w0).max() < 1e-10 * w0.max()


def test_truncation_error_at_the_largest_exponent_is_finite():
    from hairlut.budget import MAX_EXPONENT
    from hairlut.shtables import band_truncation_error

    err = band_truncation_error(MAX_EXPONENT, specular_band_rule(49.0))
    assert np.isfinite(err) and 0.0 < err <= 1.0
