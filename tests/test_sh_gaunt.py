"""Real Gaunt coefficients against an exact Wigner-3j (Racah) construction and identities."""

import functools
import itertools
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut.errors import ValidationError
from hairlut.sh import gaunt, gaunt_quadrature, gaunt_sparse, index_lm, lm_arrays, n_coeffs, real_sh_reference, selection_mask

F = math.factorial
INV_2_SQRT_PI = 1.0 / (2.0 * math.sqrt(math.pi))


@functools.cache
def wigner_3j(j1, j2, j3, m1, m2, m3) -> float:
    """Racah's formula, summed exactly in rationals (integer j only)."""
    if m1 + m2 + m3 != 0 or not abs(j1 - j2) <= j3 <= j1 + j2 or max(abs(m1) - j1, abs(m2) - j2, abs(m3) - j3) > 0:
        return 0.0
    total = Fraction(0)
    for k in range(0, j1 + j2 + j3 + 1):
        args = (k, j3 - j2 + k + m1, j3 - j1 + k - m2, j1 + j2 - j3 - k, j1 - k - m1, j2 - k + m2)
        if min(args) < 0:
            continue
        total += Fraction((-1) ** k, math.prod(F(a) for a in args))
    delta = Fraction(F(j1 + j2 - j3) * F(j1 - j2 + j3) * F(-j1 + j2 + j3), F(j1 + j2 + j3 + 1))
    root = delta * F(j1 + m1) * F(j1 - m1) * F(j2 + m2) * F(j2 - m2) * F(j3 + m3) * F(j3 - m3)
    sign = -1 if (j1 - j2 - m3) % 2 else 1
    return sign * math.sqrt(root) * float(total)


def complex_gaunt(l1, l2, l3, m1, m2, m3) -> float:
    """∫ Y_l1^m1 Y_l2^m2 Y_l3^m3 dω for complex SH with the Condon–Shortley phase."""
    pre = math.sqrt((2 * l1 + 1) * (2 * l2 + 1) * (2 * l3 + 1) / (4 * math.pi))
    return pre * wigner_3j(l1, l2, l3, 0, 0, 0) * wigner_3j(l1, l2, l3, m1, m2, m3)


def real_to_complex(l, m):
    """Real Y_l,m (no CS phase) as Σ u·Y_l^μ (complex, CS phase): list of (μ, u)."""
    if m == 0:
        return [(0, 1.0)]
    a = abs(m)
    s = (-1) ** a / math.sqrt(2)
    if m > 0:
        return [(a, s), (-a, 1 / math.sqrt(2))]
    return [(a, s / 1j), (-a, -1 / (1j * math.sqrt(2)))]


def real_gaunt_exact(i, j, k) -> float:
    (l1, m1), (l2, m2), (l3, m3) = index_lm(i), index_lm(j), index_lm(k)
    acc = 0j
    terms = itertools.product(real_to_complex(l1, m1), real_to_complex(l2, m2), real_to_complex(l3, m3))
    for (u1, c1), (u2, c2), (u3, c3) in terms:
        acc += c1 * c2 * c3 * complex_gaunt(l1, l2, l3, u1, u2, u3)
    assert abs(acc.imag) < 1e-14
    return acc.real


def test_3j_known_values():
    assert math.isclose(wigner_3j(1, 1, 0, 0, 0, 0), -1 / math.sqrt(3), rel_tol=1e-15)
    assert math.isclose(wigner_3j(1, 1, 2, 0, 0, 0), math.sqrt(2 / 15), rel_tol=1e-15)
    assert math.isclose(wigner_3j(2, 2, 2, 1, -1, 0), math.sqrt(1 / 70), rel_tol=1e-14)
    assert wigner_3j(1, 1, 1, 0, 0, 0) == 0.0


def test_against_exact_racah_all_entries():
    g = gaunt(3, 2, 4)
    assert g.shape == (16, 9, 25) and g.dtype == np.float64
    exact = np.array([[[real_gaunt_exact(i, j, k) for k in range(25)] for j in range(9)] for i in range(16)])
    assert np.abs(g - exact).max() <= 1e-14


