"""HSVs and sectors, strand generation and assignment, the random sector sampler, real grooms."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from hairlut.errors import ValidationError
from hairlut.geometry import (
    ClusterGeometry,
    ClusterSpec,
    FeatureStats,
    SectorSpace,
    Strands,
    assign_strands,
    build_sectors,
    generate_strands,
    groom_sectors,
    read_strands,
    sample_sectors,
    sector_density,
    sector_features,
)

from .conftest import groom_path

WAVY = np.array([[0, 0, 0], [1, 0.5, 1.5], [2, 0, 3], [3, -0.5, 4.5], [4, 0, 6]], float)


def cylinder(**kw) -> ClusterGeometry:
    spec = (
        dict(
            trajectory=[[0, 0, 0], [0, 0, 1], [0, 0, 2], [0, 0, 4]],
            half_axis_a=2.0,
            half_axis_b=1.0,
            twist=0.3,
            layer_radii=(0.5, 1.0),
            core_radius=0.25,
            s_t=2,
            s_v=2,
            s_u=4,
            normal0=[1, 0, 0],
        )
        | kw
    )
    return ClusterGeometry(ClusterSpec(**spec))


def polylines(*lines) -> Strands:
    return Strands.from_list([np.asarray(p, float) for p in lines])


# -- sectors and HSVs ------------------------------------------------------------------------------
def test_sector_and_hsv_layout_with_analytic_corners():
    geom = cylinder()
    tab = build_sectors(geom, polylines([[0.1, 0.1, -1], [0.1, 0.1, 5]]), np.zeros(1, int), radius=0.01)
    assert tab.shape == (1, 3, 4, 4) and tab.n_sectors == 48 and tab.n_hsvs == 32
    np.testing.assert_allclose(geom.track_bounds[0], [0.25, 0.375, 0.5, 0.75, 1.0])
    top, bottom = tab.hsv_sectors.T
    assert (tab.t_index[bottom] == tab.t_index[top] + 1).all()
    for field in (tab.track, tab.u_index, tab.cluster):
        assert (field[bottom] == field[top]).all()
    assert (tab.layer == tab.track // 2).all()
    v = np.stack([tab.v_range[:, 0], tab.v_range[:, 1], tab.v_range[:, 1], tab.v_range[:, 0]], 1)
    u = np.stack([tab.u_range[:, 0], tab.u_range[:, 0], tab.u_range[:, 1], tab.u_range[:, 1]], 1)
    t = tab.t[:, None]
    want = np.stack([2 * v * np.cos(0.3 + u), v * np.sin(0.3 + u), 4 * np.broadcast_to(t, v.shape)], -1)
    np.testing.assert_allclose(tab.corners, want, atol=1e-10)
    # the strand at (0.1, 0.1) lies in the core (v ≈ 0.16 < 0.25): no crossing recorded
    assert tab.crossing_strand.size == 0


def test_crossings_keep_the_nearest_in_shell_point():
    geom = cylinder()
    x, y = 2 * 0.6 * np.cos(1.0), 0.6 * np.sin(1.0)  # v = 0.6 at polar angle 1 (u = 1 − 0.3)
    u_bend = [[x, y, -1], [x, y, 2.5], [3.0, 0.0, 2.5], [3.0, 0.0, -1]]  # crosses t = 0 twice: at v = 0.6 and outside
    far = [[x, y, -1], [x, y, 0.5], [-x, -y, 0.5], [-x, -y, 5]]  # crosses t = 0.5 and t = 1 at the opposite side
    tab = build_sectors(geom, polylines(u_bend, far), np.zeros(2, int), radius=0.01)
    first = tab.crossing_strand == 0
    assert set(tab.t_index[tab.crossing_sector[first]]) == {0, 1}  # t = 0 and t = 0.5; the t = 1 plane is missed
    np.testing.assert_allclose(tab.crossing_vu[first], [[0.6, 0.7]] * 2, atol=1e-12)
    sid = tab.crossing_sector[first][0]
    assert tab.track[sid] == 2 and tab.u_index[sid] == 0
    np.testing.assert_allclose(tab.crossing_sr[first][0], [0.7 / (np.pi / 2), (0.6 - 0.5) / 0.25], atol=1e-12)
    second = tab.crossing_strand == 1
    np.testing.assert_allclose(tab.crossing_vu[second][:, 0], 0.6, atol=1e-12)
    np.testing.assert_allclose(tab.crossing_point[second][:, 2], [0.0, 2.0, 4.0][: int(second.sum())], atol=1e-12)


def test_an_outlier_beyond_the_outer_layer_is_kept_at_the_rim_at_its_own_phase():
    """A strand of the cluster that crosses a section only beyond the outer layer (the fit's ellipse holds 95 % of the
    crossings) is counted, not lost: kept at the middle of the outermost track, at its own phase; its splat's mass lies
    in the shells.  A crossing inside the shells still wins over an outlier's, and the core still holds none."""
    from hairlut.geometry.sectors import RIM

    geom = cylinder()
    bounds = geom.track_bounds[0]
    rim = bounds[-2] + RIM * (bounds[-1] - bounds[-2])
    out_x, out_y = 2 * 1.5 * np.cos(2.0), 1.5 * np.sin(2.0)  # v = 1.5 at polar angle 2
    outlier = [[out_x, out_y, -1], [out_x, out_y, 5]]
    core = [[0.1, 0.1, -1], [0.1, 0.1, 5]]
    x, y = 2 * 0.6 * np.cos(1.0), 0.6 * np.sin(1.0)
    both = [[x, y, -1], [x, y, 2.5], [out_x, out_y, 2.5], [out_x, out_y, -1]]  # t = 0, 0.5: in the shells and beyond
    tab = build_sectors(geom, polylines(outlier, core, both), np.zeros(3, int), radius=0.01)
    out = tab.crossing_strand == 0
    assert sorted(tab.t_index[tab.crossing_sector[out]]) == [0, 1, 2]
    np.testing.assert_allclose(tab.crossing_vu[out], [[rim, 2.0 - 0.3]] * 3, atol=1e-12)
    np.testing.assert_allclose(tab.crossing_xy[out], [[2 * rim * np.cos(2.0), rim * np.sin(2.0)]] * 3, atol=1e-12)
    assert (tab.track[tab.crossing_sector[out]] == len(bounds) - 2).all()
    assert not (tab.crossing_strand == 1).any()
    np.testing.assert_allclose(tab.crossing_vu[tab.crossing_strand == 2], [[0.6, 0.7]] * 2, atol=1e-12)
    assert set(np.flatnonzero(out)) <= set(tab.splat_crossing)  # the outlier's crossings splat into the shells


