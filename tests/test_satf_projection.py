"""The SATF's projection features (issue 12, satf item): each sector's own density projected at 8 views.

Hand-computed profiles of a uniform annular slab (exact chord lengths) and of one Gaussian strand (its
closed-form line integral); a database whose records are a scene's own sectors finds every sector at
distance 0 and returns its HRIRs; the feature set round-trips through the file (old feature sets still
read); bad option values are rejected by name.
"""

import numpy as np
import pytest

from hairlut import errors
from hairlut.geometry import sector_features
from hairlut.hrir import resolve_recipe, sector_projections
from hairlut.hrir._projection import BINS, COMPONENTS, CUMULATIVE, DIRECTIONS, SUB, fit_projection, profile
from hairlut.march import GEOM, sector_geometry

from .test_direct_maps import _one_strand_sector

COL = {k: i for i, k in enumerate(GEOM)}


def _lanes(R):
    """Ray offsets t along the image line: BINS·SUB rays over [−R, R] (the march's lanes)."""
    n = BINS * SUB
    return -R + (np.arange(n) + 0.5) * 2 * R / n


def _bins(opacity):
    """(D, BINS·SUB) ray opacities → (D·BINS,) bin means."""
    return opacity.reshape(DIRECTIONS, BINS, SUB).mean(-1).ravel()


def _views():
    return np.pi * np.arange(DIRECTIONS) / DIRECTIONS


def _local_to_ellipse(g):
    beta, c = g[COL["beta"]], g[[COL["cx"], COL["cy"]]]
    return c, np.array([[np.cos(beta), -np.sin(beta)], [np.sin(beta), np.cos(beta)]])


def _chord(p0, d, v0, v1, phase, du, R):
    """Length of {z ∈ [−R, R] : p0 + z d in the annular wedge v0 ≤ |p| ≤ v1, phase ≤ φ ≤ phase + du}
    (du < π, so the wedge is two half-planes), by exact interval arithmetic."""

    def disc(v):  # z interval with |p0 + z d| ≤ v (d is a unit vector)
        b, c = p0 @ d, p0 @ p0 - v * v
        disc_ = b * b - c
        return None if disc_ < 0 else (-b - np.sqrt(disc_), -b + np.sqrt(disc_))

    lo, hi = -R, R
    for u, sign in ((np.array([np.cos(phase), np.sin(phase)]), 1.0), (np.array([np.cos(phase + du), np.sin(phase + du)]), -1.0)):
        # sign · cross(u, p) ≥ 0, linear in z: a + b z ≥ 0
        a, b = sign * (u[0] * p0[1] - u[1] * p0[0]), sign * (u[0] * d[1] - u[1] * d[0])
        if abs(b) < 1e-15:
            if a < 0:
                return 0.0
        elif b > 0:
            lo = max(lo, -a / b)
        else:
            hi = min(hi, -a / b)
    outer, inner = disc(v1), disc(v0)
    if outer is None or hi <= lo:
        return 0.0
    pieces = [(outer[0], outer[1])] if inner is None else [(outer[0], inner[0]), (inner[1], outer[1])]
    return sum(max(0.0, min(hi, b) - max(lo, a)) for a, b in pieces)


def test_uniform_slab_profile_is_the_exact_chord_integral():
    params = {
        "phase": np.array([0.3]),
        "s_u": np.array([8]),
        "v_range": np.array([[1.0, 2.0]]),
        "aspect": np.array([1.0]),
        "radius_rel": np.array([0.05]),
    }
    g = sector_geometry(params, kappa=1.0, n_pix=64)[0]
    sigma_t, rho0, steps = 0.8, 1.5, 4096
    g[COL["sigma_t"]] = sigma_t
    got = sector_projections(np.full((1, 8, 8), rho0), g[None], n_steps=steps)[0]
    R = g[COL["extent"]]
    c, rot = _local_to_ellipse(g)
    want = np.zeros((DIRECTIONS, BINS * SUB))
    for i, th in enumerate(_views()):
        d, e = np.array([np.cos(th), np.sin(th)]), np.array([-np.sin(th), np.cos(th)])
        for j, t in enumerate(_lanes(R)):
            chord = _chord(c + rot @ (t * e), rot @ d, 1.0, 2.0, 0.3, np.pi / 4, R)
            want[i, j] = 1 - np.exp(-sigma_t * rho0 * chord)
    # the midpoint rule misplaces each of a ray's ≤ 4 boundary crossings by at most half a step
    step = 2 * R / steps
    np.testing.assert_allclose(got, _bins(want), atol=sigma_t * rho0 * 2 * step, rtol=0)
    assert got.max() > 0.5 and (got == 0).sum() > 8  # not vacuous: dense bins and empty ones


