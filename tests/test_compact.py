"""Stream compaction inside jit (hairlut.march._compact) against NumPy's cumsum and flatnonzero."""

import jax
import jax.numpy as jnp
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut.march._compact import ROW, compact, prefix_count


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 3), min_size=1, max_size=3 * ROW**3))
def test_prefix_count_is_the_cumulative_sum(values):
    x = np.asarray(values, np.int32)
    np.testing.assert_array_equal(np.asarray(jax.jit(prefix_count)(jnp.asarray(x))), np.cumsum(x))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.booleans(), min_size=1, max_size=3 * ROW**3))
def test_compact_lists_the_true_entries_in_order(bits):
    mask = np.asarray(bits)
    idx, count = jax.jit(compact)(jnp.asarray(mask))
    want = np.flatnonzero(mask)
    assert int(count) == want.size
    np.testing.assert_array_equal(np.asarray(idx)[: want.size], want)
    assert not np.asarray(idx)[want.size :].any()  # the rest is zero


def test_compact_of_a_long_sparse_mask():
    """Several levels of the blocked sum (ROW⁵ entries), true entries only near the ends and at one block edge."""
    n = ROW**5 + 3
    mask = np.zeros(n, bool)
    mask[[0, ROW - 1, ROW, ROW**3, n - 1]] = True
    idx, count = jax.jit(compact)(jnp.asarray(mask))
    assert int(count) == 5
    np.testing.assert_array_equal(np.asarray(idx)[:5], np.flatnonzero(mask))