@pytest.mark.parametrize("tilt_deg", [0.0, 30.0, 60.0, 85.0])
def test_a_tilted_strand_keeps_its_hair_per_unit_length(tilt_deg):
    """A straight strand at angle γ to the cluster's axis holds π r² / cos γ of hair per unit length of the axis:
    its crossing is the disc of that area (π r_eff² = π r² / cos γ), capped at MAX_TILT_STRETCH near the plane."""
    from hairlut.geometry.sectors import MAX_TILT_STRETCH

    g = np.radians(tilt_deg)
    d = np.array([np.sin(g), 0.0, np.cos(g)])
    start = np.array([0.0, 0.3, 2.0]) - 3.0 * d  # through (0, 0.3, 2): inside the shells at t = 0.5
    tab = build_sectors(cylinder(), polylines([start, start + 6.0 * d]), np.zeros(1, int), radius=0.01)
    mid = tab.t_index[tab.crossing_sector] == 1
    assert mid.sum() == 1
    stretch = min(1.0 / np.cos(g), MAX_TILT_STRETCH)
    np.testing.assert_allclose(tab.crossing_radius[mid], 0.01, rtol=1e-12)
    np.testing.assert_allclose(tab.crossing_stretch[mid], stretch, rtol=1e-12)
    np.testing.assert_allclose(tab.splat_radius()[np.isin(tab.splat_crossing, np.flatnonzero(mid))] ** 2, 0.01**2 * stretch)


# -- strand generation and assignment --------------------------------------------------------------------
@pytest.mark.parametrize("profile", ["uniform", "gaussian", "clumped"])
def test_generated_strands_are_deterministic_and_inside_their_cluster(profile):
    specs = [
        ClusterSpec(WAVY + [3.0 * i, 0, 0], [0.5, 0.7, 0.6], [0.4, 0.3], [0.0, 2.0], layer_radii=(0.5, 0.8, 1.0), core_radius=0.2)
        for i in range(2)
    ]
    geom = ClusterGeometry(specs)
    kw = dict(radius=(0.002, 0.004), profile=profile, spread=0.2, jitter=0.05, points=16)
    a, cl = generate_strands(geom, [40, 25], seed=7, **kw)
    b, _ = generate_strands(geom, [40, 25], seed=7, **kw)
    c, _ = generate_strands(geom, [40, 25], seed=8, **kw)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.thickness, b.thickness)
    assert not np.array_equal(a.points, c.points)
    assert a.n_strands == 65 and (np.bincount(cl) == [40, 25]).all()
    assert ((a.thickness >= 0.004) & (a.thickness <= 0.008)).all()
    t = np.tile(np.linspace(0, 1, 16), a.n_strands)
    sec = geom.sections_of(np.repeat(cl, 16), t)
    rel = a.points - sec.origin
    v = np.hypot(np.sum(rel * sec.normal, 1) / sec.a, np.sum(rel * sec.binormal, 1) / sec.b)
    assert v.min() >= 0.2 - 1e-9 and v.max() <= 1.0 + 1e-9
    np.testing.assert_array_equal(assign_strands(a, geom), cl)