def test_one_strand_profile_is_the_gaussian_line_integral():
    sigma, sigma_t = 0.09, 5.0
    rho, g, o = _one_strand_sector(sigma, sigma_t=sigma_t)
    got = sector_projections(rho, g, n_steps=1024)[0]
    R = g[0, COL["extent"]]
    want = []
    for th in _views():
        e = np.array([-np.sin(th), np.cos(th)])
        line = np.sqrt(2 * np.pi) * sigma * np.exp(-((o @ e - _lanes(R)) ** 2) / (2 * sigma**2))  # ∫ρ ds, peak 1
        want.append(1 - np.exp(-sigma_t * line))
    np.testing.assert_allclose(got, _bins(np.array(want)), atol=1e-4, rtol=0)
    assert got.max() > 0.3 and (got < 1e-3).sum() > DIRECTIONS * BINS // 2


def test_empty_sectors_are_zero_and_the_basis_pads():
    prof = sector_projections(np.zeros((3, 4, 4)), np.ones((3, len(GEOM))), n_steps=8)
    assert prof.shape == (3, DIRECTIONS * BINS) and not prof.any()
    rng = np.random.default_rng(2)
    x = rng.random((5, DIRECTIONS * BINS))
    basis, scores, stats = fit_projection(x)
    assert basis.components.shape == (COMPONENTS, 2 * DIRECTIONS * BINS) and not basis.components[5:].any()
    assert stats.names[0] == "proj0" and np.all(stats.std == stats.std[0])
    # the profile: per direction the bins, then CUMULATIVE × their running sum over the bins
    prof = profile(x).reshape(5, DIRECTIONS, 2 * BINS)
    q = x.reshape(5, DIRECTIONS, BINS)
    np.testing.assert_allclose(prof[..., :BINS], q)
    np.testing.assert_allclose(prof[..., -1], CUMULATIVE * q.mean(-1))
    # the scores keep the profiles' distances (N − 1 ≤ 24 components span the centred records)
    x = profile(x)
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    np.testing.assert_allclose(np.linalg.norm(scores[:, None] - scores[None], axis=-1), d, atol=1e-12)


def _scene_db(tmp_path):
    """A scene (method satf, k = 1) and an hrir_db whose records are that scene's own sectors, traced."""
    from hairlut.hrir._bake import trace_sectors
    from hairlut.hrir._io import PARAMS, assemble
    from hairlut.march import scene_sector_inputs
    from hairlut.scene import resolve_scene
    from hairlut.synth import prepare

    from ._synth_fixtures import scene

    given = scene()
    given["render"] = {**given["render"], "method": "direct"}
    pr = prepare(resolve_scene(given))
    recipe = resolve_recipe(
        {
            "sectors": {"grid": [8, 8], "features": "projection"},
            "angles": {"views": 8, "lights": 4},
            "trace": {"pixels": 16, "steps": 32},
        }
    )
    parts = [scene_sector_inputs(pc.table, recipe, extent=pc.frames.extent) for pc in pr.clusters]
    dens, geom = np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    alpha, refl = trace_sectors(dens, geom, recipe)
    data = {
        "alpha": np.asarray(alpha),
        "reflectance": np.asarray(refl),
        "density": dens.astype(np.float32),
        "geometry": geom,
        "params": {p: np.zeros(len(dens)) for p in PARAMS},
    }
    path = assemble(tmp_path / "own.h5", recipe, data)
    given["render"] = {**given["render"], "method": "satf", "neighbours": 1}
    given["tables"] = {"hrir": {"sectors": {"grid": [8, 8], "features": "projection"}}}
    return resolve_scene(given), path, dens


