"""The shadow seam: a scene selects eq 12's s-map, the light-oriented map, opacity maps or none; each
gives T = 1 in front of the hair and darkens behind it; "none" does no shadow work; bad keys are
rejected by name; "smap" is the default and renders exactly as an unmarked scene."""

import numpy as np
import pytest

import hairlut.shadows
import hairlut.synth._shading
from hairlut import errors
from hairlut.geometry import Strands
from hairlut.planner import plan
from hairlut.scene import SHADOW_METHODS, resolve_scene
from hairlut.shadows import LIGHT_METHODS, light_transmittance
from hairlut.synth import prepare, render_view, shade_lights

from ._synth_fixtures import scene, synthetic_db

LIGHT = np.array([0.0, 0.0, 1.0])
#: The methods a scene can run (``auto`` chooses one of them: test_auto_chooses_…).
METHODS = [m for m in SHADOW_METHODS if m != "auto"]


def with_shadows(**shadows):
    s = scene()
    s["shadows"] = shadows
    return s


@pytest.fixture(scope="module")
def db():
    return synthetic_db()


@pytest.fixture(scope="module")
def views(db):
    """One prepared scene and its view (render_view) per shadow method."""
    out = {}
    for method in METHODS:
        prep = prepare(with_shadows(method=method), db)
        out[method] = (prep, render_view(prep))
    return out


def slab(n=400, seed=0):
    """Straight strands along x filling the slab |y| < 0.5, −0.1 < z < 0.1: hair between z = +1 and z = −1."""
    rng = np.random.default_rng(seed)
    y, z = rng.uniform(-0.5, 0.5, n), rng.uniform(-0.1, 0.1, n)
    x = np.linspace(-0.5, 0.5, 8)
    pts = np.stack(
        [np.broadcast_to(x, (n, 8)), np.broadcast_to(y[:, None], (n, 8)), np.broadcast_to(z[:, None], (n, 8))], -1
    ).reshape(-1, 3)
    return Strands(pts, np.full(n, 8), thickness=np.full(len(pts), 0.004))


# ----------------------------------------------------------------------------- selection and validation


@pytest.mark.parametrize("method", METHODS)
def test_scene_selects_each_method(views, method):
    prep, res = views[method]
    assert prep.scene.shadow_method == method and prep.scene.effects["shadow"] is (method != "none")
    n_lights = len(prep.scene.lights)
    for c in res.clusters:
        K, n_t, n_u = c.alpha.shape
        assert c.shadow.shape == (K, n_lights if method in LIGHT_METHODS else 1, n_t, n_u)
        assert np.all((c.shadow >= 0) & (c.shadow <= 1)) and np.all(np.isfinite(c.final))
    assert ("shadows" in prep.seconds) is (method in LIGHT_METHODS)


