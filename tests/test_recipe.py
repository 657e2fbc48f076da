import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hairlut.assets import canonical_json, recipe_hash
from hairlut.errors import ValidationError

scalars = st.none() | st.booleans() | st.integers(-(2**53), 2**53) | st.floats(allow_nan=False, allow_infinity=False) | st.text()
recipes = st.recursive(
    scalars, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4), max_leaves=20
)


@given(st.dictionaries(st.text(max_size=8), recipes, max_size=6))
def test_canonical_json_is_order_free_and_round_trips(recipe):
    text = canonical_json(recipe)
    reordered = dict(reversed(list(recipe.items())))
    assert canonical_json(reordered) == text
    assert json.loads(text) == json.loads(json.dumps(recipe))
    assert recipe_hash(recipe) == recipe_hash(text)
    assert text == json.dumps(json.loads(text), sort_keys=True, separators=(",", ":"), ensure_ascii=False)


def test_numpy_values_and_tuples_are_plain():
    a = {"x": np.float64(0.5), "n": np.int32(3), "v": np.arange(3), "t": (1, 2), "b": np.bool_(True)}
    b = {"x": 0.5, "n": 3, "v": [0, 1, 2], "t": [1, 2], "b": True}
    assert canonical_json(a) == canonical_json(b) == '{"b":true,"n":3,"t":[1,2],"v":[0,1,2],"x":0.5}'


def test_hash_is_sha256_of_the_text():
    import hashlib

    assert recipe_hash({"a": 1}) == hashlib.sha256(b'{"a":1}').hexdigest()


@pytest.mark.parametrize("bad", [{"x": math.nan}, {"x": [1.0, math.inf]}, {1: 2}, {"f": object()}, [1, 2]])
def test_bad_recipes_name_the_field(bad):
    with pytest.raises(ValidationError) as info:
        canonical_json(bad)
    if isinstance(bad, dict) and "x" in bad:
        assert "x" in info.value.field
