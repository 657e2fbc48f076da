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
from hairlut.synth import trace_view_grid

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