def test_auto_chooses_light_oriented_smap_for_its_knobs_and_none_without_strands(views, db):
    """shadows.method = auto (the default): the light-oriented map for strands that shade each other, eq 12's s-map
    when the scene sets its knobs, none when no strand casts a shadow; an explicit method always wins."""
    plain = scene()
    del plain["shadows"]
    sc = resolve_scene(plain)
    assert sc.config["shadows"]["method"] == "auto" and sc.shadow_method == "light_oriented"
    assert not sc.shadow_choice.given and "bertails" in sc.shadow_choice.reason
    assert resolve_scene({**plain, "material": {**plain["material"], "k_shadow": 0.7}}).shadow_method == "smap"
    empty = dict(plain, strands={**plain["strands"], "count": 0})
    assert resolve_scene(empty).shadow_method == "none"
    assert resolve_scene(dict(plain, shadows={"method": "opacity_maps"})).shadow_choice.given
    unmarked = render_view(prepare(dict(plain, material={**plain["material"], "k_shadow": 0.5}), db))
    _, explicit = views["smap"]
    for a, b in zip(unmarked.clusters, explicit.clusters):
        for name in ("re", "alpha", "shadow", "lighting", "rgba", "final"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


@pytest.mark.parametrize(
    "shadows, key",
    [
        ({"method": "raytrace"}, "shadows.method"),
        ({"method": 3}, "shadows.method"),
        ({"method": "light_oriented", "kappa": -0.1}, "shadows.kappa"),
        ({"method": "light_oriented", "kappa": "thick"}, "shadows.kappa"),
        ({"method": "opacity_maps", "kappa": 0}, "shadows.kappa"),
        ({"method": "opacity_maps", "slices": 0}, "shadows.slices"),
        ({"method": "light_oriented", "resolution": 1}, "shadows.resolution"),
        ({"method": "light_oriented", "resolution": 8.5}, "shadows.resolution"),
        ({"method": "light_oriented", "padding": -1}, "shadows.padding"),
        ({"method": "light_oriented", "slices": 8}, "shadows.slices"),  # a key the method does not read
        ({"method": "smap", "kappa": 0.1}, "shadows.kappa"),
        ({"method": "none", "resolution": 16}, "shadows.resolution"),
        ({"method": "opacity_maps", "sharpness": 2}, "shadows.sharpness"),
    ],
)
def test_bad_method_or_parameters_name_the_key(shadows, key):
    with pytest.raises(errors.ValidationError) as exc:
        resolve_scene(with_shadows(**shadows))
    assert exc.value.field == key


def test_switches_turn_the_shadow_off():
    off = scene()
    off["effects"]["shadow"] = False
    off["shadows"] = {"method": "opacity_maps"}
    assert resolve_scene(off).shadow_method == "none"
    assert resolve_scene(scene(k_shadow=0.0)).shadow_method == "none"
    assert resolve_scene(dict(scene(k_shadow=0.0), shadows={"method": "light_oriented"})).shadow_method == "light_oriented"


# ----------------------------------------------------------------------------- T = 1 in front, darker behind


@pytest.mark.parametrize("method", LIGHT_METHODS)
def test_light_space_T_is_one_in_front_of_the_hair_and_darkens_behind(method):
    hair = slab()
    grid = np.stack(np.meshgrid(np.linspace(-0.3, 0.3, 5), np.linspace(-0.3, 0.3, 5)), -1).reshape(-1, 2)
    front = np.concatenate([grid, np.full((len(grid), 1), 0.3)], 1)  # between the light (+z) and the hair
    behind = front * [1, 1, -1]
    lights = np.stack([LIGHT, -LIGHT])
    T = light_transmittance(hair, lights, np.stack([front, behind]), method=method, resolution=16)
    assert T.shape == (2, len(grid), 2)
    np.testing.assert_array_equal(T[0, :, 0], 1.0)  # in front of the hair, toward light 0
    np.testing.assert_array_equal(T[1, :, 1], 1.0)  # the same points are in front for the opposite light
    assert np.all(T[1, :, 0] < 0.5) and np.all(T[0, :, 1] < 0.5)  # behind the slab: darker
    thin = light_transmittance(hair, LIGHT, behind, method=method, resolution=16, kappa=0.001)
    assert np.all(thin[:, 0] > T[1, :, 0]) and np.all(thin < 1)  # a smaller κ lets more light through


@pytest.mark.parametrize("method", LIGHT_METHODS)
def test_rendered_texels_facing_the_light_are_lit_and_the_far_side_darker(views, method):
    prep, res = views[method]
    for j, light in enumerate(prep.scene.lights):
        lit, dark = [], []
        for pc, c in zip(prep.clusters, res.clusters):
            facing = pc.normal[-1] @ light  # outer layer's normals
            T = c.shadow[-1, j]
            lit.append(T[facing > 0.5])
            dark.append(T[facing < -0.5])
        lit, dark = np.concatenate(lit), np.concatenate(dark)
        assert lit.size and dark.size
        # a texel's T is its strands' below the surface (synth._shadowing.seen_points), so even a lit one is shaded
        assert lit.max() > 0.6 and lit.max() > dark.max() and lit.mean() > dark.mean() + 0.2
    inner, outer = (np.concatenate([c.shadow[k].ravel() for c in res.clusters]) for k in (0, -1))
    assert inner.mean() < outer.mean()  # the inner layer lies deeper in the hair


def test_smap_is_one_on_the_outer_layer_and_darker_inside(views):
    _, res = views["smap"]
    for c in res.clusters:
        np.testing.assert_array_equal(c.shadow[-1], 1.0)  # nothing outside the outer layer
        assert np.all(c.shadow[0] <= 1.0) and c.shadow[0].min() < 1.0


# ----------------------------------------------------------------------------- no shadow work; per-light shading


def test_none_does_no_shadow_work(db, monkeypatch):
    def boom(*args, **kwargs):
        raise AssertionError("shadow work for shadows.method = 'none'")

    for name in ("light_transmittance", "light_oriented_map", "opacity_shadow_maps"):
        monkeypatch.setattr(hairlut.shadows, name, boom)
    monkeypatch.setattr(hairlut.synth._shading, "shadow_map", boom)
    given = with_shadows(method="none")
    given["render"]["resolution"] = [12, 6]  # a shape no other test traced, so the kernel traces afresh
    prep = prepare(given, db)
    res = render_view(prep, lights=[[0.0, 1.0, 0.0]])
    assert "shadows" not in res.stats["seconds"]
    for c in res.clusters:
        np.testing.assert_array_equal(c.shadow, 1.0)


def test_plan_explains_the_shadow_method(tmp_path):
    from .test_plan import TINY_HRIR

    def steps(**shadows):
        s = with_shadows(**shadows)
        s["tables"] = {"hrir": TINY_HRIR}
        return {st.name: st for st in plan(s, tmp_path).steps}

    st = steps()
    assert st["s_map"].action == "skip" and st["shadow_maps"].action == "run"  # auto: light-oriented
    assert st["shadows.method"].action == "choose" and "light_oriented" in st["shadows.method"].reason
    st = steps(method="smap")
    assert st["s_map"].action == "run" and st["shadow_maps"].action == "skip"
    assert st["shadows.method"].action == "set"
    st = steps(method="none")
    assert st["s_map"].action == "skip" and st["shadow_maps"].action == "skip" and "'none'" in st["s_map"].reason
    st = steps(method="light_oriented", resolution=20)
    assert st["s_map"].action == "skip" and st["shadow_maps"].action == "run"
    assert "light-oriented" in st["shadow_maps"].reason and "25³ cells" in st["shadow_maps"].reason
    st = steps(method="opacity_maps", slices=8, kappa=0.02)
    assert st["shadow_maps"].action == "run" and "8 slices" in st["shadow_maps"].reason
    assert st["shadow_maps"].details["kappa"] == 0.02


def test_light_space_maps_are_rebuilt_only_when_the_lights_change(views):
    prep, res = views["light_oriented"]
    again = render_view(prep)
    assert again.stats["seconds"]["shadows"] == prep.seconds["shadows"]  # the scene's own lights: not rebuilt
    other = render_view(prep, lights=[[0.0, -1.0, 0.2]])
    assert other.clusters[0].shadow.shape[1] == 1
    assert other.stats["seconds"]["shadows"] > prep.seconds["shadows"]  # rebuilt for the new light
    back = render_view(prep)  # and for the scene's own lights again
    for a, b in zip(res.clusters, back.clusters):
        np.testing.assert_allclose(a.shadow, b.shadow)


def test_shade_lights_applies_each_lights_own_transmittance():
    rng = np.random.default_rng(1)
    K, n, L = 2, 5, 3
    lighting, re, T = rng.uniform(size=(K, n, L, 3)), rng.uniform(size=(K, L, n)), rng.uniform(size=(K, n, L))
    want = np.einsum("knl,knlc,kln->knc", T, lighting, re)
    np.testing.assert_allclose(np.asarray(shade_lights(lighting, re, T)), want, rtol=1e-5)
