"""re-/α-maps (eqs 6–7) against a direct computation; bounds; frames; cluster-order invariance."""

import math

import numpy as np
import pytest

from hairlut.geometry import ClusterGeometry, build_sectors, generate_strands
from hairlut.hrir._query import satf_query
from hairlut.scene import resolve_scene
from hairlut.synth import synthesize
from hairlut.synth._maps import build_maps, param_distance, sector_params, texels, wrap

from ._synth_fixtures import CLUSTER_A, scene, synthetic_db


@pytest.fixture(scope="module")
def db():
    return synthetic_db()


@pytest.fixture(scope="module")
def setup(db):
    sc = resolve_scene({**scene(), "clusters": [dict(CLUSTER_A)]})
    spec = sc.specs[0]
    geom = ClusterGeometry(spec)
    strands, _ = generate_strands(geom, 60, radius=0.006, profile="clumped", spread=0.2, seed=1)
    table = build_sectors(geom, strands, np.zeros(strands.n_strands, np.int64))
    sp = sector_params(geom, table, sc.view, sc.lights, db)
    tx = texels(table, sp, spec.n_layers, (16, 8), db.alpha.shape[-1])
    return table, sp, tx


def _interp(arr, pix):
    """Linear sampling of 1-D arrays (..., P) at float pixel indices (...), clamped."""
    P = arr.shape[-1]
    return np.array([np.interp(p, np.arange(P), a) for a, p in zip(arr.reshape(-1, P), pix.ravel())]).reshape(pix.shape)


def _query(db, f, tv, tl):
    re, a, _, _ = satf_query(db, f[:, None, :], tv[:, None], tl)
    return re, a[:, 0]


def test_threshold_inf_always_uniform(db, setup):
    table, sp, tx = setup
    maps = build_maps(db, table, sp, tx, math.inf)
    assert maps.uniform.all()
    h = tx.hsv.ravel()
    top, bot = table.hsv_sectors[h, 0], table.hsv_sectors[h, 1]
    f = 0.5 * (sp.features[top] + sp.features[bot])
    tv = sp.theta_v[top] + 0.5 * wrap(sp.theta_v[bot] - sp.theta_v[top])
    tl = sp.theta_l[top] + 0.5 * wrap(sp.theta_l[bot] - sp.theta_l[top])
    re, a = _query(db, f, tv, tl)
    pix = tx.pix_ave.ravel()
    np.testing.assert_allclose(maps.alpha.ravel(), _interp(a, pix), atol=1e-5)
    for j in range(re.shape[1]):
        np.testing.assert_allclose(np.moveaxis(maps.re, 2, -1)[..., j].ravel(), _interp(re[:, j], pix), atol=1e-5)
    assert maps.fetches == table.n_hsvs


def test_threshold_zero_always_interpolates(db, setup):
    table, sp, tx = setup
    maps = build_maps(db, table, sp, tx, 0.0)
    assert not maps.uniform.any()
    h = tx.hsv.ravel()
    g = tx.gamma.ravel()
    top, bot = table.hsv_sectors[h, 0], table.hsv_sectors[h, 1]
    re1, a1 = _query(db, sp.features[top], sp.theta_v[top], sp.theta_l[top])
    re2, a2 = _query(db, sp.features[bot], sp.theta_v[bot], sp.theta_l[bot])
    p1, p2 = tx.pix_top.ravel(), tx.pix_bot.ravel()
    want_a = (1 - g) * _interp(a1, p1) + g * _interp(a2, p2)
    np.testing.assert_allclose(maps.alpha.ravel(), want_a, atol=1e-5)
    want_re = (1 - g) * _interp(re1[:, 0], p1) + g * _interp(re2[:, 0], p2)
    np.testing.assert_allclose(maps.re[:, :, 0].ravel(), want_re, atol=1e-5)
    assert maps.fetches == len(np.unique(table.hsv_sectors))


