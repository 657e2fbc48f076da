"""Where a texel's strands are seen (hairlut.synth._shadowing.seen_points): the shadow lookups of the light-space
methods move from the layer surface toward the cluster's centre line by the mean visible depth of a chord."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut.geometry import build_sectors
from hairlut.synth._shadowing import depth_quantiles, section_extinction, seen_points

from .test_sectors import cylinder, polylines


def _cdf(s: np.ndarray, x: float) -> np.ndarray:
    """Where a chord of optical depth ``x`` shows its strands, by a fine midpoint rule: the cumulative share of
    ∫ x e^{−xs} ds over [0, s], s a fraction of the chord."""
    grid = (np.arange(400_000) + 0.5) / 400_000
    w = np.exp(-x * grid)
    return np.interp(s, grid, (np.cumsum(w) - 0.5 * w) / w.sum())


@settings(max_examples=40, deadline=None)
@given(st.floats(0.0, 60.0), st.integers(1, 8))
def test_depth_quantiles_are_the_beer_lambert_quantiles(x, m):
    d = depth_quantiles(x, m)
    assert d.shape == (m,) and (np.diff(d) > 0).all() and (d > 0).all() and (d < 1).all()
    np.testing.assert_allclose(_cdf(d, x), (np.arange(m) + 0.5) / m, atol=2e-5)


def test_depth_quantiles_are_finite_at_the_limits():
    x = np.array([0.0, 1e-300, 1e-12, 1e-6, 1.0, 1e3, 1e300, np.inf])
    d = depth_quantiles(x, 4)
    assert np.isfinite(d).all() and d.shape == (4, 8)
    np.testing.assert_allclose(d[:, 0], [0.125, 0.375, 0.625, 0.875])  # sparse: spread evenly
    assert (d[:, -2:] < 1e-290).all() and d[3, 5] < 0.01  # dense: at the surface


def _cluster(n_strands: int, radius: float):
    """A straight elliptic cylinder (A = 2, B = 1 along z) with ``n_strands`` strands along its axis, all in its
    shells (the core holds none)."""
    geom = cylinder()
    rng = np.random.default_rng(3)
    v, u = rng.uniform(0.3, 0.95, n_strands), rng.uniform(0, 2 * np.pi, n_strands)  # outside the core (v < 0.25)
    lines = [[[x, y, -1.0], [x, y, 5.0]] for x, y in zip(2 * v * np.cos(u), v * np.sin(u))]
    return build_sectors(geom, polylines(*lines), np.zeros(n_strands, int), radius=radius)


def test_section_extinction_is_the_strands_cut_width_over_the_ellipse():
    table = _cluster(30, 0.01)
    t, sigma = section_extinction(table)
    np.testing.assert_allclose(t, [0.0, 0.5, 1.0])
    np.testing.assert_allclose(sigma, 30 * 2 * 0.01 / (np.pi * 2.0 * 1.0), rtol=1e-9)


def _ring(n_u=16, n_t=4):
    """(1, 1, n_t, n_u, 3) texels on the ellipse A = 2, B = 1 around the z axis."""
    u = 2 * np.pi * (np.arange(n_u) + 0.5) / n_u
    z = np.linspace(0.5, 3.5, n_t)
    p = np.stack(np.broadcast_arrays(2 * np.cos(u)[None], np.sin(u)[None], z[:, None]), -1)
    return p[None, None], (np.arange(n_t) + 0.5) / n_t


@pytest.mark.parametrize(("n", "radius"), [(1, 1e-9), (30, 0.01), (400, 0.05)])
def test_seen_points_lie_between_the_texel_and_the_centre_line_at_the_quantiles(n, radius):
    table = _cluster(n, radius)
    p, t = _ring()
    q = seen_points(p, [table], t)
    assert q.shape == (4, *p.shape) and np.isfinite(q).all()
    centre = np.stack([np.zeros(4), np.zeros(4), p[0, 0, :, 0, 2]], -1)[:, None]
    rho = np.linalg.norm(p[0, 0] - centre, axis=-1)
    sigma = n * 2 * radius / (2 * np.pi)  # the strands' cut width over the ellipse's area π A B
    for i in range(4):
        np.testing.assert_allclose(np.cross(p[0, 0] - centre, q[i, 0, 0] - centre), 0.0, atol=1e-12)  # on the radius
        moved = np.linalg.norm(p[0, 0] - q[i, 0, 0], axis=-1)
        np.testing.assert_allclose(moved / rho, depth_quantiles(sigma * rho, 4)[i], rtol=1e-9, atol=1e-12)


def test_a_denser_cluster_is_seen_nearer_its_surface():
    p, t = _ring()
    moved = [np.linalg.norm(p - seen_points(p, [_cluster(n, 0.02)], t), axis=-1).mean() for n in (5, 50, 500)]
    assert moved[0] > moved[1] > moved[2] > 0
