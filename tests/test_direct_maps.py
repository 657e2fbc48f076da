"""Direct sector maps (issue 12's ``direct`` method): every sector at its own exact angles, one kernel.

The analytic chord integral of a Gaussian strand, agreement with the HRIR tracer at the same
sampling (a grid of angles and a hypothesis property), empty and saturated sectors, grazing
and wrapped angles, and input validation.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut.errors import HairlutError, ValidationError
from hairlut.geometry.density import sector_density
from hairlut.geometry.sampler import sample_sectors
from hairlut.hrir import resolve_recipe, trace_sectors
from hairlut.march import GEOM, sector_geometry
from hairlut.march._direct import bucket, direct_sector_maps

COL = {k: i for i, k in enumerate(GEOM)}
P = 32


def _recipe(**trace):
    return resolve_recipe({"trace": {"pixels": P, "steps": 48, **trace}})


def _random(n=4, grid=(16, 16), seed=11, pixels=P):
    s = sample_sectors(n, seed=seed)
    return sector_density(s.splats, grid), sector_geometry(s.params, kappa=2 / np.pi, n_pix=pixels)


# ------------------------------------------------------------------------------------------------
# one strand: α = 1 − exp(−σ_t ∫ρ ds), ∫ρ ds of a 2-D Gaussian along a line in closed form


def _one_strand_sector(sigma=0.09, n_s=512, n_r=384, sigma_t=5.0, pixels=64):
    """An annular sector v ∈ [1, 2], Δu = π/4, holding one Gaussian strand at its middle: ρ given at
    the cell centres (peak 1).  Returns (ρ, geometry row, strand centre in the local frame)."""
    params = {
        "phase": np.array([0.3]),
        "s_u": np.array([8]),
        "v_range": np.array([[1.0, 2.0]]),
        "aspect": np.array([1.0]),
        "radius_rel": np.array([0.05]),
    }
    g = sector_geometry(params, kappa=1.0, n_pix=pixels)
    g[:, COL["sigma_t"]] = sigma_t
    phi = 0.3 + np.pi / 4 * (np.arange(n_s) + 0.5) / n_s
    v = 1.0 + (np.arange(n_r) + 0.5) / n_r
    x, y = v[None, :] * np.cos(phi[:, None]), v[None, :] * np.sin(phi[:, None])
    centre = 1.5 * np.array([np.cos(0.3 + np.pi / 8), np.sin(0.3 + np.pi / 8)])
    rho = np.exp(-((x - centre[0]) ** 2 + (y - centre[1]) ** 2) / (2 * sigma**2))
    beta, c = g[0, COL["beta"]], g[0, [COL["cx"], COL["cy"]]]
    local = np.array([[np.cos(beta), np.sin(beta)], [-np.sin(beta), np.cos(beta)]]) @ (centre - c)
    return rho[None].astype(np.float32), g, local


def test_one_strand_alpha_is_the_analytic_chord_integral():
    sigma, sigma_t, pixels = 0.09, 5.0, 64
    rho, g, o = _one_strand_sector(sigma, sigma_t=sigma_t, pixels=pixels)
    views = np.array([0.0, 0.7, np.pi / 2, 2.0, 3.3, 4.5, 3 * np.pi / 2])
    n = len(views)
    alpha, re = direct_sector_maps(
        np.repeat(rho, n, 0), np.repeat(g, n, 0), views, np.zeros((n, 0)), _recipe(pixels=pixels, steps=1024, smooth=False)
    )
    R = g[0, COL["extent"]]
    t = -R + (np.arange(pixels) + 0.5) * 2 * R / pixels  # pixel centres (one ray per pixel)
    for i, th in enumerate(views):
        e = np.array([-np.sin(th), np.cos(th)])
        dist = o @ e - t
        line = np.sqrt(2 * np.pi) * sigma * np.exp(-(dist**2) / (2 * sigma**2))  # ∫ρ ds, peak density 1
        np.testing.assert_allclose(alpha[i], 1 - np.exp(-sigma_t * line), atol=1e-4, rtol=0)
    assert alpha.max() > 0.6 and (alpha < 1e-3).sum() > pixels  # not vacuous: a peak and empty pixels
    assert re.shape == (n, 0, pixels)


# ------------------------------------------------------------------------------------------------
# the same quantity as the tracer


def _as_pairs(rho, g, views, lights):
    """Every (sector, view) as its own row, all with the same lights: inputs for direct_sector_maps."""
    n, V = len(rho), len(views)
    return (np.repeat(rho, V, 0), np.repeat(g, V, 0), np.tile(views, n), np.tile(lights, (n * V, 1)))


@pytest.mark.parametrize("shadow,rays", [(False, 1), (True, 1), (True, 2)])
def test_direct_equals_the_tracer_on_an_angle_grid(shadow, rays):
    rho, g = _random(4, seed=3)
    views = np.arange(8) * 2 * np.pi / 8 + 0.05
    lights = np.array([0.4, 2.9, 5.0])
    rec = _recipe(self_shadow=shadow, rays_per_pixel=rays)
    a_ref, r_ref = trace_sectors(rho, g, rec, views=views, lights=lights)
    a, r = direct_sector_maps(*_as_pairs(rho, g, views, lights), rec, shadow_lookup="grid")
    assert a_ref.max() > 0.3 and r_ref.max() > 0.05
    np.testing.assert_allclose(a.reshape(a_ref.shape), a_ref, atol=2e-6, rtol=0)
    np.testing.assert_allclose(r.reshape(r_ref.shape), r_ref, atol=1e-5, rtol=0)  # p = 20 amplifies rounding


def test_march_shadow_lookup_is_close_to_the_tracers_grid():
    """The default light-depth lookup skips the tracer's Cartesian resampling: α is identical, re
    differs by that one interpolation only (and only where shadows fall)."""
    rho, g = _random(4, seed=5)
    views, lights = np.arange(6) * 2 * np.pi / 6, np.array([1.0, 4.0])
    inputs = _as_pairs(rho, g, views, lights)
    rec = _recipe(self_shadow=True)
    a_g, r_g = direct_sector_maps(*inputs, rec, shadow_lookup="grid")
    a_m, r_m = direct_sector_maps(*inputs, rec, shadow_lookup="march")
    _, r_0 = direct_sector_maps(*inputs, _recipe(self_shadow=False))
    np.testing.assert_array_equal(a_m, a_g)
    shadowing = np.linalg.norm(r_0 - r_g)
    assert shadowing > 0.05 * np.linalg.norm(r_g)  # the shadows matter here
    assert np.linalg.norm(r_m - r_g) < 0.1 * shadowing
    assert (r_m <= r_0 + 1e-6).all()  # shadows only darken


@settings(max_examples=12)
@given(
    seed=st.integers(0, 10_000),
    shadow=st.booleans(),
    rays=st.sampled_from([1, 2]),
    angles=st.lists(st.floats(-10.0, 10.0, allow_nan=False), min_size=3, max_size=3),
)
def test_property_direct_equals_the_tracer_at_random_angles(seed, shadow, rays, angles):
    rho, g = _random(1, seed=seed, grid=(12, 12))
    tv, tl = np.array(angles[:1]), np.array(angles[1:])
    rec = _recipe(self_shadow=shadow, rays_per_pixel=rays)
    a_ref, r_ref = trace_sectors(rho, g, rec, views=np.mod(tv, 2 * np.pi), lights=np.mod(tl, 2 * np.pi))
    a, r = direct_sector_maps(rho, g, tv, tl[None], rec, shadow_lookup="grid")
    np.testing.assert_allclose(a[0], a_ref[0, 0], atol=2e-6, rtol=0)
    np.testing.assert_allclose(r[0], r_ref[0, 0], atol=1e-5, rtol=0)


def test_each_sector_uses_its_own_angles():
    """A batch of sectors with different angles gives each the map it gets alone (no mixing, padding
    or bucketing effects)."""
    rho, g = _random(11, seed=7)
    rng = np.random.default_rng(2)
    tv, tl = rng.uniform(0, 2 * np.pi, 11), rng.uniform(0, 2 * np.pi, (11, 2))
    rec = _recipe()
    a, r = direct_sector_maps(rho, g, tv, tl, rec, block=4)
    for i in (0, 5, 10):
        ai, ri = direct_sector_maps(rho[i : i + 1], g[i : i + 1], tv[i : i + 1], tl[i : i + 1], rec)
        np.testing.assert_allclose(a[i], ai[0], atol=1e-6)
        np.testing.assert_allclose(r[i], ri[0], atol=1e-6)


# ------------------------------------------------------------------------------------------------
# limits


def test_empty_sectors_are_exactly_zero_and_skipped():
    rho, g = _random(5, seed=9)
    rho[[1, 3]] = 0.0
    tv, tl = np.linspace(0, 6, 5), np.full((5, 2), 1.0)
    a, r = direct_sector_maps(rho, g, tv, tl, _recipe())
    assert np.all(a[[1, 3]] == 0) and np.all(r[[1, 3]] == 0)
    assert a[[0, 2, 4]].max() > 0.1
    a0, r0 = direct_sector_maps(np.zeros_like(rho), g, tv, tl, _recipe())  # nothing to do at all
    assert a0.shape == (5, P) and r0.shape == (5, 2, P) and not a0.any() and not r0.any()
    a1, r1 = direct_sector_maps(rho[:0], g[:0], tv[:0], tl[:0], _recipe())
    assert a1.shape == (0, P) and r1.shape == (0, 2, P)


@pytest.mark.parametrize("shadow_lookup", ["march", "grid"])
def test_very_dense_sector_saturates_without_nan(shadow_lookup):
    rho, g = _random(3, seed=13)
    rho = rho * 1e8 + 1e6  # also regions with no gradient: the fallback normal
    tv, tl = np.array([0.0, 1.0, 4.0]), np.array([[0.5, 3.0]] * 3)
    a, r = direct_sector_maps(rho, g, tv, tl, _recipe(smooth=False), shadow_lookup=shadow_lookup)
    assert np.isfinite(a).all() and np.isfinite(r).all()
    assert a.max() == pytest.approx(1.0, abs=1e-6)
    assert np.all(a[a > 0] > 1 - 1e-4)
    assert r.max() <= 0.1 + 0.6 + 0.3 + 1e-5  # k_a + k_d + k_s


def test_grazing_and_wrapped_angles_are_finite_and_periodic():
    rho, g = _random(2, seed=17)
    rho2, g2 = np.repeat(rho, 4, 0), np.repeat(g, 4, 0)
    two_pi = 2 * np.pi
    tv = np.tile([np.pi / 2, -np.pi / 2, 0.0, two_pi], 2)
    tl = np.tile([[0.0, np.pi / 2], [-np.pi / 2, two_pi], [two_pi, -two_pi], [0.0, 0.0]], (2, 1))
    a, r = direct_sector_maps(rho2, g2, tv, tl, _recipe())
    assert np.isfinite(a).all() and np.isfinite(r).all() and a.max() > 0.05
    a = a.reshape(2, 4, P)
    r = r.reshape(2, 4, 2, P)
    np.testing.assert_array_equal(a[:, 2], a[:, 3])  # θv = 0 and 2π are the same view
    np.testing.assert_array_equal(r[:, 2, 0], r[:, 3, 0])  # θl = 2π and 0
    # −π/2 ≡ 3π/2, and a shift by 2π anywhere changes nothing (to float32 rounding of the angle)
    a3, r3 = direct_sector_maps(rho2, g2, tv + two_pi * np.tile([1, 1, -3, 2], 2), tl - two_pi, _recipe())
    np.testing.assert_allclose(a3.reshape(a.shape), a, atol=1e-6)
    np.testing.assert_allclose(r3.reshape(r.shape), r, atol=2e-5)


def test_bucketed_sizes_are_few_and_sufficient():
    sizes = {bucket(n, 64) for n in range(1, 2000)}
    assert len(sizes) < 20
    for n in (1, 7, 8, 9, 63, 64, 65, 200, 1999):
        b = bucket(n, 64)
        assert b >= n and (b <= 64 or b % 64 == 0) and (n <= 8 or b < 2 * n)


# ------------------------------------------------------------------------------------------------
# validation


def _good():
    rho, g = _random(3, seed=1)
    return {"density": rho, "geometry": g, "theta_v": np.zeros(3), "theta_l": np.zeros((3, 2))}


@pytest.mark.parametrize(
    "name,value",
    [
        ("density", np.zeros((3, 16))),
        ("density", np.full((3, 16, 16), np.nan)),
        ("density", -np.ones((3, 16, 16))),
        ("geometry", np.zeros((2, len(GEOM)))),
        ("geometry", np.zeros((3, 5))),
        ("theta_v", np.zeros(4)),
        ("theta_v", np.array([0.0, np.nan, 1.0])),
        ("theta_v", np.array([0.0, np.inf, 1.0])),
        ("theta_l", np.zeros(3)),
        ("theta_l", np.zeros((2, 2))),
        ("theta_l", np.array([[0.0, 1.0], [np.inf, 0.0], [0.0, 0.0]])),
    ],
)
def test_bad_inputs_name_the_argument(name, value):
    args = {**_good(), name: value}
    with pytest.raises(ValidationError) as err:
        direct_sector_maps(args["density"], args["geometry"], args["theta_v"], args["theta_l"], _recipe())
    assert err.value.field == name


def test_bad_geometry_values_and_settings_are_rejected():
    args = _good()
    g = args["geometry"].copy()
    g[0, COL["extent"]] = 0.0
    with pytest.raises(ValidationError, match="geometry"):
        direct_sector_maps(args["density"], g, args["theta_v"], args["theta_l"], _recipe())
    g[0, COL["extent"]] = np.nan
    with pytest.raises(ValidationError, match="geometry"):
        direct_sector_maps(args["density"], g, args["theta_v"], args["theta_l"], _recipe())
    call = (args["density"], args["geometry"], args["theta_v"], args["theta_l"])
    for kwargs, field in (
        ({"n_pix": 0}, "n_pix"),
        ({"rays": 0}, "rays"),
        ({"shadow_lookup": "nope"}, "shadow_lookup"),
        ({"block": 0}, "block"),
        ({"bogus": 1}, "bogus"),
    ):
        with pytest.raises(ValidationError) as err:
            direct_sector_maps(*call, _recipe(), **kwargs)
        assert err.value.field == field
    with pytest.raises(ValidationError) as err:
        direct_sector_maps(*call, {"trace": {}})
    assert err.value.field == "recipe"


def test_outputs_are_finite_or_an_error_never_a_silent_nan():
    """Densities near float32's limit overflow inside the kernel (gradients, optical depth): the
    caller gets finite maps or a HairlutError, never NaN."""
    args = _good()
    rho = (args["density"] / args["density"].max() * 3e38).astype(np.float32)
    try:
        a, r = direct_sector_maps(rho, args["geometry"], args["theta_v"], args["theta_l"], _recipe())
    except HairlutError as e:
        assert "non-finite" in str(e)
    else:
        assert np.isfinite(a).all() and np.isfinite(r).all()


# ------------------------------------------------------------------------------------------------
# a scene's sectors as inputs


def test_scene_sector_inputs_match_the_online_frames_and_densities():
    from hairlut.geometry import ClusterGeometry, azimuths, build_sectors, sector_axes
    from hairlut.march._direct import scene_sector_inputs, sector_extent
    from hairlut.scene import resolve_scene, scene_clusters
    from hairlut.synth import sector_frames

    from ._synth_fixtures import scene, synthetic_db

    sc = resolve_scene(scene())
    rec = resolve_recipe({"sectors": {"grid": [8, 8]}, "trace": {"pixels": 16, "steps": 32}})
    spec, strands = scene_clusters(sc)[0]
    geom = ClusterGeometry(spec)
    tb = build_sectors(geom, strands, np.zeros(strands.n_strands, np.int64))
    fr = sector_frames(geom, tb, synthetic_db())
    np.testing.assert_allclose(sector_extent(tb), fr.extent, rtol=1e-12)
    dens, g = scene_sector_inputs(tb, rec, extent=fr)
    a_axis = tb.half_axes[:, 0]
    np.testing.assert_array_equal(dens, sector_density(tb.splats(), (8, 8)))
    np.testing.assert_allclose(g[:, COL["extent"]], fr.extent / a_axis, rtol=1e-12)
    np.testing.assert_allclose(g[:, COL["aspect"]], tb.half_axes[:, 1] / a_axis, rtol=1e-12)
    _, g_default = scene_sector_inputs(tb, rec)
    np.testing.assert_allclose(g_default, g, rtol=1e-12)
    tv, tl = azimuths(*sector_axes(geom, tb), sc.view, sc.lights)
    a, r = direct_sector_maps(dens, g, tv, tl, rec)
    assert a.shape == (tb.n_sectors, 16) and r.shape == (tb.n_sectors, len(sc.lights), 16)
    live = dens.reshape(len(dens), -1).max(1) > 0
    assert live.any() and (a[live].max(1) > 0).all() and not a[~live].any()
    with pytest.raises(ValidationError) as err:
        scene_sector_inputs(tb, rec, extent=np.ones(3))
    assert err.value.field == "extent"
