"""The per-view path (the index built by ``prepare``, then ``view_maps``) against the reference
``build_maps`` of eqs 6–7, for every uniformity threshold and for texel grids that do and do not
divide into the HSV grid."""

import math

import numpy as np
import pytest

from hairlut.synth import prepare, render_view
from hairlut.synth._maps import build_maps, sector_angles, texels
from hairlut.synth._view import view_maps

from ._synth_fixtures import scene, synthetic_db


@pytest.fixture(scope="module")
def db():
    return synthetic_db()


def _reference(prep, db, view, lights, thr):
    sp = sector_angles(prep.frames, view, lights)
    n_u, n_t = prep.scene.config["render"]["resolution"]
    tx = texels(prep.table, sp, prep.clusters[0].spec.n_layers, (n_u, n_t), db.alpha.shape[-1])
    return build_maps(db, prep.table, sp, tx, thr, prep.scene.config["render"]["neighbours"])


@pytest.mark.parametrize("resolution", [(16, 8), (10, 6)])  # 4 texels per HSV column, and 2.5
@pytest.mark.parametrize("thr", [0.0, 1.0, math.inf])
def test_view_maps_equal_reference(db, thr, resolution):
    given = scene(k_threshold=thr)
    given["render"]["resolution"] = list(resolution)
    prep = prepare(given, db)
    sc = prep.scene
    for view, lights in ((sc.view, sc.lights), (np.array([0.6, -0.2, 0.77]), np.array([[0.0, 1.0, 0.0]]))):
        ref = _reference(prep, db, view, lights, thr)
        re, alpha, uniform = view_maps(prep.index, db, view, lights, thr)
        np.testing.assert_array_equal(uniform, ref.uniform)
        assert np.asarray(re).shape == ref.re.shape and np.asarray(alpha).shape == ref.alpha.shape
        np.testing.assert_allclose(np.asarray(re), ref.re, atol=2e-6)
        np.testing.assert_allclose(np.asarray(alpha), ref.alpha, atol=2e-6)
    if thr == 1.0:
        assert 0 < ref.uniform.mean() < 1  # both kinds of HSV exercised


def test_render_repeats_exactly(db):
    prep = prepare(scene(), db)
    first = render_view(prep)
    other = render_view(prep, view=[0.3, 0.1, 1.0])  # reuses the fetch buffers with other shapes
    again = render_view(prep)
    for a, b in zip(first.clusters, again.clusters):
        np.testing.assert_array_equal(a.final, b.final)
    assert not np.allclose(other.clusters[0].final, first.clusters[0].final)
    assert set(first.stats["seconds"]) >= {"maps", "shade"}