@settings(max_examples=60, deadline=None)
@given(st.integers(0, n_coeffs(8) - 1), st.integers(0, n_coeffs(8) - 1), st.integers(0, n_coeffs(8) - 1))
def test_against_exact_racah_random_entries(i, j, k):
    assert abs(gaunt(8)[i, j, k] - real_gaunt_exact(i, j, k)) <= 1e-14


def test_zeroth_index():
    g = gaunt(6)
    assert math.isclose(g[0, 0, 0], INV_2_SQRT_PI, rel_tol=1e-14)
    n = n_coeffs(6)
    np.testing.assert_allclose(g[0], np.eye(n) * INV_2_SQRT_PI, rtol=0, atol=1e-15)
    np.testing.assert_allclose(g[:, 0, :], np.eye(n) * INV_2_SQRT_PI, rtol=0, atol=1e-15)
    np.testing.assert_allclose(g[:, :, 0], np.eye(n) * INV_2_SQRT_PI, rtol=0, atol=1e-15)


def test_permutation_symmetry():
    g = gaunt(6)
    for perm in itertools.permutations(range(3)):
        assert np.abs(g - g.transpose(perm)).max() <= 1e-15
    # Unequal band limits: symmetric on the common block.
    h = gaunt(4, 6, 5)
    n = n_coeffs(4)
    assert np.abs(h[:, :n, :n] - g[:n, :n, :n]).max() <= 1e-14  # different grid orders: rounding only
    assert np.abs(h[:, :n, :n] - h[:, :n, :n].transpose(0, 2, 1)).max() <= 1e-15


def test_selection_rules_hold_and_mask_hides_nothing():
    lm = 6
    g = gaunt(lm)
    l, m = lm_arrays(lm)
    L1, L2, L3 = np.meshgrid(l, l, l, indexing="ij")
    odd = (L1 + L2 + L3) % 2 == 1
    no_triangle = (L3 > L1 + L2) | (L3 < np.abs(L1 - L2))
    assert np.all(g[odd] == 0.0) and np.all(g[no_triangle] == 0.0)
    M1, M2, M3 = np.meshgrid(m, m, m, indexing="ij")
    assert np.all(g[(M1 + M2 + M3 == 0) & (M1 < 0) & (M2 < 0) & (M3 < 0)] == 0.0)  # three sines: odd in φ
    # The quadrature values that the rules set to zero were only rounding noise.
    raw = gaunt_quadrature(lm, lm, lm)
    mask = selection_mask(lm, lm, lm)
    assert np.abs(raw[~mask]).max() <= 1e-14
    assert np.abs(raw - g).max() <= 1e-14
    assert np.count_nonzero(g) < 0.1 * g.size  # the tensor is sparse


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_product_identity(seed):
    """Y_i Y_j = Σ_k G[i,j,k] Y_k exactly when l_i + l_j ≤ lmax3, checked with the slow reference."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(40, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    y = real_sh_reference(8, d)
    g = gaunt(4, 4, 8)
    lhs = y[:, :25, None] * y[:, None, :25]
    rhs = np.einsum("ijk,pk->pij", g, y)
    assert np.abs(lhs - rhs).max() <= 1e-13


def test_sparse_form_and_cache():
    g = gaunt(5)
    assert gaunt(5) is g and gaunt(5, 5, 5) is g
    with pytest.raises(ValueError):
        g[0, 0, 0] = 1.0
    idx, vals = gaunt_sparse(5)
    assert idx.shape == (len(vals), 3) and np.all(np.abs(vals) > 1e-14)
    dense = np.zeros_like(g)
    dense[tuple(idx.T)] = vals
    assert np.abs(dense - g).max() <= 1e-14
    assert (idx[:, 0] * 10**6 + idx[:, 1] * 10**3 + idx[:, 2] == np.sort(idx[:, 0] * 10**6 + idx[:, 1] * 10**3 + idx[:, 2])).all()


@pytest.mark.parametrize(
    "args, field",
    [((-1, 2, 2), "lmax1"), ((2, 2.5, 2), "lmax2"), ((2, 2, "x"), "lmax3"), ((40, 40, 40), "lmax")],
)
def test_bad_gaunt_input(args, field):
    with pytest.raises(ValidationError) as info:
        gaunt(*args)
    assert info.value.field == field
