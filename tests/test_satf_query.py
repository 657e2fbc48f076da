"""SATF lookup: exact records at their own parameters, periodic bilinear angles, inverse-distance blending."""

from types import SimpleNamespace

import numpy as np
import pytest

from hairlut import errors
from hairlut.geometry import FeatureStats
from hairlut.hrir import satf_query

M, V, L, P, F = 12, 8, 6, 5, 3


@pytest.fixture(scope="module")
def db():
    rng = np.random.default_rng(3)
    feats = rng.normal(size=(M, F))
    return SimpleNamespace(
        features=feats,
        stats=FeatureStats.fit(feats, ("rho_st", "rho_s", "rho_t")),
        alpha=rng.random((M, V, P)),
        reflectance=rng.random((M, V, L, P)),
    )


def test_exact_record_at_grid_angles(db):
    i, v, l = 7, 3, 4
    re, a, idx, w = satf_query(db, db.features[i], 2 * np.pi * v / V, 2 * np.pi * l / L)
    assert idx[0] == i and w[0] > 0.999
    np.testing.assert_allclose(re, db.reflectance[i, v, l], atol=1e-4)
    np.testing.assert_allclose(a, db.alpha[i, v], atol=1e-4)


def test_bilinear_and_periodic(db):
    i = 2
    tv = 2 * np.pi * (V - 0.25) / V  # between the last view and view 0: wraps around
    tl = 2 * np.pi * 1.5 / L
    re, a, _, _ = satf_query(db, db.features[i], tv, tl, k=1)
    r = db.reflectance[i]
    # f = V − 0.25: a quarter of the way from the last view, three quarters of the way to view 0
    expect = 0.25 * (0.5 * r[V - 1, 1] + 0.5 * r[V - 1, 2]) + 0.75 * (0.5 * r[0, 1] + 0.5 * r[0, 2])
    np.testing.assert_allclose(re, expect, atol=1e-5)
    np.testing.assert_allclose(a, 0.25 * db.alpha[i, V - 1] + 0.75 * db.alpha[i, 0], atol=1e-5)
    shifted = satf_query(db, db.features[i], tv + 4 * np.pi, tl - 2 * np.pi, k=1)[0]
    np.testing.assert_allclose(shifted, re, atol=1e-5)


def test_inverse_distance_weights_and_batching(db):
    rng = np.random.default_rng(9)
    q = db.features.mean(0) + 0.3 * rng.normal(size=(40, F))
    tv, tl = rng.uniform(0, 2 * np.pi, 40), rng.uniform(0, 2 * np.pi, 40)
    re, a, idx, w = satf_query(db, q, tv, tl, k=3)
    assert re.shape == (40, P) and a.shape == (40, P) and idx.shape == (40, 3)
    np.testing.assert_allclose(w.sum(-1), 1, atol=1e-6)
    z = db.stats.normalize(q)
    zdb = db.stats.normalize(db.features)
    d = np.linalg.norm(z[:, None] - zdb[None], axis=-1)
    np.testing.assert_array_equal(np.sort(idx, -1), np.sort(np.argsort(d, axis=1)[:, :3], -1))
    dk = np.take_along_axis(d, idx, 1)
    expect_w = (1 / (dk + 1e-6)) / (1 / (dk + 1e-6)).sum(-1, keepdims=True)
    np.testing.assert_allclose(w, expect_w, rtol=1e-4)
    assert np.all((a >= 0) & (a <= 1))
    one = satf_query(db, q[5], tv[5], tl[5], k=3)[0]
    np.testing.assert_allclose(one, re[5], atol=1e-6)


def test_bad_queries(db):
    with pytest.raises(errors.ValidationError, match="features"):
        satf_query(db, np.ones(2), 0.0, 0.0)
    with pytest.raises(errors.ValidationError, match="features"):
        satf_query(db, [np.nan, 0, 0], 0.0, 0.0)
    with pytest.raises(errors.ValidationError, match="k="):
        satf_query(db, np.zeros(F), 0.0, 0.0, k=M + 1)
    with pytest.raises(errors.ValidationError, match="theta_v"):
        satf_query(db, np.zeros(F), np.inf, 0.0)


def test_queries_beyond_the_float32_distances_are_refused_and_huge_angles_wrap(db):
    """Issue 29 m14: finite features of 1e300 gave NaN (the float32 distances overflow, 0/0 weights) with no error;
    angles of 1e300 (inf in float32) too.  Features are refused, naming them, beyond feature_limit (Samuelson's
    bound on the records' own |z| taken off the float32 range); angles wrap in float64 as exactly as it holds them."""
    from hairlut.hrir._query import feature_limit

    for bad in ([1e300, 0.0, 0.0], [0.0, -1e300, 0.0], [0.0, 0.0, 1.7e308]):
        with pytest.raises(errors.ValidationError, match=r"features=.*standard deviations.*float32") as info:
            satf_query(db, bad, 0.0, 0.0)
        assert info.value.field == "features"
    limit = feature_limit(M, F)
    assert limit == pytest.approx(np.sqrt(np.finfo(np.float32).max / (2 * F)) - np.sqrt(M - 1))
    assert np.abs(db.stats.normalize(db.features)).max() <= np.sqrt(M - 1)  # Samuelson: the records lie within
    edge = db.stats.denormalize(np.full(F, 0.999 * limit))  # just inside: the farthest answerable query
    re, a, idx, w = satf_query(db, edge, 0.0, 0.0, k=3)
    # every record is as far as float32 can tell (|z| ~ 1e19 ≫ |z_i|): inverse-distance weights of 1/3 each, as the
    # exact ones are to 1e-18
    assert np.isfinite(re).all() and np.isfinite(a).all() and np.allclose(w, 1 / 3, rtol=1e-6)
    np.testing.assert_allclose(a, db.alpha[idx, 0].mean(axis=0), rtol=1e-5)
    for turns in (1e300, -1e300, 1e30):
        got = satf_query(db, db.features[4], turns, turns, k=1)
        want = satf_query(db, db.features[4], np.mod(turns, 2 * np.pi), np.mod(turns, 2 * np.pi), k=1)
        assert np.isfinite(got[0]).all()
        for g, x in zip(got, want):
            np.testing.assert_array_equal(g, x)
