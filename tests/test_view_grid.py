"""The scene table's tracer (hairlut.synth.trace_view_grid): the HRIR tracer's arrays with mirror views sharing samples.

Independent reference: ``hairlut.hrir.trace_sectors`` (one sector at a time, every view its own
march and light lookups) on the same sectors, views and lights, with and without self-shadowing and
with several rays per pixel; empty sectors are zero; bad grids are rejected by name.
"""

import numpy as np
import pytest

from hairlut import errors
from hairlut.hrir import resolve_recipe, trace_sectors
from hairlut.scene import resolve_scene, scene_maps_recipe
from hairlut.scenemaps import hrir_recipe, scene_inputs
from hairlut.synth import bake_view_grid, trace_view_grid

from ._synth_fixtures import scene as base_scene


@pytest.fixture(scope="module")
def sectors():
    s = base_scene()
    s["strands"] = {**s["strands"], "count": 30}
    s["render"] = {**s["render"], "method": "scene"}
    s["tables"] = {"hrir": {"sectors": {"grid": [8, 8]}, "trace": {"pixels": 8, "steps": 12}}}
    sc = resolve_scene(s)
    recipe = scene_maps_recipe(sc)
    dens, geom = scene_inputs(sc, recipe)
    live = np.flatnonzero(dens.reshape(len(dens), -1).max(axis=1) > 0)[:5]
    empty = np.zeros((2, *dens.shape[1:]), dens.dtype)  # two sectors with no strands
    return np.concatenate([dens[live], empty]), np.concatenate([geom[live], geom[live[:2]]]), hrir_recipe(recipe)


@pytest.mark.parametrize("shadow, rays", [(True, 1), (True, 2), (False, 1)])
def test_equals_the_tracer(sectors, shadow, rays):
    dens, geom, full = sectors
    full = resolve_recipe({**full, "trace": {**full["trace"], "self_shadow": shadow, "rays_per_pixel": rays}})
    V, L = 6, 3
    a, r = trace_view_grid(dens, geom, full, views=V, lights=L)
    a_ref, r_ref = trace_sectors(dens, geom, full, views=2 * np.pi * np.arange(V) / V, lights=2 * np.pi * np.arange(L) / L)
    assert a.shape == a_ref.shape and r.shape == r_ref.shape
    np.testing.assert_allclose(a, a_ref, atol=2e-6, rtol=0)
    np.testing.assert_allclose(r, r_ref, atol=2e-6, rtol=0)
    assert a_ref.max() > 0.1 and r_ref.max() > 0.01
    empty = dens.reshape(len(dens), -1).max(axis=1) == 0
    assert empty.sum() == 2 and not a[empty].any() and not r[empty].any()


def test_bad_grids_are_rejected(sectors):
    dens, geom, full = sectors
    with pytest.raises(errors.ValidationError, match="views"):
        trace_view_grid(dens, geom, full, views=5, lights=3)
    with pytest.raises(errors.ValidationError, match="lights"):
        trace_view_grid(dens, geom, full, views=6, lights=0)
    with pytest.raises(errors.ValidationError, match="density"):
        trace_view_grid(-dens, geom, full, views=6, lights=3)


