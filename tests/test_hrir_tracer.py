"""The planar ray tracer (satf §5.1): analytic cases, limits, symmetry, smoothing, the NumPy reference."""

import numpy as np
import pytest

from hairlut.geometry.density import sector_density
from hairlut.geometry.sampler import sample_sectors
from hairlut.geometry.splats import SIGMA_PER_RADIUS
from hairlut.hrir import gaussian_smooth, reference_hrir, resolve_recipe, trace_sectors
from hairlut.march import GEOM, disc_params, sector_geometry
from hairlut.march import smooth_matrix as _smooth_matrix

COL = {k: i for i, k in enumerate(GEOM)}
PHONG = np.array([0.1, 0.6, 0.3, 20.0])


def _recipe(**trace):
    return resolve_recipe(
        {"angles": {"views": 8, "lights": 6}, "trace": {"pixels": 32, "steps": 48, "self_shadow": False, **trace}}
    )


def _random(n=4, grid=(16, 16), seed=11, pixels=32, **override):
    s = sample_sectors(n, seed=seed)
    rho = sector_density(s.splats, grid)
    params = {**s.params, **{k: np.full(n, v) for k, v in override.items()}}
    return rho, sector_geometry(params, kappa=2 / np.pi, n_pix=pixels), params


def _disc(rho_value, sigma_t, n_grid=8, pixels=64):
    g = sector_geometry(disc_params(1), kappa=1.0, n_pix=pixels)
    g[:, COL["sigma_t"]] = sigma_t
    return np.full((1, n_grid, n_grid), rho_value, np.float32), g


def test_uniform_disc_matches_the_chord_law():
    """α(pixel) = 1 − exp(−σ_t ρ chord(pixel)) for a uniform disc, without smoothing."""
    rho, g = _disc(0.8, 1.0)
    views = np.array([0.0, 0.7, 2.0, 4.5])
    r = _recipe(pixels=64, steps=4096, smooth=False, self_shadow=False)
    alpha, refl = trace_sectors(rho, g, r, views=views, lights=[0.3])
    R = g[0, COL["extent"]]
    beta = g[0, COL["beta"]]
    c = g[0, [COL["cx"], COL["cy"]]]
    # disc centre (the ellipse origin) in the local frame
    o = np.array([[np.cos(beta), np.sin(beta)], [-np.sin(beta), np.cos(beta)]]) @ (-c)
    t = -R + (np.arange(64) + 0.5) * 2 * R / 64
    for i, th in enumerate(views):
        e = np.array([-np.sin(th), np.cos(th)])
        dist = o @ e - t
        chord = 2 * np.sqrt(np.clip(1 - dist**2, 0, None))
        np.testing.assert_allclose(alpha[0, i], 1 - np.exp(-0.8 * chord), atol=1e-3)
    assert alpha.max() > 0.7  # the test is not vacuous


def test_step_opacity_is_exact_for_piecewise_constant_density():
    """With few steps the opacity is 1 − exp(−σ_t ρ n Δs), n the samples inside: exact per step
    (a linear α = σ_t ρ Δs would be off by O(σ_t ρ Δs) per step)."""
    rho, g = _disc(0.8, 3.0)
    K, P = 16, 32
    alpha, _ = trace_sectors(rho, g, _recipe(pixels=P, steps=K, smooth=False), views=[0.4], lights=[0.0])
    R, beta = g[0, COL["extent"]], g[0, COL["beta"]]
    c = g[0, [COL["cx"], COL["cy"]]]
    rot = np.array([[np.cos(beta), -np.sin(beta)], [np.sin(beta), np.cos(beta)]])
    d, e = np.array([np.cos(0.4), np.sin(0.4)]), np.array([-np.sin(0.4), np.cos(0.4)])
    t = -R + (np.arange(P) + 0.5) * 2 * R / P
    z = R - (np.arange(K) + 0.5) * 2 * R / K
    pts = c + (t[:, None, None] * e + z[None, :, None] * d) @ rot.T  # ellipse coordinates
    inside = (np.hypot(pts[..., 0], pts[..., 1]) <= 1).sum(axis=1)
    expected = 1 - np.exp(-3.0 * 0.8 * inside * 2 * R / K)
    np.testing.assert_allclose(alpha[0, 0], expected, atol=2e-6)
    assert expected.max() > 0.9


def test_empty_sector_is_transparent_and_black():
    rho = np.zeros((1, 16, 16), np.float32)
    _, g, _ = _random(1)
    alpha, refl = trace_sectors(rho, g, _recipe(self_shadow=True))
    assert np.all(alpha == 0) and np.all(refl == 0)


