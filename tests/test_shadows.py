"""Voxel SH transmittance (xing §5): mass, analytic chords, Beer–Lambert step independence, eq (7)."""

import numpy as np
import pytest

from hairlut import errors
from hairlut.geometry import Strands
from hairlut.sh import real_sh, sphere_grid
from hairlut.shadows import Volume, gradient, transmittance, voxelize

from .conftest import groom_path


def test_voxelize_conserves_length(rng):
    pts = [np.cumsum(rng.normal(size=(12, 3)) * 0.3, axis=0) for _ in range(20)]
    s = Strands.from_list(pts)
    v = voxelize(s, 16)
    assert v.density.sum() * v.size == pytest.approx(s.lengths().sum(), rel=1e-12)
    assert np.all(v.density[:2] == 0) and np.all(v.density[-2:] == 0)  # padding


def test_gradient_is_central_difference():
    rho = np.zeros((5, 5, 5))
    rho[2, 2, 2] = 4.0
    g = np.asarray(gradient(rho))
    assert g[1, 2, 2, 0] == 2.0 and g[3, 2, 2, 0] == -2.0 and g[2, 2, 2].tolist() == [0, 0, 0]


def _box(n=24, rho0=1.0, half=8):
    d = np.zeros((n, n, n))
    c = n // 2
    d[c - half : c + half, c - half : c + half, c - half : c + half] = rho0
    return Volume(d, np.zeros(3), 1.0), c


def test_no_extinction_gives_the_projection_of_one():
    vol, _ = _box()
    tr = transmittance(vol, kappa=0.0, stride=4)
    b = tr.coeffs[tr.valid]
    np.testing.assert_allclose(b[:, 0], np.sqrt(4 * np.pi), rtol=1e-12)
    np.testing.assert_allclose(b[:, 1:], 0, atol=1e-12)


def test_box_centre_matches_analytic_chords():
    vol, c = _box(n=32, half=12)
    kappa = 0.05
    tr = transmittance(vol, kappa=kappa, stride=8, order=8, step=0.25, neighbours=1)  # c = 16 is a sample voxel
    grid = sphere_grid(8)
    # from voxel centre c (continuous coordinate c) the box spans [c−12−0.5, c+12−0.5] per axis
    p = np.full(3, float(c))
    lo, hi = c - 12 - 0.5, c + 12 - 0.5
    d = grid.dirs
    with np.errstate(divide="ignore"):
        t_exit = np.min(np.where(d > 0, (hi - p) / d, np.where(d < 0, (lo - p) / d, np.inf)), axis=1)
    expect = np.asarray(real_sh(2, d)).T @ (grid.weights * np.exp(-kappa * t_exit))
    # trilinear sampling blurs the box face over one voxel: ~κ·ρ·0.5 of optical depth
    np.testing.assert_allclose(tr.coeffs[c, c, c], expect, atol=0.03 * expect[0])


def test_step_size_independence():
    vol, c = _box(n=20, half=6)
    coarse = transmittance(vol, kappa=0.2, stride=4, step=0.5).coeffs
    fine = transmittance(vol, kappa=0.2, stride=4, step=0.125).coeffs
    m = np.abs(fine[..., 0]) > 0
    assert np.abs(coarse[m] - fine[m]).max() < 0.02 * np.abs(fine[m, 0]).max()


def test_stride_one_is_the_samples_themselves():
    vol, _ = _box(n=12, half=3)
    tr = transmittance(vol, kappa=0.3, stride=1, neighbours=1)
    direct = transmittance(vol, kappa=0.3, stride=1, neighbours=1, use_gradient=False)
    nonempty = vol.density > 0
    np.testing.assert_allclose(tr.coeffs[nonempty], direct.coeffs[nonempty], atol=1e-12)


@pytest.mark.slow
def test_sparse_samples_with_gradient_beat_plain_average_on_sintel():
    path = groom_path("sintel_lite.tfx")
    from hairlut.geometry import read_strands

    vol = voxelize(read_strands(path), 32)
    ref = transmittance(vol, kappa=0.5, stride=1)
    m = ref.valid & (vol.density > 0)
    err = {
        g: np.abs(transmittance(vol, kappa=0.5, stride=2, use_gradient=g).coeffs[m] - ref.coeffs[m]).mean() for g in (True, False)
    }
    assert err[True] < err[False]


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"kappa": -1.0}, "kappa"),
        ({"kappa": 1.0, "stride": 0}, "stride"),
        ({"kappa": 1.0, "step": 0.0}, "step"),
        ({"kappa": 1.0, "lmax": 4, "order": 2}, "order"),
    ],
)
def test_bad_parameters(kwargs, field):
    vol, _ = _box(n=8, half=2)
    with pytest.raises(errors.ValidationError) as info:
        transmittance(vol, **kwargs)
    assert info.value.field == field


def test_empty_volume_is_rejected():
    with pytest.raises(errors.ValidationError, match="no hair"):
        transmittance(Volume(np.zeros((4, 4, 4)), np.zeros(3), 1.0), kappa=1.0)
