"""The one periodic in-plane angle grid (hairlut.geometry.angle_grid, grid_cell) against brute force."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut.geometry import angle_grid, grid_cell
from hairlut.scene import grid_coverage


def test_grid_nodes():
    for n in (1, 2, 7, 32):
        g = angle_grid(n)
        assert g.shape == (n,) and g[0] == 0.0
        np.testing.assert_allclose(g, [2 * np.pi * i / n for i in range(n)], rtol=0, atol=1e-15)


@settings(max_examples=200, deadline=None)
@given(theta=st.floats(-50, 50), n=st.integers(1, 64))
def test_cell_is_the_node_below_with_wrap(theta, n):
    i0, frac = grid_cell(np.array([theta]), n)
    i0, frac = int(i0[0]), float(frac[0])
    assert 0 <= i0 < n and -1e-9 <= frac <= 1 + 1e-9
    # θ lies between node i0 and the next one, periodically, at the fraction ``frac`` of the step: node i0 + frac·step
    # is θ modulo 2π (compared as a periodic difference, so that θ a hair below a node may come back either as that
    # node with frac 0 or as the node before it with frac 1)
    step = 2 * np.pi / n
    diff = np.mod(theta - (angle_grid(n)[i0] + frac * step) + np.pi, 2 * np.pi) - np.pi
    assert abs(diff) < 1e-8


def test_cell_of_an_angle_a_hair_below_a_node():
    """The case hypothesis found: θ = −9.3e-10 on a one-node grid is node 0 at frac ≈ 1 (one turn below), or frac 0."""
    i0, frac = grid_cell(np.array([-9.27106889436748e-10]), 1)
    assert int(i0[0]) == 0
    assert min(abs(float(frac[0])), abs(float(frac[0]) - 1)) < 1e-9


def test_coverage_counts_the_two_nodes_each_angle_reads():
    n = 8
    assert grid_coverage(np.array([0.1]), n) == 2 / n
    assert grid_coverage(np.array([2 * np.pi - 0.1]), n) == 2 / n  # nodes 7 and 0 (wraps)
    assert grid_coverage(angle_grid(n) + 0.01, n) == 1.0
