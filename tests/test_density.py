"""Sector density fields (satf §3.3) and features (§5.2): exact masses, flat fields, permutations."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.special import ndtr

from hairlut.errors import ValidationError
from hairlut.geometry import (
    SIGMA_PER_RADIUS,
    ClusterGeometry,
    ClusterSpec,
    FeatureStats,
    PCABasis,
    SplatBatch,
    Strands,
    build_sectors,
    feature_names,
    sector_density,
    sector_density_numpy,
    sector_features,
)


def one_sector(centers, sigmas, radii, *, area_scale=0.7, v_range=(0.4, 0.9)) -> SplatBatch:
    c = np.asarray(centers, float).reshape(1, -1, 2)
    k = c.shape[1]
    return SplatBatch(
        c,
        np.asarray(sigmas, float).reshape(1, k, 2),
        np.asarray(radii, float).reshape(1, k),
        np.ones((1, k), bool),
        np.array([area_scale]),
        np.array([v_range]),
    )


def mass(rho: np.ndarray, splats: SplatBatch) -> np.ndarray:
    n_s, n_r = rho.shape[1:]
    return np.sum(rho * splats.row_areas(n_s, n_r)[:, None, :], axis=(1, 2))


# -- exact normalisation ----------------------------------------------------------------------------
def test_single_strand_integrates_to_its_cross_section_area():
    r = 0.01
    sp = one_sector([[0.43, 0.57]], [[0.03, 0.04]], [r])  # ≥ 10σ from every edge
    for grid in (8, 32, 64):
        rho = sector_density(sp, grid, density_scale=2.5, dtype=np.float64)
        assert mass(rho, sp)[0] == pytest.approx(2.5 * np.pi * r * r, rel=1e-12)


@pytest.mark.parametrize(
    "center, fraction", [([0.0, 0.5], 0.5), ([0.5, 1.0], 0.5), ([0.0, 0.0], 0.25), ([-0.03, 0.5], None), ([1.1, 0.2], None)]
)
def test_a_strand_partly_outside_keeps_exactly_its_inside_part(center, fraction):
    sig = (0.04, 0.06)
    if fraction is None:  # the analytic fraction of the Gaussian inside [0, 1]²
        fraction = np.prod([ndtr((1 - c) / s) - ndtr((0 - c) / s) for c, s in zip(center, sig)])
    sp = one_sector([center], [sig], [0.02])
    rho = sector_density(sp, 32, dtype=np.float64)
    assert mass(rho, sp)[0] == pytest.approx(fraction * np.pi * 0.02**2, rel=1e-12)


def test_jax_kernel_matches_the_numpy_loop(rng):
    n, k = 40, 12
    sp = SplatBatch(
        rng.uniform(-0.2, 1.2, (n, k, 2)),
        rng.uniform(0.01, 0.3, (n, k, 2)),
        rng.uniform(0.001, 0.05, (n, k)),
        rng.uniform(size=(n, k)) < 0.7,
        rng.uniform(0.1, 2, n),
        np.sort(rng.uniform(0, 1, (n, 2)), axis=1),
    )
    ref = sector_density_numpy(sp, (16, 24))
    np.testing.assert_allclose(sector_density(sp, (16, 24), dtype=np.float64, chunk=7), ref, rtol=1e-12, atol=1e-14)
    f32 = sector_density(sp, (16, 24))
    assert f32.dtype == np.float32
    np.testing.assert_allclose(f32, ref, rtol=2e-5, atol=2e-6 * ref.max())


# -- through the cluster model -------------------------------------------------------------------------
def straight_cylinder(**kw) -> ClusterGeometry:
    spec = (
        dict(
            trajectory=[[0, 0, 0], [0, 0, 1], [0, 0, 2], [0, 0, 3]],
            half_axis_a=1.0,
            half_axis_b=1.0,
            layer_radii=(0.5, 0.75, 1.0),
            core_radius=0.25,
            s_t=1,
            s_u=8,
            normal0=[1, 0, 0],
        )
        | kw
    )
    return ClusterGeometry(ClusterSpec(**spec))


def straight_strands(xy, z=(-1.0, 4.0)) -> Strands:
    xy = np.asarray(xy, float)
    pts = np.stack([np.column_stack([xy, np.full(len(xy), z[0])]), np.column_stack([xy, np.full(len(xy), z[1])])], axis=1)
    return Strands.from_padded(pts)


def test_strand_across_a_sector_border_splits_its_mass_exactly():
    geom = straight_cylinder()
    r, v = 0.01, 0.6
    # on the u = π/4 border between sectors 0 and 1 of the middle track, offset by half a σ
    sigma_u = SIGMA_PER_RADIUS * r / v
    u = np.pi / 4 + 0.5 * sigma_u
    tab = build_sectors(geom, straight_strands([[v * np.cos(u), v * np.sin(u)]]), np.zeros(1, int), radius=r)
    sp = tab.splats()
    m = mass(sector_density(sp, 32, dtype=np.float64), sp)
    section0 = m.reshape(tab.shape)[0, 0]  # (tracks, phases) at t = 0
    assert np.count_nonzero(section0) == 2
    assert section0.sum() == pytest.approx(np.pi * r * r, rel=1e-12)
    assert section0[1, 1] == pytest.approx(ndtr(0.5) * np.pi * r * r, rel=1e-9)
    # the crossing record: one strand, in sector (track 1, phase 1), at the analytic (s, r)
    own = tab.crossings_of(int(tab.sector_id(0, 0, 1, 1)))
    assert own.size == 1
    np.testing.assert_allclose(tab.crossing_sr[own[0]], [(u - np.pi / 4) / (np.pi / 4), (v - 0.5) / 0.25], atol=1e-12)
    np.testing.assert_allclose(tab.crossing_xy[own[0]], [v * np.cos(u), v * np.sin(u)], atol=1e-12)


def test_uniform_strand_field_gives_a_flat_density():
    geom = straight_cylinder()
    h = 0.01  # square lattice of strands, spacing h; σ = 1.5 h makes the sum of Gaussians flat
    r = 1.5 * h / SIGMA_PER_RADIUS
    g = np.arange(-1, 1 + h / 2, h)
    xy = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    xy = xy[(np.hypot(*xy.T) > 0.25) & (np.hypot(*xy.T) < 1.0)]
    tab = build_sectors(geom, straight_strands(xy), np.zeros(len(xy), int), radius=r)
    grid = 32
    sel = tab.sector_id(0, 0, 1, np.arange(8))  # the middle track, v ∈ [0.5, 0.75]: 4σ from the envelope
    sp = tab.splats(sel)
    rho = sector_density(sp, grid, dtype=np.float64)
    expected = np.pi * r * r / h**2  # covered fraction of a lattice cell
    inner = rho[:, 4:-4, 8:-8]  # away from the track's radial edges (σ is ~1.5 cells)
    np.testing.assert_allclose(inner, expected, rtol=1e-6)  # measured: ~1e-14
    assert mass(rho, sp).sum() / sp.sector_areas().sum() == pytest.approx(expected, rel=1e-6)


# -- features --------------------------------------------------------------------------------------
def test_features_follow_their_definitions(rng):
    rho = rng.uniform(0, 2, (5, 8, 6))
    rho[3] = 0.0
    rows = rng.uniform(0.5, 2.0, (5, 6))
    f = sector_features(rho, rows, "moments")
    s, r = (np.arange(8) + 0.5) / 8, (np.arange(6) + 0.5) / 6
    for n in range(5):
        a = np.broadcast_to(rows[n], (8, 6))
        h_s = (rho[n] * a).sum(1) / rows[n].sum()
        h_t = rho[n].mean(0)
        mean = (rho[n] * a).sum() / a.sum()
        if n == 3:
            np.testing.assert_allclose(f[n, :3], [0.0, 0.5, 0.5])
            continue
        cs, ct = (s * h_s).sum() / h_s.sum(), (r * h_t).sum() / h_t.sum()
        cov = (rho[n] * np.outer(s - cs, r - ct)).sum() / rho[n].sum()
        contrast = np.sqrt(((rho[n] - mean) ** 2 * a).sum() / a.sum()) / mean
        want = [
            mean,
            cs,
            ct,
            ((s - cs) ** 2 * h_s).sum() / h_s.sum(),
            ((r - ct) ** 2 * h_t).sum() / h_t.sum(),
            cov,
            contrast,
            rho[n].max(),
        ]
        np.testing.assert_allclose(f[n], want, rtol=1e-12)
    assert feature_names("moments")[:3] == ("rho_st", "rho_s", "rho_t")


def test_centroids_converge_to_the_truncated_gaussian_centroid():
    c, sig = np.array([0.3, 0.62]), np.array([0.07, 0.05])
    sp = one_sector([c], [sig], [0.05], area_scale=1.0, v_range=(0.999, 1.0))  # nearly equal row areas
    a, b = (0 - c) / sig, (1 - c) / sig
    phi = lambda x: np.exp(-x * x / 2) / np.sqrt(2 * np.pi)  # noqa: E731
    exact = c + sig * (phi(a) - phi(b)) / (ndtr(b) - ndtr(a))
    for grid, tol in ((8, 5e-3), (64, 1e-4)):
        f = sector_features(sector_density(sp, grid, dtype=np.float64), sp, "basic")[0]
        np.testing.assert_allclose(f[1:], exact, atol=tol)
        assert f[0] == pytest.approx(np.pi * 0.05**2 * np.prod(ndtr(b) - ndtr(a)) / sp.sector_areas()[0], rel=1e-9)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 12))
def test_features_are_invariant_under_strand_order(seed, n):
    gen = np.random.default_rng(seed)
    k = 12
    mask = np.zeros((3, k), bool)
    mask[:, :n] = True
    sp = SplatBatch(
        gen.uniform(-0.1, 1.1, (3, k, 2)),
        gen.uniform(0.02, 0.3, (3, k, 2)),
        gen.uniform(0.001, 0.05, (3, k)),
        mask,
        gen.uniform(0.1, 2, 3),
        np.array([[0.2, 0.5], [0.5, 0.7], [0.0, 1.0]]),
    )
    perm = gen.permutation(k)
    shuffled = SplatBatch(sp.center[:, perm], sp.sigma[:, perm], sp.radius[:, perm], sp.mask[:, perm], sp.area_scale, sp.v_range)
    f0 = sector_features(sector_density(sp, 16, dtype=np.float64), sp, "moments")
    f1 = sector_features(sector_density(shuffled, 16, dtype=np.float64), shuffled, "moments")
    np.testing.assert_allclose(f1, f0, rtol=1e-10, atol=1e-13)


def test_features_invariant_when_the_strand_file_is_reordered(rng):
    geom = straight_cylinder(s_u=6)
    rad = np.sqrt(rng.uniform(0.25**2, 1, 300))
    ang = rng.uniform(0, 2 * np.pi, 300)
    xy = np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])
    perm = rng.permutation(300)
    out = []
    for order in (np.arange(300), perm):
        tab = build_sectors(geom, straight_strands(xy[order]), np.zeros(300, int), radius=0.02)
        sp = tab.splats()
        out.append(sector_features(sector_density(sp, 16, dtype=np.float64), sp, "moments"))
    np.testing.assert_allclose(out[1], out[0], rtol=1e-10, atol=1e-13)


def test_normalisation_statistics_and_pca(rng):
    x = rng.normal([1.0, 5.0, -2.0], [0.1, 3.0, 1e-3], (200, 3))
    stats = FeatureStats.fit(x, ("rho_st", "rho_s", "rho_t"))
    z = stats.normalize(x)
    np.testing.assert_allclose(z.mean(0), 0, atol=1e-12)
    np.testing.assert_allclose(z.std(0), 1, rtol=1e-12)
    np.testing.assert_allclose(stats.denormalize(z), x)
    assert FeatureStats.from_dict(stats.to_dict()).names == stats.names
    rho = rng.uniform(0, 1, (50, 8, 8))
    pca = PCABasis.fit(rho, 3)
    np.testing.assert_allclose(pca.components @ pca.components.T, np.eye(3), atol=1e-12)
    f = sector_features(rho, None, ("rho_st", "pc0", "pc2"), pca=pca)
    np.testing.assert_allclose(f[:, 1], (rho.reshape(50, -1) - pca.mean) @ pca.components[0])


# -- bad input -----------------------------------------------------------------------------------------
def test_bad_density_and_feature_input_names_the_field():
    sp = one_sector([[0.5, 0.5]], [[0.1, 0.1]], [0.01])
    for kwargs, field in (
        (dict(grid=0), "grid"),
        (dict(grid=(8, 8, 8)), "grid"),
        (dict(density_scale=-1.0), "density_scale"),
        (dict(dtype=np.float16), "dtype"),
        (dict(chunk=0), "chunk"),
    ):
        with pytest.raises(ValidationError) as exc:
            sector_density(sp, **kwargs)
        assert exc.value.field == field
    with pytest.raises(ValidationError) as exc:
        one_sector([[0.5, 0.5]], [[0.0, 0.1]], [0.01])
    assert exc.value.field == "sigma"
    with pytest.raises(ValidationError) as exc:
        sector_features(np.zeros((2, 4, 4)), None, ("rho_st", "nope"))
    assert exc.value.field == "features"
    with pytest.raises(ValidationError) as exc:
        sector_features(np.zeros((2, 4, 4)), None, "pc0")
    assert exc.value.field == "features"
    with pytest.raises(ValidationError) as exc:
        build_sectors(straight_cylinder(), straight_strands([[0.5, 0.0]]), np.zeros(1, int))
    assert exc.value.field == "radius"  # no thickness in the strands, no radius given
