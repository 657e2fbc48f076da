"""Product quadrature, orthonormality, projection and evaluation."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut.errors import ValidationError
from hairlut.sh import (
    GaussLegendreGrid,
    evaluate,
    n_coeffs,
    project,
    project_function,
    real_sh,
    real_sh_reference,
    sphere_grid,
)


def monomial_integral(a: int, b: int, c: int) -> float:
    """∫_{S²} x^a y^b z^c dω in closed form (0 unless all exponents are even)."""
    if a % 2 or b % 2 or c % 2:
        return 0.0
    g = math.gamma
    return 2.0 * g((a + 1) / 2) * g((b + 1) / 2) * g((c + 1) / 2) / g((a + b + c + 3) / 2)


def test_grid_shape_weights_and_caching():
    for L in (0, 1, 7):
        g = sphere_grid(L)
        assert isinstance(g, GaussLegendreGrid)
        assert g.dirs.shape == ((L + 1) * (2 * L + 1), 3) and g.weights.shape == (g.size,)
        assert g.degree == 2 * L
        np.testing.assert_allclose(np.linalg.norm(g.dirs, axis=-1), 1.0, rtol=0, atol=1e-15)
        assert np.all(g.weights > 0)
        assert math.isclose(g.weights.sum(), 4 * math.pi, rel_tol=1e-14)
    assert sphere_grid(7) is sphere_grid(7)
    with pytest.raises(ValueError):
        sphere_grid(7).weights[0] = 1.0  # read-only


@pytest.mark.parametrize("L", [0, 1, 4, 9])
def test_exact_for_monomials_up_to_degree_2L(L):
    g = sphere_grid(L)
    x, y, z = g.dirs.T
    for deg in range(2 * L + 1):
        for a in range(deg + 1):
            for b in range(deg + 1 - a):
                c = deg - a - b
                got = g.integrate(x**a * y**b * z**c)
                assert abs(got - monomial_integral(a, b, c)) < 1e-13, (a, b, c)
    # ...and not beyond: the rule is tight (z^(2L+2) is integrated wrongly).
    assert abs(g.integrate(z ** (2 * L + 2)) - monomial_integral(0, 0, 2 * L + 2)) > 1e-6


def test_orthonormality_lmax30():
    g = sphere_grid(30)
    y = np.asarray(real_sh(30, g.dirs))
    gram = (y * g.weights[:, None]).T @ y
    assert np.abs(gram - np.eye(n_coeffs(30))).max() <= 1e-12


def test_reference_orthonormal_too():
    g = sphere_grid(12)
    y = real_sh_reference(12, g.dirs)
    gram = (y * g.weights[:, None]).T @ y
    assert np.abs(gram - np.eye(n_coeffs(12))).max() <= 1e-12


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_projection_recovers_band_limited_coefficients(seed):
    rng = np.random.default_rng(seed)
    lmax = 12
    coeffs = rng.normal(size=(3, n_coeffs(lmax)))
    g = sphere_grid(lmax)
    values = coeffs @ real_sh_reference(lmax, g.dirs).T  # (3, N), sampled with the slow reference
    got = np.asarray(project(values, g, lmax))
    assert got.shape == coeffs.shape and got.dtype == np.float64
    assert np.abs(got - coeffs).max() <= 1e-12 * np.abs(coeffs).max()
    # Evaluate back at fresh directions.
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    expect = coeffs @ real_sh_reference(lmax, d).T
    back = np.asarray(evaluate(got[:, None, :], d))
    assert back.shape == (3, 50)
    assert np.abs(back - expect).max() <= 1e-12 * np.abs(expect).max()


def test_project_on_finer_grid_and_lower_lmax():
    # A degree-4 function on an order-9 grid, projected to lmax 6: higher bands are zero.
    f = lambda d: d[:, 0] ** 2 * d[:, 2] ** 2 - 0.5 * d[:, 1]  # noqa: E731
    c = np.asarray(project_function(f, 6, L=9))
    l = np.floor(np.sqrt(np.arange(c.size))).astype(int)
    assert np.abs(c[l > 4]).max() < 1e-14
    assert math.isclose(c[1], -0.5 * math.sqrt(4 * math.pi / 3), rel_tol=1e-13)  # −y/2 = −½·√(4π/3)·Y₁,₋₁
    d = sphere_grid(5).dirs
    np.testing.assert_allclose(np.asarray(evaluate(c, d)), f(d), rtol=0, atol=1e-13)


def test_project_function_known_expansions():
    c = np.asarray(project_function(lambda d: np.ones(len(d)), 3))
    np.testing.assert_allclose(c, np.eye(16)[0] * math.sqrt(4 * math.pi), atol=1e-14)
    c = np.asarray(project_function(lambda d: np.stack([d[:, 2], d[:, 0]], axis=-1), 2))
    assert c.shape == (2, 9)
    np.testing.assert_allclose(c[0], np.eye(9)[2] * math.sqrt(4 * math.pi / 3), atol=1e-14)
    np.testing.assert_allclose(c[1], np.eye(9)[3] * math.sqrt(4 * math.pi / 3), atol=1e-14)


def test_evaluate_broadcasting_and_dtypes():
    rng = np.random.default_rng(2)
    d = rng.normal(size=(5, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    c = rng.normal(size=(5, 16))
    per_point = np.asarray(evaluate(c, d))  # one coefficient set per direction
    assert per_point.shape == (5,)
    ref = real_sh_reference(3, d)
    np.testing.assert_allclose(per_point, np.sum(c * ref, axis=-1), rtol=0, atol=1e-13)
    single = np.asarray(evaluate(c[0], d))
    np.testing.assert_allclose(single, ref @ c[0], rtol=0, atol=1e-13)
    f32 = evaluate(c.astype(np.float32), d.astype(np.float32))
    assert f32.dtype == np.float32
    np.testing.assert_allclose(np.asarray(f32), per_point, rtol=0, atol=1e-5)
    assert evaluate(c.astype(np.float32), d).dtype == np.float64


def test_project_float32():
    g = sphere_grid(4)
    vals = np.cos(g.dirs[:, 2]).astype(np.float32)
    got = project(vals, g, 4)
    assert got.dtype == np.float32
    np.testing.assert_allclose(np.asarray(got), np.asarray(project(vals.astype(np.float64), g, 4)), rtol=0, atol=1e-5)


def test_bad_projection_inputs():
    g = sphere_grid(4)
    with pytest.raises(ValidationError) as info:
        project(np.zeros(g.size), g, 5)  # would alias
    assert info.value.field == "lmax"
    with pytest.raises(ValidationError) as info:
        project(np.zeros(g.size + 1), g, 4)
    assert info.value.field == "values"
    with pytest.raises(ValidationError) as info:
        project(np.full(g.size, np.nan), g, 4)
    assert info.value.field == "values"
    with pytest.raises(ValidationError) as info:
        project(np.zeros(g.size), "grid", 4)
    assert info.value.field == "grid"
    with pytest.raises(ValidationError) as info:
        sphere_grid(-1)
    assert info.value.field == "L"
    with pytest.raises(ValidationError) as info:
        project_function(lambda d: np.zeros(3), 2)
    assert info.value.field == "f"


def test_bad_evaluate_inputs():
    d = np.array([[0.0, 0.0, 1.0]])
    for coeffs in (np.zeros(5), np.zeros(0), np.array([np.nan] * 4), np.zeros((2, 4))):
        with pytest.raises(ValidationError) as info:
            evaluate(coeffs, np.repeat(d, 3, axis=0))
        assert info.value.field == "coeffs"
    with pytest.raises(ValidationError) as info:
        evaluate(np.zeros(4), np.array([[0.0, 0.0, 2.0]]))
    assert info.value.field == "dirs"
