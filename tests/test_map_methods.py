"""Map methods (issue 12): [render] method = auto | direct | scene | satf, the scene_maps table kind.

Scene-table fetches against the tracer at grid angles (storage precision), the mirror symmetry, empty
sectors, the scene and direct methods against each other on a small scene, the planner's auto choice
and its steps, and bad methods, knobs and missing tables rejected by name.
"""

import numpy as np
import pytest

from hairlut import errors
from hairlut.bake import registry
from hairlut.hrir import trace_sectors
from hairlut.planner import map_method, plan, scene_maps_recipe
from hairlut.scene import resolve_scene
from hairlut.scenemaps import compress, fetch_rows, hrir_recipe, load_scene_maps, scene_inputs
from hairlut.synth import prepare, render_view

from ._synth_fixtures import scene as base_scene

TINY = {"sectors": {"grid": [8, 8]}, "trace": {"pixels": 8, "steps": 12}}


def scene(method="auto", **render):
    s = base_scene()
    s["strands"] = {**s["strands"], "count": 30}
    s["render"] = {**s["render"], "method": method, **render}
    s["tables"] = {"hrir": TINY}
    return s


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """A float32 scene table with every pixel its own bin and L = 2K + 1 light angles (no truncation)."""
    sc = resolve_scene(scene("scene", views=8, terms=2, shading_pixels=8, precision="float32"))
    recipe = scene_maps_recipe(sc)
    recipe["table"]["lights"] = 5
    recipe["table"]["ratio_step"] = 1
    recipe["table"].update(alpha_grid=0, shade_rays=0, shade_steps=0)  # the bake's exact settings: the tracer's arrays
    out = tmp_path_factory.mktemp("maps") / "t.h5"
    report = registry.bake("scene_maps", recipe, out, scene=sc)
    return sc, recipe, load_scene_maps(out), report


def test_scene_table_fetch_equals_the_tracer_at_grid_angles(baked):
    sc, recipe, maps, report = baked
    full = hrir_recipe(recipe)
    dens, geom = scene_inputs(sc, recipe)
    live = np.flatnonzero(maps.row >= 0)
    assert live.size > 10 and report["total_units"] == live.size
    V, L = 8, 5
    a_ref, r_ref = trace_sectors(
        dens[live], geom[live], full, views=2 * np.pi * np.arange(V) / V, lights=2 * np.pi * np.arange(L) / L
    )
    for v in range(V):
        tv = np.full(live.size, 2 * np.pi * v / V)
        tl = np.tile(2 * np.pi * np.arange(L) / L, (live.size, 1))
        a, r = fetch_rows(maps, maps.row[live], tv, tl)
        tol = 1e-5 if v < V // 2 else 1e-5 + report["mirror_error"]  # the other half comes from the mirror
        np.testing.assert_allclose(a, a_ref[:, v], atol=tol, rtol=0)
        np.testing.assert_allclose(r, r_ref[:, v], atol=2 * tol, rtol=0)
    assert report["mirror_error"] < 5e-3  # α(θ + π, p) = α(θ, P − 1 − p) holds for the tracer's conventions
    assert a_ref.max() > 0.2 and r_ref.max() > 0.02


