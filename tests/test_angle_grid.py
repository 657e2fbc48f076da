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
    # θ lies between node i0 and the next one, periodically, at the fraction ``frac`` of the step
    step = 2 * np.pi / n
    d = np.mod(theta - angle_grid(n)[i0], 2 * np.pi)
    d = d - 2 * np.pi if d > 2 * np.pi - 1e-9 else d  # rounding just below a node
    assert -1e-9 <= d < step + 1e-9
    assert abs(frac - d / step) < 1e-8


def test_coverage_counts_the_two_nodes_each_angle_reads():
    n = 8
    assert grid_coverage(np.array([0.1]), n) == 2 / n
    assert grid_coverage(np.array([2 * np.pi - 0.1]), n) == 2 / n  # nodes 7 and 0 (wraps)
    assert grid_coverage(angle_grid(n) + 0.01, n) == 1.0
