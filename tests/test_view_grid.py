"""The scene table's tracer (hairlut.march.trace_view_grid): the HRIR tracer's arrays with mirror views sharing samples.

Independent reference: ``hairlut.hrir.trace_sectors`` (one sector at a time, every view its own
march and light lookups) on the same sectors, views and lights, with and without self-shadowing and
with several rays per pixel; empty sectors are zero; bad grids are rejected by name.
"""

import numpy as np
import pytest

from hairlut import errors
from hairlut.hrir import resolve_recipe, trace_sectors
from hairlut.march import bake_view_grid, trace_view_grid
from hairlut.planner import scene_maps_recipe
from hairlut.scene import resolve_scene
from hairlut.scenemaps import hrir_recipe, scene_inputs

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
    return (
        a[:, ::step].reshape(n, -1, bins, P // bins).sum(-1),
        re[:, ::step].reshape(n, -1, re.shape[2], bins, P // bins).sum(-1),
    )


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
    np.testing.assert_allclose(half, a[:, : V // 2], atol=2e-6, rtol=0)  # alpha_grid 0: the tracer's march
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
        err[m] = (np.abs(half - a[:, : V // 2]).max(), np.linalg.norm(half - a[:, : V // 2]) / np.linalg.norm(a))
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
    _, ab, rb = bake_view_grid(
        dens, geom, full, views=V, lights=L, ratio_step=2, bins=Q, alpha_grid=16, shade_rays=1, shade_steps=6
    )
    np.testing.assert_allclose(ab, ab_ref, atol=1e-5, rtol=0)
    np.testing.assert_allclose(rb, rb_ref, atol=1e-5, rtol=0)


def test_shading_of_the_live_samples_is_the_dense_contraction(sectors):
    """_shade_weighted (the bake's compacted shading) against the dense form built from hairlut.hrir's own pieces
    (Phong at every sample, the light lookup at every sample, the weights' contraction over all steps), for a chunk
    that divides nothing (many loop steps, a partial last one) and one larger than the live samples (one step)."""
    import jax
    import jax.numpy as jnp

    from hairlut.march import direct_lighting, front_to_back, grid_transmittance, light_depth_grid, march, sector_fields
    from hairlut.march._viewgrid import _shade_weighted

    dens, geom, full = sectors
    rho, g = jnp.asarray(dens[0], jnp.float32), jnp.asarray(geom[0], jnp.float32)
    views, lights = jnp.asarray([0.3, 1.9], jnp.float32), jnp.asarray([0.0, 2.0, 4.0], jnp.float32)
    phong = jnp.asarray([0.1, 0.6, 0.3, 20.0], jnp.float32)
    lanes, K = 16, 12
    fields = sector_fields(rho)
    tau, gx, gy, rs, rr, inside = march(fields, g, views, lanes, K)
    w, _ = front_to_back(tau, 1e-4)
    w_m = jnp.flip(front_to_back(jnp.flip(tau, axis=(1, 2)), 1e-4)[0], axis=(1, 2))  # the mirror's, in march order
    depth = light_depth_grid(fields, g, lights, K, K)
    t_l = jnp.moveaxis(grid_transmittance(depth, g, views, lanes, K), -1, 1)  # (V, L, lanes, K)
    want = []
    for vs, ww in ((views, w), (views + jnp.pi, w_m)):
        direct = direct_lighting(rho, gx, gy, rs, rr, inside, vs, lights, phong) * t_l
        want.append(np.asarray(jnp.einsum("vlnk,vnk->vln", direct, ww, precision=jax.lax.Precision.HIGHEST)))
    live = int(((w > 0) | (w_m > 0)).sum())
    assert 0 < live < w.size  # some samples are skipped
    for chunk in (7, live + 100):
        got = jax.jit(lambda *a: _shade_weighted(fields, jnp.max(rho), g, views, lights, phong, *a, power=20, chunk=chunk))(
            w, w_m, depth
        )
        for x, y in zip(got, want):
            np.testing.assert_allclose(np.asarray(x), y, atol=2e-6, rtol=0)


def test_bake_grid_rejects_bad_layouts(sectors):
    dens, geom, full = sectors
    for kw, field in (
        (dict(ratio_step=3), "ratio_step"),
        (dict(bins=3), "bins"),
        (dict(alpha_grid=1), "alpha_grid"),
        (dict(alpha_grid=-1), "alpha_grid"),
        (dict(views=7), "views"),
        (dict(shade_steps=1), "shade_steps"),
        (dict(shadow_grid=1), "shadow_grid"),
    ):
        args = {"views": 8, "lights": 3, "bins": 4, "alpha_grid": 16, **kw}
        with pytest.raises(errors.ValidationError) as exc:
            bake_view_grid(dens, geom, full, **args)
        assert exc.value.field == field