def _binned(a, re, step, bins):
    """The reference's per-bin α and re on every ``step``-th view."""
    n, V, P = a.shape
    return (a[:, ::step].reshape(n, -1, bins, P // bins).sum(-1),
            re[:, ::step].reshape(n, -1, re.shape[2], bins, P // bins).sum(-1))


@pytest.mark.parametrize("V, step", [(8, 2), (8, 4), (6, 2)])  # kept views mirrored (8/2, 8/4) or not (6/2: 3 is odd)
def test_bake_grid_shading_equals_the_tracer(sectors, V, step):
    """At the trace's own rays and steps, the fast path's per-bin α and re are the reference's, binned."""
    dens, geom, full = sectors
    full = resolve_recipe({**full, "trace": {**full["trace"], "rays_per_pixel": 2}})
    L, Q = 3, 4
    a, re = trace_view_grid(dens, geom, full, views=V, lights=L)
    ab_ref, rb_ref = _binned(a, re, step, Q)
    half, ab, rb = bake_view_grid(dens, geom, full, views=V, lights=L, ratio_step=step, bins=Q, alpha_grid=0)
    assert half.shape == (len(dens), V // 2, 8) and ab.shape == ab_ref.shape and rb.shape == rb_ref.shape
    np.testing.assert_allclose(half, a[:, :V // 2], atol=2e-6, rtol=0)  # alpha_grid 0: the tracer's march
    np.testing.assert_allclose(ab, ab_ref, atol=1e-5, rtol=0)
    np.testing.assert_allclose(rb, rb_ref, atol=1e-5, rtol=0)
    assert rb_ref.max() > 0.05
    empty = dens.reshape(len(dens), -1).max(axis=1) == 0
    assert not half[empty].any() and not ab[empty].any() and not rb[empty].any()


def test_bake_grid_alpha_converges_to_the_tracer(sectors):
    """α through the m × m Cartesian resampling: within 0.07 of the tracer's march at m = 64 (rel-L2 < 5 %; on
    this tiny 8 × 8-cell, 8-pixel scene), and the error falls as m grows (the resampling is the only difference)."""
    dens, geom, full = sectors
    V = 8
    a, _ = trace_view_grid(dens, geom, full, views=V, lights=1)
    err = {}
    for m in (16, 64):
        half, _, _ = bake_view_grid(dens, geom, full, views=V, lights=1, bins=1, alpha_grid=m)
        err[m] = (np.abs(half - a[:, :V // 2]).max(), np.linalg.norm(half - a[:, :V // 2]) / np.linalg.norm(a))
    assert err[64][0] < 0.07 and err[64][1] < 0.05, err
    assert err[64][1] < 0.5 * err[16][1], err
    assert a.max() > 0.1


def test_bake_grid_coarse_shading_is_the_coarse_tracer(sectors):
    """shade_rays / shade_steps: re/α from the tracer run with those rays and steps (α keeps the recipe's)."""
    dens, geom, full = sectors
    full = resolve_recipe({**full, "trace": {**full["trace"], "rays_per_pixel": 2}})
    coarse = resolve_recipe({**full, "trace": {**full["trace"], "rays_per_pixel": 1, "steps": 6}})
    V, L, Q = 8, 3, 2
    a, re = trace_view_grid(dens, geom, coarse, views=V, lights=L)
    ab_ref, rb_ref = _binned(a, re, 2, Q)
    _, ab, rb = bake_view_grid(dens, geom, full, views=V, lights=L, ratio_step=2, bins=Q, alpha_grid=16, shade_rays=1,
                               shade_steps=6)
    np.testing.assert_allclose(ab, ab_ref, atol=1e-5, rtol=0)
    np.testing.assert_allclose(rb, rb_ref, atol=1e-5, rtol=0)


def test_lane_upsample_is_linear_interpolation():
    """grid_transmittance's coarse lanes: a linear ramp of cell centres comes back as the ramp at the fine samples
    (away from the edges, where the edge value is held)."""
    import jax.numpy as jnp
    from hairlut.hrir._march import lane_upsample

    for f in (2, 3, 4):
        n = 6
        centres = jnp.arange(n, dtype=jnp.float32)[None, :, None] * 2.0 + 1.0  # (1, n, 1): value 2c + 1
        fine = np.asarray(lane_upsample(centres, f, axis=1))[0, :, 0]
        pos = (np.arange(n * f) + 0.5) / f - 0.5  # fine samples in cell-centre units
        want = 2 * np.clip(pos, 0, n - 1) + 1
        np.testing.assert_allclose(fine, want, atol=1e-6, rtol=0)


def test_bake_grid_coarse_shadow_lookup(sectors):
    """shadow_coarse=2: the light transmittance looked up on pixel centres and interpolated across the two rays;
    α is untouched, re within 2 % (rel-L2) of the tracer's, and with self-shadowing off the same as exact."""
    dens, geom, full = sectors
    full = resolve_recipe({**full, "trace": {**full["trace"], "rays_per_pixel": 2}})
    V, L, Q = 8, 3, 4
    a, re = trace_view_grid(dens, geom, full, views=V, lights=L)
    ab_ref, rb_ref = _binned(a, re, 2, Q)
    half, ab, rb = bake_view_grid(dens, geom, full, views=V, lights=L, ratio_step=2, bins=Q, alpha_grid=0, shadow_coarse=2)
    np.testing.assert_allclose(half, a[:, :V // 2], atol=2e-6, rtol=0)
    np.testing.assert_allclose(ab, ab_ref, atol=1e-5, rtol=0)
    err = np.linalg.norm(rb - rb_ref) / np.linalg.norm(rb_ref)
    assert 0 < err < 0.02, err
    off = resolve_recipe({**full, "trace": {**full["trace"], "self_shadow": False}})
    _, _, r1 = bake_view_grid(dens, geom, off, views=V, lights=L, ratio_step=2, bins=Q, alpha_grid=0)
    _, _, r2 = bake_view_grid(dens, geom, off, views=V, lights=L, ratio_step=2, bins=Q, alpha_grid=0, shadow_coarse=2)
    np.testing.assert_array_equal(r1, r2)


def test_bake_grid_rejects_bad_layouts(sectors):
    dens, geom, full = sectors
    for kw, field in ((dict(ratio_step=3), "ratio_step"), (dict(bins=3), "bins"), (dict(alpha_grid=1), "alpha_grid"), (dict(alpha_grid=-1), "alpha_grid"),
                      (dict(views=7), "views"), (dict(shade_steps=1), "shade_steps"), (dict(shadow_coarse=3), "shadow_coarse"),
                      (dict(shadow_coarse=0), "shadow_coarse"), (dict(shadow_grid=1), "shadow_grid")):
        args = {"views": 8, "lights": 3, "bins": 4, "alpha_grid": 16, **kw}
        with pytest.raises(errors.ValidationError) as exc:
            bake_view_grid(dens, geom, full, **args)
        assert exc.value.field == field