def test_extremely_dense_sector_is_opaque_without_nan():
    rho, g, _ = _random(3)
    rho = rho * 1e8 + 1e6  # also uniform-gradient-free regions: the fallback normal
    for shadow in (False, True):
        alpha, refl = trace_sectors(rho, g, _recipe(smooth=False, self_shadow=shadow))
        assert np.isfinite(alpha).all() and np.isfinite(refl).all()
        assert alpha.max() == pytest.approx(1.0, abs=1e-6)
        hit = alpha > 0
        assert np.all(alpha[hit] > 1 - 1e-4)  # every ray that meets the sector stops opaque
        assert refl.max() <= PHONG[:3].sum() + 1e-5


def test_mirrored_sector_mirrors_the_hrir():
    rho, g, _ = _random(2, seed=5, aspect=1.0)  # a circular cluster: symmetric about the mid-phase radius
    V = L = 8
    r = resolve_recipe({"angles": {"views": V, "lights": L}, "trace": {"pixels": 32, "steps": 48}})
    a, re = trace_sectors(rho, g, r)
    am, rem = trace_sectors(rho[:, ::-1, :].copy(), g, r)  # s → 1 − s
    flip = (-np.arange(V)) % V
    np.testing.assert_allclose(am, a[:, flip, ::-1], atol=1e-4)  # float32 rounding
    np.testing.assert_allclose(rem, re[:, flip][:, :, flip, ::-1], atol=5e-4)  # p = 20 amplifies rounding
    assert a.max() > 0.05  # not vacuous


def test_smoothing_width_is_one_and_a_half_strand_sigmas():
    _, g, params = _random(3, pixels=64)
    area = params["aspect"] * 2 * np.pi / params["s_u"] * 0.5 * (params["v_range"][:, 1] ** 2 - params["v_range"][:, 0] ** 2)
    sigma_strand = SIGMA_PER_RADIUS * params["radius_rel"] * np.sqrt(area)
    pixel = 2 * g[:, COL["extent"]] / 64
    np.testing.assert_allclose(g[:, COL["sigma_px"]], 1.5 * sigma_strand / pixel, rtol=1e-12)
    # a delta through the kernel's smoothing gives a Gaussian of that standard deviation
    for s in (1.5, 2.0, 2.01, 3.0, 5.0):
        out = np.asarray(_smooth_matrix(np.float32(s), 64))[:, 32]
        x = np.arange(64) - 32
        assert out.sum() == pytest.approx(1.0, abs=1e-5)
        assert np.sqrt((out * x**2).sum()) == pytest.approx(s, rel=1e-3)
        np.testing.assert_allclose(out, gaussian_smooth(np.eye(64)[32], s), atol=1e-6)


def test_kernel_smoothing_equals_smoothing_the_raw_hrir():
    rho, g, _ = _random(2)
    g[:, COL["sigma_px"]] = [2.0, 0.7]
    raw_a, raw_r = trace_sectors(rho, g, _recipe(smooth=False))
    a, re = trace_sectors(rho, g, _recipe(smooth=True))
    for i in range(2):
        np.testing.assert_allclose(a[i], gaussian_smooth(raw_a[i], g[i, COL["sigma_px"]]), atol=1e-5)
        np.testing.assert_allclose(re[i], gaussian_smooth(raw_r[i], g[i, COL["sigma_px"]]), atol=1e-5)


def test_tracer_agrees_with_the_numpy_reference_loop():
    rho, g, _ = _random(4, grid=(12, 10), seed=3, pixels=24)
    V, L = np.arange(6) * 2 * np.pi / 6, np.arange(5) * 2 * np.pi / 5 + 0.1
    r = resolve_recipe({"trace": {"pixels": 24, "steps": 40, "rays_per_pixel": 2, "self_shadow": False}})
    a, re = trace_sectors(rho, g, r, views=V, lights=L)
    assert a.max() > 0.1
    for i in range(4):
        ar, rr = reference_hrir(rho[i], g[i], V, L, PHONG, n_pix=24, n_steps=40, rays=2)
        np.testing.assert_allclose(a[i], ar, atol=5e-5)
        np.testing.assert_allclose(re[i], rr, atol=5e-5)