def test_maps_bounded(db, setup):
    table, sp, tx = setup
    for thr in (0.0, 1.0, math.inf):
        m = build_maps(db, table, sp, tx, thr)
        assert m.alpha.min() >= 0 and m.alpha.max() <= 1
        assert m.re.min() >= 0 and m.re.max() <= 1


def test_eq6_distance_wraps_angles(db):
    f = db.features[:2]
    d = param_distance(
        db,
        f,
        np.array([0.01, 1.0]),
        np.array([[0.0], [0.0]]),
        f,
        np.array([2 * np.pi - 0.01, 1.0]),
        np.array([[0.0], [2 * np.pi]]),
    )
    np.testing.assert_allclose(d, [0.02 / (2 * np.pi / 8), 0.0], atol=1e-9)


def test_view_along_outward_normal_is_theta_zero(db, setup):
    table, sp, _ = setup
    geom = ClusterGeometry(resolve_scene({**scene(), "clusters": [dict(CLUSTER_A)]}).specs[0])
    n = 37
    sec = geom.sections(np.linspace(0, 1, table.shape[1]))
    ex3 = sp.ex[n, 0] * sec.normal[0, table.t_index[n]] + sp.ex[n, 1] * sec.binormal[0, table.t_index[n]]
    again = sector_params(geom, table, ex3, -ex3[None], db)
    assert abs(wrap(again.theta_v[n])) < 1e-9
    assert abs(wrap(again.theta_l[n, 0] - np.pi)) < 1e-9


def test_cluster_order_invariant_and_bounded(db):
    fwd = synthesize(scene(), db)
    given = scene()
    given["clusters"] = given["clusters"][::-1]
    rev = synthesize(given, db)
    for a, b in zip(fwd.clusters, rev.clusters[::-1]):
        for name in ("re", "alpha", "shadow", "rgba", "final"):
            np.testing.assert_allclose(getattr(a, name), getattr(b, name), atol=1e-6, err_msg=name)
    for c in fwd.clusters:  # kd + ks_I + ks_II = 1, white lights ≤ 1 each, background black
        assert c.alpha.min() >= 0 and c.alpha.max() <= 1
        assert c.rgba[..., :3].max() <= 2 + 1e-5  # two unit lights
        assert c.final[..., 3].max() <= 1


def test_single_light_final_le_1(db):
    given = scene()
    given["lights"] = {"directions": [[0.2, 0.9, 0.5]]}
    res = synthesize(given, db)
    for c in res.clusters:
        assert c.lighting.max() <= 1 + 1e-5 and c.final[..., :3].max() <= 1 + 1e-5


def test_too_many_neighbours_names_the_key(db):
    from hairlut import errors

    given = scene()
    given["render"]["neighbours"] = len(db.features) + 1
    with pytest.raises(errors.ValidationError) as exc:
        synthesize(given, db)
    assert exc.value.field == "render.neighbours"


def test_render_reuses_prepared_scene_for_new_lights(db):
    from hairlut.synth import prepare, render_view

    # eq 6 off (k_threshold 0): a uniform HSV's α is read at Params_ave, whose angles include the lights', so with it
    # α would follow the lights wherever an HSV's uniformity flips (the t = 0 HSVs, since their sectors hold the roots)
    prep = prepare(scene(k_threshold=0.0), db)
    base = render_view(prep)
    direct = synthesize(scene(k_threshold=0.0), db)
    np.testing.assert_allclose(base.clusters[0].final, direct.clusters[0].final, atol=1e-6)
    moved = render_view(prep, lights=[[0.0, -1.0, 0.2]])
    assert moved.clusters[0].re.shape[1] == 1
    assert not np.allclose(moved.clusters[0].lighting, base.clusters[0].lighting)
    np.testing.assert_allclose(moved.clusters[0].alpha, base.clusters[0].alpha, atol=1e-6)  # α: view only