def test_a_scene_whose_sectors_are_the_records_finds_them(tmp_path):
    from hairlut.hrir import load_hrir_db
    from hairlut.synth import prepare

    sc, path, dens = _scene_db(tmp_path)
    db = load_hrir_db(path)
    assert db.projection is not None and db.features.shape == (len(dens), COMPONENTS)
    pr = prepare(sc, db)
    occ = np.asarray(pr.frames.occupied)
    assert occ.sum() > 10
    # each occupied sector's own projection features are its record's: distance 0, its own index
    np.testing.assert_allclose(pr.frames.features[occ], db.features[occ], atol=1e-9)
    np.testing.assert_array_equal(np.asarray(pr.index.nbr)[occ, 0], np.flatnonzero(occ))
    v, l_ = 3, 2  # at grid angles the lookup returns the record's own HRIR rows
    re, a, idx, w = db.query(pr.frames.features[occ], 2 * np.pi * v / 8, 2 * np.pi * l_ / 4, k=1)
    np.testing.assert_array_equal(idx[:, 0], np.flatnonzero(occ))
    np.testing.assert_allclose(a, db.alpha[occ, v], atol=1e-6)
    np.testing.assert_allclose(re, db.reflectance[occ, v, l_], atol=1e-6)


def test_old_feature_sets_still_read_and_bad_options_are_named(tmp_path):
    from hairlut.hrir import bake, load_hrir_db, projection_features

    base = {"sectors": {"count": 3}, "angles": {"views": 4, "lights": 2}, "trace": {"pixels": 8, "steps": 8}}
    bake(base, tmp_path / "basic.h5")
    db = load_hrir_db(tmp_path / "basic.h5")
    assert db.projection is None and db.stats.names == ("rho_st", "rho_s", "rho_t")
    with pytest.raises(errors.ValidationError) as err:
        projection_features(db, db.density, np.stack([db.geometry[c] for c in GEOM], 1))
    assert err.value.field == "db.features"
    with pytest.raises(errors.ValidationError) as err:
        resolve_recipe({"sectors": {"features": "projections"}})
    assert err.value.field == "sectors.features"
    with pytest.raises(errors.ValidationError) as err:
        sector_features(np.zeros((2, 4, 4)), None, "projection")
    assert err.value.field == "features"
    for name, kw in (("n_steps", {"n_steps": 1}), ("bins", {"n_steps": 8, "bins": 0})):
        with pytest.raises(errors.ValidationError) as err:
            sector_projections(np.zeros((1, 4, 4)), np.ones((1, len(GEOM))), **kw)
        assert err.value.field == name
    with pytest.raises(errors.ValidationError) as err:
        sector_projections(np.zeros((1, 4, 4)), np.ones((2, len(GEOM))), n_steps=8)
    assert err.value.field == "geometry"


def test_reindex_writes_the_file_a_bake_of_that_feature_set_writes(tmp_path):
    from hairlut.hrir import bake, load_hrir_db, reindex

    base = {"sectors": {"count": 4}, "angles": {"views": 4, "lights": 2}, "trace": {"pixels": 8, "steps": 8}}
    bake(base, tmp_path / "basic.h5")
    bake({**base, "sectors": {"count": 4, "features": "projection"}}, tmp_path / "proj.h5")
    reindex(tmp_path / "basic.h5", tmp_path / "re.h5", "projection")
    assert (tmp_path / "re.h5").read_bytes() == (tmp_path / "proj.h5").read_bytes()
    db = load_hrir_db(tmp_path / "re.h5")
    assert db.recipe["sectors"]["features"] == "projection" and db.projection.components.shape == (COMPONENTS, 256)
    with pytest.raises(errors.ValidationError) as err:
        reindex(tmp_path / "basic.h5", tmp_path / "bad.h5", "paper")
    assert err.value.field == "sectors.features"