def test_opaque_strands_agree_with_the_numpy_reference_loop():
    """Issue 29 N9: at optical depths of 1e9 per step (trace.extinction = 1e9) the transmittance in front of a
    step was the inclusive prefix sum less the step's own depth, which cancelled (XLA:CPU recomputing the march
    in each consumer rounded the two differently): α summed past 1 and re reached 1e27.  Against the float64
    loop (the first dense sample is opaque, nothing behind it counts), re ≤ α·(k_a + k_d + k_s), and with
    self-shadowing (its light depths the same prefix sums) shadows only darken."""
    rho, g, _ = _random(3, grid=(8, 8), seed=3, pixels=12)
    g[:, COL["sigma_t"]] *= 1e9
    V, L = np.arange(4) * 2 * np.pi / 4, np.arange(3) * 2 * np.pi / 3 + 0.1
    a, re = trace_sectors(rho, g, resolve_recipe({"trace": {"pixels": 12, "steps": 12, "self_shadow": False}}), views=V, lights=L)
    _, lit = trace_sectors(rho, g, resolve_recipe({"trace": {"pixels": 12, "steps": 12, "self_shadow": True}}), views=V, lights=L)
    assert a.max() > 0.5 and np.isfinite(lit).all()
    for x in (re, lit):
        assert (x <= PHONG[:3].sum() * a[:, :, None] * (1 + 1e-5) + 1e-7).all()
    assert (lit <= re + 1e-6).all() and (lit < re - 1e-3).any()
    for i in range(3):
        ar, rr = reference_hrir(rho[i], g[i], V, L, PHONG, n_pix=12, n_steps=12)
        np.testing.assert_allclose(a[i], ar, atol=5e-5)  # the float32 tolerance of the loop's other comparison
        np.testing.assert_allclose(re[i], rr, atol=5e-5)


def test_huge_shininess_keeps_the_specular_lobe_at_most_one():
    """r·d is a cosine of unit vectors, but float32 rounding can put it a few ulp above 1, and (1 + 1e-7)^p is
    infinite for p ≳ 1e9 (phong.shininess may be anything finite in float32): clamped, re stays ≤ α·(k_a + k_d + k_s)."""
    rho, g, _ = _random(3, grid=(8, 8), seed=5, pixels=16)
    V, L = np.arange(16) * 2 * np.pi / 16, np.arange(16) * 2 * np.pi / 16
    for p in (1e12, 3e38):
        r = resolve_recipe({"trace": {"pixels": 16, "steps": 16}, "phong": {"shininess": p}})
        a, re = trace_sectors(rho, g, r, views=V, lights=L)
        assert np.isfinite(re).all() and (re <= a[:, :, None] * (1 + 1e-5) + 1e-7).all()


def test_self_shadowing_agrees_with_marching_toward_the_light():
    rho, g, _ = _random(2, seed=3, pixels=24)
    V, L = np.array([0.0, 2.0]), np.array([0.5, 3.5])
    r = resolve_recipe({"trace": {"pixels": 24, "steps": 48, "self_shadow": True}})
    a, re = trace_sectors(rho, g, r, views=V, lights=L)
    _, re0 = trace_sectors(
        rho, g, resolve_recipe({"trace": {"pixels": 24, "steps": 48, "self_shadow": False}}), views=V, lights=L
    )
    assert (re <= re0 + 1e-6).all() and (re < re0 - 1e-3).any()  # shadows only darken
    for i in range(2):
        _, rr = reference_hrir(rho[i], g[i], V, L, PHONG, n_pix=24, n_steps=48, shadow=True)
        assert np.abs(re[i] - rr).max() < 0.1 * max(rr.max(), 1e-3)


def test_convergence_in_step_and_grid():
    """Halving the step and doubling the density grid: the HRIR changes by a mean |Δ| < 3e-3 and a
    max |Δ| < 0.1 at (grid 32 → 64, steps 96 → 192), and each refinement changes it less.

    Sectors whose strands the grids resolve (radius ≥ 0.03 √area); thinner strands converge
    more slowly in the max norm (see benchmarks/hrir_bake.py).
    """
    from hairlut.geometry.sampler import SectorSpace

    s = sample_sectors(4, SectorSpace(radius_rel=(0.03, 0.1)), seed=21)
    means, maxes, prev = [], [], None
    for grid, steps in ((16, 48), (32, 96), (64, 192)):
        rho = sector_density(s.splats, (grid, grid))
        g = sector_geometry(s.params, kappa=2 / np.pi, n_pix=32)
        a, re = trace_sectors(
            rho,
            g,
            resolve_recipe({"angles": {"views": 6, "lights": 4}, "trace": {"pixels": 32, "steps": steps, "rays_per_pixel": 2}}),
        )
        if prev is not None:
            d = np.concatenate([np.abs(a - prev[0]).ravel(), np.abs(re - prev[1]).ravel()])
            means.append(d.mean())
            maxes.append(d.max())
        prev = (a, re)
    assert means[1] < 3e-3 and maxes[1] < 0.1
    assert means[1] < 0.6 * means[0] and maxes[1] < maxes[0]
