"""Real SH basis: DESIGN constants, references, poles, precision, helpers, bad input."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.special import eval_legendre

from hairlut.errors import ValidationError
from hairlut.sh import (
    index_lm,
    lm_arrays,
    lm_index,
    n_coeffs,
    normalize_dirs,
    real_sh,
    real_sh_reference,
    real_sh_scipy,
)

LMAX = 30


def unit_vectors(rng, n):
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


# Poles, equator, grazing and tiny-but-nonzero x, y (all exactly or nearly unit).
SPECIAL = np.array(
    [
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [-1.0, 0.0, 0.0],
        [1e-200, 1e-200, 1.0],
        [1e-30, 0.0, -1.0],
        [1e-8, -1e-8, 1.0],
        [0.6, 0.8, 0.0],
        [1e-12, 1.0, 1e-12],
    ]
)
SPECIAL = SPECIAL / np.linalg.norm(SPECIAL, axis=-1, keepdims=True)


@pytest.fixture(scope="module")
def dirs():
    return np.concatenate([unit_vectors(np.random.default_rng(7), 400), SPECIAL])


@pytest.fixture(scope="module")
def reference(dirs):
    return real_sh_reference(LMAX, dirs)


# --------------------------------------------------------------------------- DESIGN.md constants


def design_formulas(x, y, z):
    """The DESIGN.md table: flat index → (6-digit constant, precise constant, polynomial)."""
    pi = math.pi
    return {
        0: (0.282095, math.sqrt(1 / (4 * pi)), np.ones_like(x)),
        1: (0.488603, math.sqrt(3 / (4 * pi)), y),
        2: (0.488603, math.sqrt(3 / (4 * pi)), z),
        3: (0.488603, math.sqrt(3 / (4 * pi)), x),
        4: (1.092548, math.sqrt(15 / (4 * pi)), x * y),
        5: (1.092548, math.sqrt(15 / (4 * pi)), y * z),
        6: (0.315392, math.sqrt(5 / (16 * pi)), 3 * z * z - 1),
        7: (1.092548, math.sqrt(15 / (4 * pi)), x * z),
        8: (0.546274, math.sqrt(15 / (16 * pi)), x * x - y * y),
    }


def test_design_constants_at_random_unit_vectors(dirs):
    y_sh = np.asarray(real_sh(2, dirs))
    assert y_sh.shape == (len(dirs), 9) and y_sh.dtype == np.float64
    x, y, z = dirs.T
    for i, (rounded, precise, poly) in design_formulas(x, y, z).items():
        # The table's constants are rounded to 6 decimals: within half a unit of the last digit.
        np.testing.assert_array_less(np.abs(y_sh[:, i] - rounded * poly), 5e-7 * np.abs(poly) + 1e-15, err_msg=f"i={i}")
        np.testing.assert_allclose(y_sh[:, i], precise * poly, rtol=0, atol=1e-12, err_msg=f"i={i}")


def test_design_constants_in_float32():
    d = unit_vectors(np.random.default_rng(3), 64).astype(np.float32)
    y_sh = np.asarray(real_sh(2, d))
    assert y_sh.dtype == np.float32
    x, y, z = d.astype(np.float64).T
    for i, (_, precise, poly) in design_formulas(x, y, z).items():
        np.testing.assert_allclose(y_sh[:, i], precise * poly, rtol=0, atol=2e-6, err_msg=f"i={i}")


def test_sign_convention_no_condon_shortley():
    # At φ = 0 (x > 0, y = 0) every cos(mφ) harmonic is ≥ 0 for z = 0 when (l+m) even: no (−1)^m.
    d = np.array([[1.0, 0.0, 0.0]])
    y_sh = np.asarray(real_sh(6, d))[0]
    for l in range(7):
        for m in range(-l, l + 1):
            v = y_sh[lm_index(l, m)]
            if m < 0 or (l + m) % 2:
                assert v == 0.0  # sin(|m|·0) and odd Legendre at z = 0 vanish exactly
            else:
                assert v != 0.0
                assert np.sign(v) == (-1) ** ((l - m) // 2)  # sign of P_l^m(0) without CS phase


# --------------------------------------------------------------------------- references


def test_matches_slow_reference_lmax30(dirs, reference):
    fast = np.asarray(real_sh(LMAX, dirs))
    assert fast.shape == reference.shape == (len(dirs), n_coeffs(LMAX))
    assert np.abs(fast - reference).max() <= 1e-12 * np.abs(reference).max()


def test_matches_scipy_lmax30(dirs, reference):
    fast = np.asarray(real_sh(LMAX, dirs))
    via_scipy = real_sh_scipy(LMAX, dirs)
    scale = np.abs(via_scipy).max()
    assert np.abs(fast - via_scipy).max() <= 1e-12 * scale
    # The two references are independent of each other as well.
    assert np.abs(reference - via_scipy).max() <= 1e-12 * scale


def test_batch_shapes_and_scalar_direction():
    d = unit_vectors(np.random.default_rng(1), 6).reshape(2, 3, 3)
    out = np.asarray(real_sh(4, d))
    assert out.shape == (2, 3, 25)
    np.testing.assert_allclose(out.reshape(6, 25), np.asarray(real_sh(4, d.reshape(6, 3))), rtol=0, atol=1e-15)
    single = np.asarray(real_sh(4, d[0, 0]))
    assert single.shape == (25,)
    np.testing.assert_allclose(single, out[0, 0], rtol=0, atol=1e-15)
    assert np.asarray(real_sh(0, d)).shape == (2, 3, 1)


@settings(max_examples=40, deadline=None)
@given(
    st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 3).filter(lambda v: np.linalg.norm(v) > 1e-3),
    st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 3).filter(lambda v: np.linalg.norm(v) > 1e-3),
)
@example((0.0, 0.0, 1.0), (0.0, 0.0, -1.0))
@example((0.0, 0.0, 1.0), (0.0, 0.0, 1.0))
@example((1.0, 0.0, 0.0), (0.0, 1e-9, 1.0))
def test_addition_theorem(a, b):
    """Σ_m Y_lm(a) Y_lm(b) = (2l+1)/(4π) P_l(a·b): rotation-invariant, independent of the basis code."""
    d = np.array([a, b], dtype=np.float64)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    y_sh = np.asarray(real_sh(LMAX, d))
    cos_ab = float(np.clip(d[0] @ d[1], -1.0, 1.0))
    l, _ = lm_arrays(LMAX)
    lhs = np.bincount(l, weights=y_sh[0] * y_sh[1])
    ls = np.arange(LMAX + 1)
    scale = (2 * ls + 1) / (4 * np.pi)
    rhs = scale * eval_legendre(ls, cos_ab)
    # 1e-13 relative, plus the rounding of a·b (a few ulp) times |P_l'| ≤ l(l+1)/2.
    tol = scale * (1e-13 + ls * (ls + 1) / 2 * 1e-15)
    np.testing.assert_array_less(np.abs(lhs - rhs), tol)


# --------------------------------------------------------------------------- poles and grazing


def test_poles_only_zonal_terms():
    l, m = lm_arrays(LMAX)
    for sign in (1.0, -1.0):
        for dtype in (np.float64, np.float32):
            out = np.asarray(real_sh(LMAX, np.array([0.0, 0.0, sign], dtype=dtype)))
            assert np.all(np.isfinite(out))
            assert np.all(out[m != 0] == 0.0)
            expected = sign ** l[m == 0] * np.sqrt((2 * l[m == 0] + 1) / (4 * np.pi))
            tol = 1e-13 if dtype == np.float64 else 1e-5
            np.testing.assert_allclose(out[m == 0], expected, rtol=tol, atol=0)


def test_grazing_and_tiny_xy_match_reference():
    out = np.asarray(real_sh(LMAX, SPECIAL))
    ref = real_sh_reference(LMAX, SPECIAL)
    assert np.all(np.isfinite(out))
    assert np.abs(out - ref).max() <= 1e-12 * np.abs(ref).max()
    l, m = lm_arrays(LMAX)
    # (1, 0, 0): y = 0 kills every sin(|m|φ) term exactly.
    assert np.all(out[2][m < 0] == 0.0)
    # Tiny x, y: non-zonal terms are tiny but the zonal ones are the pole values.
    np.testing.assert_allclose(out[5][m == 0], out[0][m == 0], rtol=1e-12)
    assert np.abs(out[5][m != 0]).max() < 1e-150


def test_tiny_xy_float32_finite():
    d = np.array([[1e-20, 1e-20, 1.0], [1e-30, 0.0, -1.0], [3e-4, -2e-4, 1.0]], dtype=np.float32)
    out = np.asarray(real_sh(LMAX, d, normalize=True))
    assert out.dtype == np.float32 and np.all(np.isfinite(out))
    ref = real_sh_reference(LMAX, d.astype(np.float64), normalize=True)
    assert np.abs(out - ref).max() <= 1e-5 * np.abs(ref).max()


# --------------------------------------------------------------------------- precision and dtype


def test_float32_vs_float64_gap_lmax30(dirs):
    """Documented bound: float32 differs from float64 by ≤ 1e-4 × max|Y| at lmax = 30 (measured ~1.5e-5)."""
    d32 = dirs.astype(np.float32)
    y32 = np.asarray(real_sh(LMAX, d32))
    y64 = np.asarray(real_sh(LMAX, d32.astype(np.float64)))  # same (rounded) directions
    assert y32.dtype == np.float32 and y64.dtype == np.float64
    assert np.all(np.isfinite(y32))
    assert np.abs(y32 - y64).max() <= 1e-4 * np.abs(y64).max()


def test_dtype_follows_input_and_x64_flag_untouched():
    d = np.array([[0.0, 0.6, 0.8]])
    assert real_sh(3, d).dtype == jnp.float64
    assert real_sh(3, d.astype(np.float32)).dtype == jnp.float32
    assert real_sh(3, [[0, 0, 1]]).dtype == jnp.float64  # integers promote like NumPy
    assert real_sh(3, jnp.asarray(d, jnp.float32)).dtype == jnp.float32
    assert real_sh(3, d.astype(np.float16)).dtype == jnp.float32
    assert jnp.ones(1).dtype == jnp.float32  # the global x64 flag is still off


def test_works_inside_a_callers_jit():
    d = unit_vectors(np.random.default_rng(5), 8).astype(np.float32)
    jitted = jax.jit(lambda v: real_sh(5, v) * 2.0)
    np.testing.assert_allclose(np.asarray(jitted(d)), 2.0 * np.asarray(real_sh(5, d)), rtol=1e-6, atol=1e-6)


def test_normalize_option():
    rng = np.random.default_rng(11)
    raw = rng.normal(size=(20, 3)) * rng.uniform(1e-3, 1e3, size=(20, 1))
    unit = raw / np.linalg.norm(raw, axis=-1, keepdims=True)
    np.testing.assert_allclose(np.asarray(real_sh(8, raw, normalize=True)), np.asarray(real_sh(8, unit)), rtol=0, atol=1e-13)
    np.testing.assert_allclose(normalize_dirs(raw), unit, rtol=0, atol=1e-15)
    huge = np.array([[1e200, 1e200, 0.0], [1e-300, 0.0, -1e-300]])
    out = np.asarray(real_sh(3, huge, normalize=True))
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out[0, 4], math.sqrt(15 / (4 * math.pi)) * 0.5, rtol=1e-14)


# --------------------------------------------------------------------------- index helpers


@given(st.integers(0, 200).flatmap(lambda l: st.tuples(st.just(l), st.integers(-l, l))))
def test_index_round_trip(lm):
    l, m = lm
    i = lm_index(l, m)
    assert i == l * l + l + m
    assert index_lm(i) == (l, m)


def test_counts_and_arrays():
    assert [n_coeffs(l) for l in range(4)] == [1, 4, 9, 16]
    l, m = lm_arrays(3)
    assert list(zip(l.tolist(), m.tolist()))[:5] == [(0, 0), (1, -1), (1, 0), (1, 1), (2, -2)]
    assert all(lm_index(a, b) == i for i, (a, b) in enumerate(zip(l, m)))


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("lmax", [-1, 2.5, "3", True, None, 10_000])
def test_bad_lmax(lmax):
    with pytest.raises(ValidationError) as info:
        real_sh(lmax, np.array([0.0, 0.0, 1.0]))
    assert info.value.field == "lmax"


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((4, 2)),
        np.zeros(3).reshape(3, 1),
        np.array(1.0),
        np.array([[np.nan, 0.0, 1.0]]),
        np.array([[0.0, np.inf, 0.0]]),
        np.array([[0.0, 0.0, 0.0]]),
        np.array([[1.0, 1.0, 0.0]]),
        np.array([[0.0, 0.0, 1.0 + 1e-5]]),
        np.array([[0.0, 0.0, 1.0 + 0j]]),
        np.array([["a", "b", "c"]]),
    ],
    ids=["shape2", "shape1", "scalar", "nan", "inf", "zero", "non-unit", "slightly-long", "complex", "strings"],
)
def test_bad_dirs(bad):
    with pytest.raises(ValidationError) as info:
        real_sh(2, bad)
    assert info.value.field == "dirs"


def test_float32_tolerance_is_looser_and_normalize_still_rejects_zero():
    near = np.array([[0.0, 0.0, 1.0 + 5e-4]], dtype=np.float32)
    real_sh(2, near)  # within the float32 tolerance
    with pytest.raises(ValidationError):
        real_sh(2, near.astype(np.float64))
    with pytest.raises(ValidationError) as info:
        real_sh(2, np.array([[1.0, 0, 0], [0, 0, 0]]), normalize=True)
    assert info.value.field == "dirs" and "zero vector" in info.value.reason
    with pytest.raises(ValidationError):
        real_sh(2, np.array([[np.nan, 0.0, 1.0]]), normalize=True)


def test_helper_validation():
    calls = [
        (lambda: lm_index(2, 3), "m"),
        (lambda: lm_index(-1, 0), "l"),
        (lambda: index_lm(-2), "i"),
        (lambda: n_coeffs(-1), "lmax"),
    ]
    for call, field in calls:
        with pytest.raises(ValidationError) as info:
            call()
        assert info.value.field == field


@pytest.mark.slow
def test_stable_at_max_lmax_both_precisions():
    """lmax = 64 (MAX_LMAX): float64 ≤ 1e-11 and float32 ≤ 1e-4 of max|Y| (measured 4e-13, 5e-6), never NaN."""
    from hairlut.sh import MAX_LMAX

    d = np.concatenate([unit_vectors(np.random.default_rng(9), 200), SPECIAL])
    ref = real_sh_reference(MAX_LMAX, d)
    y64 = np.asarray(real_sh(MAX_LMAX, d))
    y32 = np.asarray(real_sh(MAX_LMAX, d.astype(np.float32)))
    assert np.all(np.isfinite(y64)) and np.all(np.isfinite(y32))
    assert np.abs(y64 - ref).max() <= 1e-11 * np.abs(ref).max()
    ref32 = real_sh_reference(MAX_LMAX, d.astype(np.float32).astype(np.float64))
    assert np.abs(y32 - ref32).max() <= 1e-4 * np.abs(ref32).max()


@pytest.mark.parametrize("lmax", [0, 1, 5, 9, 16])
def test_unrolled_soa_matches_real_sh(lmax):
    from hairlut.sh import real_sh_soa

    rng = np.random.default_rng(lmax)
    d = rng.normal(size=(64, 3))
    d[:2] = [[0, 0, 1], [0, 0, -1]]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    with jax.enable_x64(True):
        got = np.asarray(real_sh_soa(*jnp.asarray(d.T), lmax)).T
    np.testing.assert_allclose(got, np.asarray(real_sh(lmax, d)), rtol=0, atol=1e-13)
    with pytest.raises(ValidationError):
        real_sh_soa(*jnp.asarray(d.T), 17)