def test_gaussian_profile_concentrates_strands_toward_the_axis():
    geom = ClusterGeometry(ClusterSpec(WAVY, 0.5, 0.5, layer_radii=(1.0,), core_radius=0.0))
    means = {}
    for profile in ("uniform", "gaussian"):
        s, _ = generate_strands(geom, 400, profile=profile, spread=0.2, points=2, seed=1)
        rel = s.points[::2] - geom.sections(0.0).origin[0, None]
        means[profile] = np.mean(np.linalg.norm(rel, axis=1)) / 0.5
    assert means["uniform"] == pytest.approx(2 / 3, abs=0.05)  # mean radius of a uniform disc
    assert means["gaussian"] == pytest.approx(0.2 * np.sqrt(np.pi / 2), abs=0.03)  # Rayleigh mean (barely truncated)


def test_assignment_rejects_far_strands_and_bad_generation_input():
    geom = cylinder()
    far = polylines([[50, 0, 0], [50, 0, 4]], [[0.5, 0, 0], [0.5, 0, 4]])
    np.testing.assert_array_equal(assign_strands(far, geom, max_distance=5.0), [-1, 0])
    for kw, field in (
        (dict(profile="curly"), "profile"),
        (dict(radius=-1.0), "radius"),
        (dict(points=1), "points"),
        (dict(seed=-1), "seed"),
        (dict(jitter=-0.1), "jitter"),
    ):
        with pytest.raises(ValidationError) as exc:
            generate_strands(geom, 5, **kw)
        assert exc.value.field == field


# -- the random sector sampler --------------------------------------------------------------------------
def test_sampler_is_deterministic_and_stays_in_its_space():
    space = SectorSpace(strands=(0, 20), s_u=(6, 12))
    a, b, c = sample_sectors(300, space, seed=3), sample_sectors(300, space, seed=3), sample_sectors(300, space, seed=4)
    for f in ("center", "sigma", "radius", "mask"):
        assert np.array_equal(getattr(a.splats, f), getattr(b.splats, f))
    assert not np.array_equal(a.splats.center, c.splats.center)
    p = a.params
    assert p["strands"].min() >= 0 and p["strands"].max() <= 20
    assert (a.splats.mask.sum(axis=1) == p["strands"]).all()
    assert ((p["s_u"] >= 6) & (p["s_u"] <= 12)).all()
    assert ((p["v_range"][:, 1] <= 1) & (p["v_range"][:, 0] >= 0)).all()
    assert set(np.unique(p["profile"])) == {0, 1, 2}
    with pytest.raises(ValidationError) as exc:
        SectorSpace(radius_rel=(0.1, 0.01))
    assert exc.value.field == "space.radius_rel"


def _coverage(groom: str, n_clusters: int):
    path = groom_path(groom)
    strands = read_strands(path)
    sampled = sample_sectors(3000, seed=11)
    rho = sector_density(sampled.splats, 16, dtype=np.float64)
    ref = sector_features(rho, sampled.splats, "basic")
    stats = FeatureStats.fit(ref, ("rho_st", "rho_s", "rho_t"))
    tree = cKDTree(stats.normalize(ref))
    for radius in (0.01, 0.05):  # guide-strand radii in the groom's units, thin and thick
        tab, geom, labels = groom_sectors(strands, n_clusters, radius=radius, s_t=8, s_u=12, seed=0)
        assert (labels >= 0).all() and geom.n_clusters <= n_clusters
        keep = np.diff(tab.splat_offsets) > 0  # sectors some strand reaches
        sp = tab.splats(np.flatnonzero(keep))
        real = sector_features(sector_density(sp, 16, dtype=np.float64), sp, "basic")
        lo, hi = np.percentile(real, 1, axis=0), np.percentile(real, 99, axis=0)
        assert (lo >= ref.min(axis=0)).all() and (hi <= ref.max(axis=0)).all()
        dist, _ = tree.query(stats.normalize(real))
        assert np.percentile(dist, 99) < 0.5, np.percentile(dist, [50, 90, 99])


def test_sampler_covers_sectors_cut_from_the_sintel_groom():
    _coverage("sintel_lite.tfx", 20)


@pytest.mark.slow
def test_sampler_covers_sectors_cut_from_the_ratboy_groom():
    _coverage("ratboy_mohawk.tfx", 60)
