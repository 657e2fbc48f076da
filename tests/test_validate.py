"""The shared validators (hairlut.validate): field checks, argument checks, directions and points."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut import errors
from hairlut import validate as v
from hairlut.recipes import Field, resolve


@settings(max_examples=80, deadline=None)
@given(
    st.lists(
        st.lists(st.floats(-1e6, 1e6), min_size=3, max_size=3).filter(lambda x: np.linalg.norm(x) > 1e-6), min_size=1, max_size=5
    )
)
def test_directions_are_normalised_and_parallel(vecs):
    d = v.directions(vecs, "lights")
    a = np.asarray(vecs, np.float64)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(d * np.linalg.norm(a, axis=-1, keepdims=True), a, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize(
    "bad, words",
    [
        ([0, 0, 0], "zero vector"),
        ([1, np.nan, 0], "non-finite"),
        ([1, 2], "3"),
        ([True, False, True], "real"),
        (["a", "b", "c"], "real"),
        ([[1, 0, 0], [0, 0, 0]], "zero vector"),
        ([[1, 0, 0, 1]], "3"),
    ],
)
def test_bad_direction_names_the_field(bad, words):
    with pytest.raises(errors.ValidationError) as info:
        v.direction(bad, "camera.view") if np.ndim(bad) == 1 else v.directions(bad, "camera.view")
    assert info.value.field == "camera.view" and words in info.value.reason


def test_unit_tolerance_without_normalising():
    assert v.directions([[0, 0, 1 + 1e-9]], normalize=False).dtype == np.float64
    with pytest.raises(errors.ValidationError, match="not a unit vector at index"):
        v.directions([[1, 0, 0], [0, 0, 1.01]], normalize=False)
    assert v.directions(np.float32([[0, 0, 1.0005]]), normalize=False, tol=1e-3, dtype=np.float32).dtype == np.float32


def test_points():
    assert v.points([[1, 2, 3]]).dtype == np.float64
    for bad in ([1, 2, 3], [[1, 2]], [[np.inf, 0, 0]], [["x", "y", "z"]]):
        with pytest.raises(errors.ValidationError) as info:
            v.points(bad, "texels")
        assert info.value.field == "texels"


def test_argument_checks():
    assert v.check_int(np.int64(5), "n", 1, 8) == 5 and isinstance(v.check_int(np.int64(5), "n"), int)
    assert v.check_real(np.float32(0.5), "k", 0, 1) == 0.5
    for call in (
        lambda: v.check_int(True, "n"),
        lambda: v.check_int(2.0, "n"),
        lambda: v.check_int(0, "n", 1),
        lambda: v.check_int(9, "n", 1, 8),
        lambda: v.check_real(0.0, "n", 0, lo_open=True),
        lambda: v.check_real(float("nan"), "n"),
        lambda: v.check_real("1", "n"),
        lambda: v.check_real(2, "n", hi=1),
    ):
        with pytest.raises(errors.ValidationError) as info:
            call()
        assert info.value.field == "n"


def test_field_checks_give_reasons():
    assert v.positive(1e-9) is None and v.positive(0) and v.positive(float("inf"))
    assert v.nonneg(0) is None and v.nonneg(-1e-9)
    assert v.unit_interval(1) is None and v.unit_interval(1.5) and v.open_unit_interval(1)
    assert v.at_least(2)(2) is None and v.at_least(2)(1) and v.at_least(2)(2.0)
    assert v.in_range(2, 512)(512) is None and v.in_range(2, 512)(513) and v.in_range(-1, 1)(0.5) is None
    assert v.in_range(-1, 1)(1.5) and v.in_range(0, 1)(float("nan"))
    assert v.one_of("exp", "linear")("exp") is None and "linear" in v.one_of("exp", "linear")("lin")
    assert v.auto_or(v.at_least(1))("auto") is None and "'auto'" in v.auto_or(v.at_least(1))(0)
    assert v.vec3([0, 0, 2]) is None and v.vec3([0, 0, 0]) and v.vec3([1, 2]) and v.vec3([1, "a", 2])
    big = float(np.finfo(np.float32).max)
    assert v.float32(v.nonneg)(big) is None and "float32" in v.float32(v.nonneg)(np.nextafter(big, np.inf))
    assert v.float32(v.nonneg)(-1) == v.nonneg(-1) and "float32" in v.float32(v.positive)(1e300)


def test_resolve_names_the_key_path():
    schema = {"material": {"kd": Field(0.5, (int, float), v.nonneg, "")}, "render": {"n": Field(4, (int,), v.at_least(1))}}
    assert resolve(schema, {})["material"]["kd"] == 0.5
    for given_, path in (({"material": {"kd": -1}}, "material.kd"), ({"render": {"n": 0}}, "render.n")):
        with pytest.raises(errors.ValidationError) as info:
            resolve(schema, given_)
        assert info.value.field == path