def _fetch_reference(alpha_t, ratio_t, row, tv, tl):
    """The fetch of ``hairlut.scenemaps._fetch``'s module docstring, element by element in float64."""
    n, half, P = alpha_t.shape
    Vr, Q, T = ratio_t.shape[1:]
    V = 2 * half
    S, L = tl.shape
    a, re = np.zeros((S, P)), np.zeros((S, L, P))
    for s in range(S):
        if row[s] < 0:
            continue
        f = (tv[s] % (2 * np.pi)) * V / (2 * np.pi)
        i0, w = int(np.floor(f)) % V, f - np.floor(f)
        views = (i0, (i0 + 1) % V)
        for p in range(P):
            a[s, p] = sum(
                wt * (alpha_t[row[s], i, p] if i < half else alpha_t[row[s], i - half, P - 1 - p])
                for wt, i in zip((1 - w, w), views)
            )
        g = (tv[s] % (2 * np.pi)) * Vr / (2 * np.pi)
        j0, u = int(np.floor(g)) % Vr, g - np.floor(g)
        c = (1 - u) * ratio_t[row[s], j0].astype(np.float64) + u * ratio_t[row[s], (j0 + 1) % Vr]
        for j in range(L):
            d = tl[s, j] - tv[s]
            basis = [1.0] + [fn(k * d) for k in range(1, (T - 1) // 2 + 1) for fn in (np.cos, np.sin)]
            rho = c @ np.asarray(basis)
            re[s, j] = a[s] * rho[np.arange(P) * Q // P]
    return a, re


@pytest.mark.parametrize("dtype,step", [("float16", 1), ("float32", 1), ("float32", 2)])
def test_fetch_kernel_equals_an_elementwise_reference(dtype, step):
    from hairlut.scenemaps import fetch_kernel

    rng = np.random.default_rng(1)
    n, V, P, Q, K, S, L = 5, 8, 16, 4, 2, 9, 2
    alpha_t = rng.random((n, V // 2, P)).astype(dtype)
    ratio_t = (0.3 * rng.normal(size=(n, V // step, Q, 2 * K + 1))).astype(dtype)
    row = np.array([0, 4, -1, 2, 2, 1, -1, 3, 0], np.int32)
    tv = np.concatenate([rng.uniform(0, 2 * np.pi, S - 3), [0.0, np.pi, 2 * np.pi - 1e-3]])  # grid, mirror, wrap
    tl = rng.uniform(0, 2 * np.pi, (S, L))
    a, r = (np.asarray(x) for x in fetch_kernel(alpha_t, ratio_t, row, tv.astype(np.float32), tl.astype(np.float32)))
    a_ref, r_ref = _fetch_reference(
        alpha_t, ratio_t, row, tv.astype(np.float32).astype(np.float64), tl.astype(np.float32).astype(np.float64)
    )
    np.testing.assert_allclose(a, a_ref, atol=2e-6, rtol=0)
    np.testing.assert_allclose(r, r_ref, atol=1e-5, rtol=0)
    assert not a[row < 0].any() and not r[row < 0].any()


def test_view_fetch_kernels_equal_the_reference_at_edge_angles():
    """index_kernel then terms_kernel (a view's fetch) at grid views, the mirror seam, 2π − ε, 0 and
    negative angles: the element-wise reference, and bitwise fetch_kernel's α and ratio terms."""
    import jax
    import jax.numpy as jnp

    from hairlut.scenemaps import fetch_terms, index_kernel, terms_kernel

    rng = np.random.default_rng(2)
    n, V, P, Q, K, L = 4, 8, 16, 4, 2, 2
    alpha_t = rng.random((n, V // 2, P)).astype("float16")
    ratio_t = (0.3 * rng.normal(size=(n, V // 2, Q, 2 * K + 1))).astype("float16")
    tv = np.array([0.0, np.pi, 2 * np.pi - 1e-7, -1e-7, np.pi - 1e-6, 3 * np.pi / 4, -np.pi, 5.0, 2 * np.pi], np.float32)
    row = np.array([0, 1, 2, 3, -1, 1, 2, 0, 3], np.int32)
    tl = rng.uniform(0, 2 * np.pi, (len(tv), L)).astype(np.float32)
    index = index_kernel(jnp.asarray(row), jnp.asarray(tv), half=V // 2, views=V // 2)
    a, rho = (np.asarray(x) for x in terms_kernel(alpha_t, ratio_t, index, tv, tl))
    a_ref, r_ref = _fetch_reference(alpha_t, ratio_t, row, tv.astype(np.float64), tl.astype(np.float64))
    np.testing.assert_allclose(a, a_ref, atol=2e-6, rtol=0)
    np.testing.assert_allclose(a[:, None, :] * np.repeat(rho, P // Q, axis=-1), r_ref, atol=1e-5, rtol=0)
    a2, rho2 = (np.asarray(x) for x in jax.jit(fetch_terms)(alpha_t, ratio_t, row, tv, tl))
    assert np.array_equal(a, a2) and np.array_equal(rho, rho2)
    assert not a[row < 0].any()  # an empty sector: α = 0, hence re = α ρ = 0


def test_scene_view_kernel_equals_fetch_then_sweep(baked):
    """The scene method's one-kernel view gives the maps of fetch_kernel's rows swept by sweep_sectors."""
    import jax.numpy as jnp

    from hairlut.scenemaps import fetch_kernel
    from hairlut.synth import MapSource, params_kernel, sweep_sectors

    _, _, maps, _ = baked
    lit = scene("direct")
    lit["lights"] = {"directions": [[0.5, 0.8, 1.0], [-0.7, 0.2, 0.4]]}
    prep = prepare(resolve_scene(lit))  # the geometry index of the same sectors
    ix = prep.index
    dev = (jnp.asarray(maps.alpha), jnp.asarray(maps.ratio), jnp.asarray(maps.row, jnp.int32))
    f32 = lambda x: np.asarray(x, np.float32)  # noqa: E731
    tv, tl, cs, _, _ = params_kernel(ix, f32(prep.scene.view), f32(prep.scene.lights), f32(0.0), n_v=1, n_l=1)
    assert tl.shape[1] == 2 and len(maps.row) == len(tv)
    a, r = fetch_kernel(*dev, tv, tl)
    re_ref, a_ref = sweep_sectors(ix, a, r, cs)
    re_map, a_map, uniform = MapSource("scene", "", maps.pixels, maps=maps, device=dev).view(
        ix, prep.scene.view, prep.scene.lights
    )
    assert not uniform.any() and float(jnp.max(a_ref)) > 0.1 and float(jnp.max(re_ref)) > 0.01
    np.testing.assert_allclose(np.asarray(a_map), np.asarray(a_ref), atol=1e-7, rtol=0)
    np.testing.assert_allclose(np.asarray(re_map), np.asarray(re_ref), atol=1e-7, rtol=0)


def test_compress_reconstructs_a_band_limited_ratio():
    rng = np.random.default_rng(0)
    n, V, L, P, K = 3, 4, 7, 4, 3
    alpha = rng.uniform(0.1, 1.0, (n, V, P))
    tl = 2 * np.pi * np.arange(L) / L
    tv = 2 * np.pi * np.arange(V) / V
    coef = rng.normal(size=(n, P, 2 * K + 1))
    d = tl[None, :] - tv[:, None]  # (V, L)
    basis = np.concatenate([np.ones((V, L, 1)), np.stack([f(k * d) for k in range(1, K + 1) for f in (np.cos, np.sin)], -1)], -1)
    ratio = np.einsum("npt,vlt->nvlp", coef, basis)
    half, got, _ = compress(alpha, alpha[:, :, None] * ratio, V, K, P)
    np.testing.assert_allclose(got, np.broadcast_to(coef[:, None], got.shape), atol=1e-10)
    np.testing.assert_array_equal(half, alpha[:, : V // 2])


def test_empty_sectors_are_zero_without_work(baked):
    _, _, maps, _ = baked
    a, r = fetch_rows(maps, np.array([-1, -1]), np.array([0.3, 2.0]), np.array([[1.0], [4.0]]))
    assert not a.any() and not r.any() and r.shape == (2, 1, maps.pixels)


def test_scene_and_direct_maps_agree_on_a_small_scene(baked, tmp_path):
    sc, _, _, _ = baked
    f16 = resolve_scene(scene("scene", views=32))
    report = registry.bake("scene_maps", scene_maps_recipe(f16), tmp_path / "s.h5", scene=f16)
    by_scene = render_view(prepare(f16, maps=report["out"]))
    by_direct = render_view(prepare(resolve_scene(scene("direct"))))
    assert by_scene.stats["map_method"] == "scene" and by_direct.stats["map_method"] == "direct"
    a_s = np.concatenate([c.alpha.ravel() for c in by_scene.clusters])
    a_d = np.concatenate([c.alpha.ravel() for c in by_direct.clusters])
    r_s = np.concatenate([c.re.ravel() for c in by_scene.clusters])
    r_d = np.concatenate([c.re.ravel() for c in by_direct.clusters])
    assert a_d.max() > 0.2 and r_d.max() > 0.02
    assert np.linalg.norm(a_s - a_d) < 0.1 * np.linalg.norm(a_d)
    assert np.linalg.norm(r_s - r_d) < 0.2 * np.linalg.norm(r_d)


def test_auto_and_the_plan(tmp_path):
    import jax

    sc = resolve_scene(scene())
    method, why = map_method(sc)
    assert why.startswith("auto:")
    if jax.default_backend() == "cpu":
        assert method == "scene"
        assert map_method(resolve_scene(scene(animated=True)))[0] == "satf"
    p = plan(sc, tmp_path)
    steps = {s.name: s for s in p.steps}
    assert steps["map_method"].details["method"] == method
    if method == "scene":
        assert steps["scene_maps"].action == "bake" and steps["scene_maps"].kind == "scene_maps"
        assert steps["hrir_db"].action == "skip" and steps["uniformity"].action == "skip"
    sat = {s.name: s for s in plan(resolve_scene(scene("satf")), tmp_path).steps}
    assert sat["scene_maps"].action == "skip" and sat["hrir_db"].action == "bake"
    assert map_method(resolve_scene(scene("direct")))[0] == "direct"


def test_geometry_keys_the_table():
    a = scene_maps_recipe(resolve_scene(scene("scene")))
    lit = scene("scene")
    lit["lights"] = {"directions": [[1.0, 0.0, 0.0]]}
    assert scene_maps_recipe(resolve_scene(lit)) == a  # lights do not move a strand
    moved = scene("scene")
    moved["strands"] = {**moved["strands"], "seed": 4}
    assert scene_maps_recipe(resolve_scene(moved))["geometry"] != a["geometry"]


def test_geometry_key_follows_the_code_that_cuts_the_sectors(monkeypatch):
    """A hairlut whose fit or sector cutting changed (hairlut.scene.code_digest) does not reuse an old table."""
    import hairlut.scene

    a = scene_maps_recipe(resolve_scene(scene("scene")))
    monkeypatch.setattr(hairlut.scene, "code_digest", lambda **kw: "another build")
    assert scene_maps_recipe(resolve_scene(scene("scene")))["geometry"] != a["geometry"]


@pytest.mark.parametrize(
    "render,field",
    [
        ({"method": "fast"}, "render.method"),
        ({"method": "direct", "views": 64}, "render.views"),
        ({"method": "scene", "views": 63}, "render.views"),
        ({"method": "scene", "precision": "int8"}, "render.precision"),
        ({"method": "scene", "ratio_step": 0}, "render.ratio_step"),
        ({"method": "direct", "ratio_step": 2}, "render.ratio_step"),
        ({"rays": 0}, "render.rays"),
    ],
)
def test_bad_method_or_knob_is_rejected_by_name(render, field):
    s = scene()
    s["render"] = {**s["render"], **render}
    with pytest.raises(errors.ValidationError) as exc:
        resolve_scene(s)
    assert exc.value.field == field


def test_shading_pixels_must_divide_the_pixels():
    with pytest.raises(errors.ValidationError) as exc:
        scene_maps_recipe(resolve_scene(scene("scene", shading_pixels=3)))
    assert exc.value.field == "render.shading_pixels"


def test_ratio_step_comes_from_the_scene_file():
    assert scene_maps_recipe(resolve_scene(scene("scene")))["table"]["ratio_step"] == 2  # the default
    assert scene_maps_recipe(resolve_scene(scene("scene", views=16, ratio_step=4)))["table"]["ratio_step"] == 4
    with pytest.raises(errors.ValidationError) as exc:
        scene_maps_recipe(resolve_scene(scene("scene", views=16, ratio_step=3)))
    assert exc.value.field == "render.ratio_step" and exc.value.value == 3


def test_scene_without_its_table_names_the_command():
    with pytest.raises(errors.AssetNotFoundError, match="hairlut bake --scene"):
        prepare(resolve_scene(scene("scene")))
