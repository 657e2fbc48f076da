"""Energy: the layered render's radiance per unit α against the strand render and Kajiya–Kay's closed form (issue 26).

A furnace: a flat slab of straight, parallel strands of uniform density (one procedural cluster whose cross-section
is a flat ellipse, half-axes 0.3 × 0.03, strands along y), one directional light, no environment.  With shadows off
every strand has the same lighting, so the strand render's colour per unit α is exactly the lighting (eqs 8–11,
Kajiya–Kay: kd · sin(t, l) · f_dif for the diffuse term, ks · max(0, sin(t, l) sin(t, v) − (t·l)(t·v))^p · f for each
specular lobe, unshifted), whatever the slab's density or thickness; the layered render must give the same, within
2 %, at several view and light angles, densities and hair colours.

Colour per unit α: the luminance of the premultiplied RGB over α, averaged over the pixels with α > :data:`ALPHA_MIN`.

Before the fix (``[material] reflectance = "hrir"``, eq 13 as written: the lighting × the HRIR's re) the layered
colour per unit α was 0.16–0.40 of the strand render's on :data:`CASES` (0.399 frontal, 0.158 back light, 0.204
grazing light); with ``"unit"`` (the default) it is the strand render's and Kajiya–Kay's to 1e-4 on every case
(``hairlut.synth.shade_kernel``'s docstring says why).

Measured, not tested (:func:`slab` at 64², strand render level 1; each row names what differs from 200 white strands
seen and lit from +z): with shadows on, the ratio depends on the shadow method and on the strand render's own shadows, which darken an isolated strand by its own tube (see
:func:`test_an_isolated_strand_is_not_shadowed_by_itself`).  Layered / strands colour per unit α, before → after:

| slab case | smap (k_shadow 0.5) | light_oriented | opacity_maps |
|---|---|---|---|
| (as stated) | 0.63 → 1.67 | 0.41 → 1.06 | 0.50 → 1.21 |
| light (0.5, 0.8, 1) | 0.64 → 2.02 | 0.35 → 1.05 | 0.32 → 0.97 |
| light behind (−1, 0.3, −0.4) | 1.52 → 10.1 | 0.30 → 1.87 | 0.22 → 1.33 |
| view (0.3, 0.4, 1), light (0.2, −0.6, 1) | 0.64 → 1.79 | 0.37 → 1.02 | 0.38 → 1.05 |
| 40 strands, brown (0.75, 0.5, 0.25) | 0.63 → 1.40 | 0.48 → 1.09 | 0.43 → 1.02 |
| kd 0.5, ks 0.4 / 0.3, view (0, −0.3, 1), light (0, 0.5, 1) | 0.66 → 1.76 | 0.39 → 1.01 | 0.41 → 1.04 |

Eq 12's s-map shadows a layer by the α of the layers outside it whatever the light's direction, so it cannot darken
the outermost layer nor tell a back light from a front one; the light-space methods come within 10 % of the strand
render but with the back light (1.33–1.87: their maps are coarse against a slab 0.06 thick).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from hairlut import errors
from hairlut.render import render_layered, render_strands
from hairlut.scene import resolve_scene

#: Pixels with less α are left out of the colour per unit α (their colour is all rounding).
ALPHA_MIN = 0.05
#: Rec. 709 luminance weights.
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: The strands' tangent: the slab's strands run along y.
TANGENT = np.array([0.0, 1.0, 0.0])


def slab(*, view, light, count=200, colour=(1.0, 1.0, 1.0), kd=1.0, ks_I=0.0, ks_II=0.0, shadows="none", res=48, **material):
    """The furnace scene: one straight cluster along y whose cross-section is a flat ellipse (half-axes 0.3 along x,
    0.03 along z), ``count`` strands of radius 0.004 spread uniformly over it, seen from ``view`` and lit from
    ``light``; shift 0 (so a lobe's value is Kajiya–Kay's at the strand's own tangent), direct maps, track reads."""
    return resolve_scene(
        {
            "render": {"resolution": [16, 8], "method": "direct", "layer_reads": "track"},
            "camera": {"view": list(view), "resolution": [res, res]},
            "lights": {"directions": [list(light)]},
            "material": {"kd": kd, "ks_I": ks_I, "ks_II": ks_II, "hair_color": list(colour), "shift": 0.0, **material},
            "shadows": {"method": shadows},
            "strands": {"count": count, "radius": 0.004, "profile": "uniform", "seed": 1},
            "clusters": [
                {
                    "trajectory": [[0.0, 0.3, 0.0], [0.0, 0.0, 0.0], [0.0, -0.3, 0.0]],
                    "half_axis_a": 0.3,
                    "half_axis_b": 0.03,
                    "s_t": 2,
                    "s_u": 8,
                }
            ],
        }
    )


def colour_per_alpha(rgba) -> float:
    """The luminance of the premultiplied RGB over α, averaged over the pixels with α > :data:`ALPHA_MIN`."""
    a = np.asarray(rgba[..., 3], np.float64)
    m = a > ALPHA_MIN
    assert m.sum() > 50, "the frame holds too little hair to measure"
    return float(((np.asarray(rgba[..., :3], np.float64) @ LUMA)[m] / a[m]).mean())


def _unit(x):
    x = np.asarray(x, np.float64)
    return x / np.linalg.norm(x)


def kajiya_kay(scene) -> float:
    """The luminance of eqs 8–11 for the slab's strands, written out: kd sin(t, l) f_dif + Σ_lobes ks (sin(t, l)
    sin(t, v) − (t·l)(t·v))₊^p f, t the strands' tangent, shift 0, one white light."""
    m = scene.material
    t, v, l = TANGENT, _unit(scene.view), _unit(scene.lights[0])
    tl, tv = t @ l, t @ v
    sl, sv = math.sqrt(max(0.0, 1 - tl * tl)), math.sqrt(max(0.0, 1 - tv * tv))
    lobe = max(0.0, sl * sv - tl * tv)
    hair = np.asarray(m["hair_color"])
    out = m["kd"] * sl * (hair @ LUMA)
    out += m["ks_I"] * lobe ** m["p_I"] * (np.asarray(m["spec_color_I"]) @ LUMA)
    second = np.asarray(m["spec_color_II"]) * (hair if m["secondary_hair_tint"] else 1.0)
    out += m["ks_II"] * lobe ** m["p_II"] * (second @ LUMA)
    return float(out)


CASES = {
    "frontal": {"view": [0, 0, 1], "light": [0, 0, 1]},
    "key light": {"view": [0, 0, 1], "light": [0.5, 0.8, 1.0]},
    "back light": {"view": [0, 0, 1], "light": [-1.0, 0.3, -0.4]},
    "oblique view": {"view": [0.3, 0.4, 1.0], "light": [0.2, -0.6, 1.0]},
    "grazing light": {"view": [0, 0, 1], "light": [0.1, 1.0, 0.2]},
    "sparse, brown": {"view": [0, 0, 1], "light": [0.4, 0.2, 1.0], "count": 40, "colour": (0.75, 0.5, 0.25)},
    "dense, dark": {"view": [0.2, 0, 1], "light": [0.3, -0.3, 1.0], "count": 400, "colour": (0.2, 0.12, 0.08)},
    "specular": {
        "view": [0, -0.3, 1.0],
        "light": [0, 0.5, 1.0],
        "kd": 0.5,
        "ks_I": 0.4,
        "ks_II": 0.3,
        "colour": (0.6, 0.4, 0.2),
    },
    "specular, off the mirror cone": {
        "view": [0.2, 0.1, 1.0],
        "light": [-0.5, 0.4, 1.0],
        "kd": 0.3,
        "ks_I": 0.5,
        "ks_II": 0.4,
        "p_I": 8.0,
        "p_II": 4.0,
    },
}


@pytest.mark.parametrize("case", list(CASES))
def test_layered_energy_matches_the_strands_and_kajiya_kay(case):
    """Shadows off: the layered render's colour per unit α is the strand render's within 2 %, and both are
    Kajiya–Kay's closed form within 2 % (measured: all three equal to 1e-4)."""
    sc = slab(**CASES[case])
    ref = render_strands(sc, levels=[0])
    lay = render_layered(sc, camera=ref.camera, repeat=0)
    want, strands, layered = kajiya_kay(sc), colour_per_alpha(ref.rgba), colour_per_alpha(lay.rgba)
    assert want > 0.01  # not vacuous
    assert strands == pytest.approx(want, rel=0.02)
    assert layered == pytest.approx(strands, rel=0.02)
    assert layered == pytest.approx(want, rel=0.02)


def test_the_paper_reflectance_stays_available_and_is_what_was_wrong():
    """``reflectance = "hrir"`` is eq 13 as written (× the HRIR's re): on the frontal slab its colour per unit α is
    far below the strands' (measured 0.38), where ``"unit"`` is exact; α is the same either way."""
    frames = {}
    for mode in ("unit", "hrir"):
        sc = slab(**CASES["frontal"], reflectance=mode)
        frames[mode] = render_layered(sc, repeat=0)
    np.testing.assert_array_equal(frames["unit"].rgba[..., 3], frames["hrir"].rgba[..., 3])
    ratio = colour_per_alpha(frames["hrir"].rgba) / colour_per_alpha(frames["unit"].rgba)
    assert 0.2 < ratio < 0.6


def test_shade_kernel_reflectances():
    """``unit``: the shaded colour is α · τ · Ψ^lighting (premultiplied, re unread); ``hrir``: τ · Ψ^lighting · re."""
    from hairlut.synth._synth import shade_kernel

    rng = np.random.default_rng(3)
    C, K, L, n_t, n_u = 2, 3, 2, 4, 5
    f32 = np.float32
    re = rng.uniform(size=(C, K, L, n_t, n_u)).astype(f32)
    alpha = rng.uniform(size=(C, K, n_t, n_u)).astype(f32)
    t = np.broadcast_to(TANGENT, (C, K, n_t, n_u, 3)).astype(f32)
    n = np.broadcast_to([0.0, 0.0, 1.0], (C, K, n_t, n_u, 3)).astype(f32)
    mat = np.array([1.0, 0.3, 0.2, 20.0, 10.0, 0.0, 1.0, 0.0, 0.0], f32)
    cols = np.array([[0.7, 0.5, 0.3], [1, 1, 1], [0.7, 0.5, 0.3]], f32)
    args = (
        re,
        alpha,
        t,
        n,
        np.zeros((C, K, n_t, n_u), f32),
        _unit([0.1, 0.2, 1.0]).astype(f32),
        np.stack([_unit([0.3, 0.4, 1.0]), _unit([-0.5, 0.1, 0.4])]).astype(f32),
        np.array([[1.0, 0.9, 0.8], [0.2, 0.3, 0.4]], f32),
        mat,
        cols,
        f32(0.5),
        np.zeros(3, f32),
    )
    kw = {"effects": (True, True, True, False, True), "linear": False}
    tau, light, unit, _ = (np.asarray(x) for x in shade_kernel(*args, **kw, reflectance="unit"))
    _, _, paper, _ = (np.asarray(x) for x in shade_kernel(*args, **kw, reflectance="hrir"))
    np.testing.assert_allclose(unit[..., :3], (alpha * tau)[..., None] * light, rtol=1e-5, atol=1e-7)
    np.testing.assert_array_equal(unit[..., 3], alpha)
    zero = np.asarray(shade_kernel(np.zeros_like(re), *args[1:], **kw, reflectance="unit")[2])
    np.testing.assert_array_equal(zero, unit)  # re is not read
    from hairlut.synth._shading import lighting_kernel

    per_light = np.asarray(lighting_kernel(*(jnp.asarray(a) for a in (t, n, args[5], args[6], args[7], args[4], mat, cols))))
    want = tau[..., None] * np.einsum("cklij,ckijlr->ckijr", re, per_light)
    np.testing.assert_allclose(paper[..., :3], want, rtol=1e-5, atol=1e-7)


def test_an_unknown_reflectance_names_the_key():
    with pytest.raises(errors.ValidationError) as e:
        slab(**CASES["frontal"], reflectance="phong")
    assert e.value.field == "material.reflectance"


@pytest.mark.xfail(
    strict=True,
    reason="the strand render shadows each step through its own strand's tube too (an isolated strand, shadows on: "
    "0.69-0.80 of Kajiya-Kay's value by light direction and frame); reported in issue 26, not changed here",
)
def test_an_isolated_strand_is_not_shadowed_by_itself():
    """One strand alone, shadows on: nothing lies between it and the light, so its colour per unit α is Kajiya–Kay's,
    as with shadows off (Kajiya–Kay's diffuse term already integrates the lit half of the fibre)."""
    sc = slab(view=[0, 0, 1], light=[0, 0, 1], count=1, shadows="light_oriented")
    ref = render_strands(sc, levels=[1])
    assert colour_per_alpha(ref.rgba) == pytest.approx(kajiya_kay(sc), rel=0.02)
