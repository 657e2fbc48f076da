"""The one Kajiya–Kay lobe module (hairlut.kernels) against DESIGN.md's definition, in NumPy and JAX."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut import errors, kernels as kk


def _angle(a, b):
    return np.arccos(np.clip(np.sum(a * b, -1), -1.0, 1.0))


@pytest.mark.parametrize("p", [1.0, 2.5, 49.0, 300.0])
def test_specular_is_the_design_formula(p):
    th, tv = np.meshgrid(np.linspace(0, np.pi, 91), np.linspace(0, np.pi, 83))
    want = np.maximum(np.cos(np.pi - th - tv), 0.0) ** p  # DESIGN.md, written out
    np.testing.assert_allclose(kk.specular(th, tv, p), want, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.asarray(jax.jit(kk.specular)(jnp.asarray(th), jnp.asarray(tv), p)), want,
                               rtol=2e-5, atol=1e-6)
    assert kk.specular(np.array([0.3]), np.array([np.pi - 0.3]), p)[0] == pytest.approx(1.0)  # the mirror cone
    assert kk.specular(np.array([0.3]), np.array([0.3]), p)[0] == 0.0  # far from it: clamped


def test_specular_offset_equals_specular():
    th, tv = np.meshgrid(np.linspace(0, np.pi, 57), np.linspace(0, np.pi, 61))
    for p in (1.0, 7.3, 80.0):
        np.testing.assert_allclose(kk.specular_offset(th + tv - np.pi / 2, p), kk.specular(th, tv, p), atol=1e-13)


def test_diffuse_is_sin_theta():
    th = np.linspace(0, np.pi, 101)
    np.testing.assert_allclose(kk.diffuse(th), np.sin(th).clip(0), atol=0)
    assert isinstance(kk.diffuse(th), np.ndarray)  # NumPy in, NumPy out


unit = st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 0.1)


@settings(max_examples=60, deadline=None)
@given(t=unit, w=unit, v=unit, p=st.floats(0.5, 200))
def test_cosine_form_equals_the_angle_form(t, w, v, p):
    t, w, v = (np.asarray(x) / np.linalg.norm(x) for x in (t, w, v))
    th, tv = _angle(w, t), _angle(t, v)
    # √(1 − c²) and sin(arccos c) differ by rounding, up to ~1e-8 where t is nearly parallel to w or v
    assert kk.diffuse_cos(t @ w) == pytest.approx(np.sin(th), abs=5e-8)
    assert kk.specular_cos(t @ w, t @ v, p) == pytest.approx(kk.specular(th, tv, p), abs=1e-7 * p)


def test_jax_tracers_use_jax_numpy():
    f = jax.jit(lambda c, d, p: kk.specular_cos(c, d, p) + kk.diffuse_cos(c))
    c, d = np.linspace(-1, 1, 9), np.linspace(1, -1, 9)
    np.testing.assert_allclose(np.asarray(f(c, d, 20.0)), kk.specular_cos(c, d, 20.0) + kk.diffuse_cos(c), atol=1e-6)


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), True, "3", None])
def test_bad_exponent_names_the_field(bad):
    with pytest.raises(errors.ValidationError) as info:
        kk.check_exponent(bad, "material.p_I")
    assert info.value.field == "material.p_I"
    assert kk.exponent_reason(bad)
    assert kk.check_exponent(2) == 2.0 and kk.exponent_reason(80.0) is None
