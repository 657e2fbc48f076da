"""Physical bounds of every table kind, checked when a bake writes its tables (issue 29, Deliver 5).

Each kind declares its bounds in its ``_kind.py`` (``Baker(bounds=...)``, one ``Bound`` a line) and every write of
the kind or its shard kind checks them (``hairlut.assets.bounds``): α in [0, 1], re ≤ α·(k_a + k_d + k_s), the scene
table's re/α terms, |Rd|, |Rs| ≤ 1 and |Cd|, |Cs| ≤ ‖a‖₂.  A breach (injected here: no recipe makes one now) is
refused like NaN, naming the table and the recipe keys, and nothing is written under the output's name.
"""

import numpy as np
import pytest

from hairlut import errors
from hairlut.assets import Axis, Variable, write_table
from hairlut.assets.bounds import ATOL, RTOL, check_bounds
from hairlut.bake import registry
from hairlut.bake.protocol import Baker, Bound

from ._synth_fixtures import scene as base_scene

HRIR = {"sectors": {"count": 4, "grid": [8, 8]}, "angles": {"views": 4, "lights": 3}, "trace": {"pixels": 8, "steps": 12}}
TINY = {"sectors": {"grid": [8, 8]}, "trace": {"pixels": 8, "steps": 12}}


def _scene(**trace):
    from hairlut.scene import resolve_scene

    s = base_scene()
    s["strands"] = {**s["strands"], "count": 30}
    s["render"] = {**s["render"], "method": "scene", "views": 8, "terms": 1, "shading_pixels": 8, "precision": "float32"}
    s["tables"] = {"hrir": {**TINY, "trace": {**TINY["trace"], **trace}}}
    return resolve_scene(s)


# ----------------------------------------------------------------------------- the mechanism


RE = Bound("re", 0.0, 1.0, of="alpha", scale=lambda r, t: r["k"], keys=("k", "depth.kappa"), text="0 ≤ re ≤ k·α")
DIMS_A, DIMS_R = ("n", "v", "p"), ("n", "v", "l", "p")


def _tables(alpha, re):
    return {"alpha": (alpha, DIMS_A), "re": (re, DIMS_R)}


def test_a_bound_aligns_its_reference_by_dimension_name_and_allows_rounding():
    rng = np.random.default_rng(0)
    alpha = rng.uniform(0, 1, (3, 4, 5)).astype(np.float32)
    re = (0.7 * alpha[:, :, None, :] * rng.uniform(0, 1, (3, 4, 6, 5))).astype(np.float32)
    recipe = {"k": 0.7, "depth": {"kappa": 2.0}}
    check_bounds("toy", (RE,), recipe, _tables(alpha, re))
    edge = (0.7 * alpha[:, :, None, :] * np.ones((1, 1, 6, 1))).astype(np.float32)
    check_bounds("toy", (RE,), recipe, _tables(alpha, edge * np.float32(1 + RTOL / 2)))  # within the tolerance
    check_bounds("toy", (RE,), recipe, _tables(alpha.astype(np.float16), edge.astype(np.float16)))  # both rounded
    worse = edge.copy()
    worse[2, 1, 4, 3] = 0.7 * alpha[2, 1, 3] * (1 + 10 * RTOL) + 10 * ATOL
    with pytest.raises(
        errors.BoundsError,
        match=r"toy: re breaks its bound 0 ≤ re ≤ k·α: 1 value beyond it .*index "
        r"\[2, 1, 4, 3\]\); the recipe drives it: k=0.7, depth.kappa=2.0",
    ):
        check_bounds("toy", (RE,), recipe, _tables(alpha, worse))
    low = edge / 2
    low[1, 2, 3, 0] = -1e-3
    with pytest.raises(errors.BoundsError, match=r"1 value beyond it \(worst -0.001 against 0, at index \[1, 2, 3, 0\]\)"):
        check_bounds("toy", (RE,), recipe, _tables(alpha, low))
    nan = edge.copy()
    nan[0, 0, 0, 0] = np.nan
    with pytest.raises(errors.NonFiniteError, match=r"toy: re is not finite \(1 NaN/inf values\).*k=0.7"):
        check_bounds("toy", (RE,), recipe, _tables(alpha, nan))


@pytest.fixture
def bounded_toy():
    """A toy kind with one Bound in its Baker (and its shard kind), withdrawn from the kind table afterwards."""
    from hairlut.assets import KINDS

    Baker(
        kind="bounded_toy",
        command="toy",
        description="a toy kind with a bound",
        required=("x",),
        schema={},
        resolve_recipe=dict,
        bake=lambda recipe, out, **_: {},
        load=None,
        estimate=None,
        shard_kind="bounded_toy_shard",
        merge=lambda s, o: {},
        bounds=(Bound("x", 0.0, 1.0, keys=("gain",)),),
    )
    yield ("bounded_toy", "bounded_toy_shard")
    for name in ("bounded_toy", "bounded_toy_shard"):
        dict.pop(KINDS, name, None)


def test_a_new_kind_declares_its_bounds_in_one_line_and_every_write_checks_them(tmp_path, bounded_toy):
    axes = [Axis("i", np.arange(3), "1", "index")]

    def x(*values):
        return [Variable("x", np.array(values), ("i",), "1", "x")]

    write_table(tmp_path / "ok.h5", "bounded_toy", {"gain": 1}, axes, x(0.0, 0.5, 1.0))
    for kind in bounded_toy:
        with pytest.raises(errors.BoundsError, match=r"bounded_toy.* bad.h5: x breaks its bound \[0, 1\].*gain=2"):
            write_table(tmp_path / "bad.h5", kind, {"gain": 2}, axes, x(0.0, 2.0, 1.0))
    assert not (tmp_path / "bad.h5").exists()


# ----------------------------------------------------------------------------- each kind, a breach injected


def _traced_then(monkeypatch, change):
    """The hrir bake's tracer outputs (α, re) passed through ``change`` before they are stored."""
    from hairlut.hrir import _bake

    traced = _bake.dispatch_trace

    def dispatch(*args, **kwargs):
        gather = traced(*args, **kwargs)
        return lambda: change(*(np.array(x) for x in gather()))

    monkeypatch.setattr(_bake, "dispatch_trace", dispatch)


def _nan(alpha, refl):
    refl[-1, 0, 0, 0] = np.nan
    return alpha, refl


def _brighter(alpha, refl):
    n, v, p = np.unravel_index(np.argmax(alpha), alpha.shape)
    refl[n, v, 0, p] = 1.5 * alpha[n, v, p]  # k_a + k_d + k_s = 1
    return alpha, refl


@pytest.mark.parametrize(
    "change, error, match",
    [
        (
            _nan,
            errors.NonFiniteError,
            r"hrir_shard part-[^:]*: reflectance is not finite \(1 NaN/inf values\); the "
            r"recipe drives it: trace\.extinction=0\.63.*phong\.shininess=20\.0",
        ),
        (
            _brighter,
            errors.BoundsError,
            r"hrir_shard part-[^:]*: reflectance breaks its bound 0 ≤ re ≤ α·\(k_a \+ k_d \+ "
            r"k_s\): 1 value beyond it.*trace\.extinction=0\.63.*phong\.ambient=0\.1",
        ),
        (
            lambda a, r: (a + 0.5, r),
            errors.BoundsError,
            r"hrir_shard part-[^:]*: alpha breaks its bound 0 ≤ α ≤ 1: "
            r".*trace\.extinction",
        ),
    ],
)
def test_hrir_db_refuses_tables_beyond_their_bounds(tmp_path, monkeypatch, change, error, match):
    """NaN (no recipe inside the float32 bounds makes one now), re above α·(k_a + k_d + k_s), α above 1."""
    _traced_then(monkeypatch, change)
    with pytest.raises(error, match=match):
        registry.bake("hrir_db", HRIR, tmp_path / "db.h5")
    assert not (tmp_path / "db.h5").exists()


def test_scene_maps_refuse_a_ratio_above_the_phong_sum(tmp_path, monkeypatch):
    from hairlut.planner import scene_maps_recipe
    from hairlut.scenemaps import _parts

    terms = _parts.ratio_terms

    def brighter(*args, **kwargs):
        t = terms(*args, **kwargs).copy()
        t[0, 0, 0, 0] = 1.2  # c₀, the mean of ρ = re/α over the lights, with k_a + k_d + k_s = 1
        return t

    monkeypatch.setattr(_parts, "ratio_terms", brighter)
    sc = _scene()
    with pytest.raises(
        errors.BoundsError,
        match=r"scene_shard part-[^:]*: ratio\[\.\.\., 0\] breaks its bound 0 ≤ c₀ "
        r"≤ k_a \+ k_d \+ k_s.*hrir\.trace\.extinction=0\.63.*"
        r"hrir\.phong\.ambient=0\.1",
    ):
        registry.bake("scene_maps", scene_maps_recipe(sc), tmp_path / "maps.h5", scene=sc)
    assert not (tmp_path / "maps.h5").exists()


@pytest.mark.parametrize("extinction", [1e7, 1e9])
def test_scene_maps_at_opaque_extinction_stay_within_their_bounds(tmp_path, extinction):
    """Issue 29 N9 in the scene table's bake: its view-grid weights were differences of one prefix sum (both ways
    along each ray), which lose the depth in front of a step far denser than it (α reached 1.00001 at extinction
    1e7 on this scene, refused by its bound); now each side is summed directly, and the bake passes its bounds
    (α in [0, 1], c₀ = mean re/α in [0, 1]) with α saturated."""
    from hairlut.planner import scene_maps_recipe
    from hairlut.scenemaps import load_scene_maps

    sc = _scene(extinction=extinction)
    registry.bake("scene_maps", scene_maps_recipe(sc), tmp_path / "maps.h5", scene=sc)
    maps = load_scene_maps(tmp_path / "maps.h5")
    a, c0 = np.asarray(maps.alpha, np.float64), np.asarray(maps.ratio[..., 0], np.float64)
    assert a.max() > 0.99 and 0 <= a.min() and a.max() <= 1 + 1e-3 and 0 <= c0.min() and c0.max() <= 1 + 1e-3


def test_sh_tables_refuse_rd_beyond_one(tmp_path, monkeypatch):
    from hairlut.shtables import _bake

    block = _bake.dense_block

    def louder(*args, **kwargs):
        dense, light = block(*args, **kwargs)
        return {**dense, "rd": np.asarray(dense["rd"]) * 2}, light  # the largest |Rd| is 0.9: 1.8 > 1

    monkeypatch.setattr(_bake, "dense_block", louder)
    with pytest.raises(errors.BoundsError, match=r"sh_shard part-[^:]*: dense/rd breaks its bound \|Rd\| ≤ 1.*kernel\.p=49\.0"):
        registry.bake("sh_tables", {"dense": {"t_resolution": 2}}, tmp_path / "sh.h5")
    assert not (tmp_path / "sh.h5").exists()


def test_sh_tables_refuse_cd_beyond_the_light_norm(tmp_path, monkeypatch):
    from hairlut.shtables import _bake

    block = _bake.dense_block

    def louder(*args, **kwargs):
        dense, light = block(*args, **kwargs)
        return dense, {**light, "cd": np.asarray(light["cd"]) * 10}

    monkeypatch.setattr(_bake, "dense_block", louder)
    with pytest.raises(errors.BoundsError, match=r"sh_shard part-[^:]*: light/cd breaks its bound \|Cd\| ≤ ‖a‖₂"):
        registry.bake("sh_tables", {"dense": {"t_resolution": 2}}, tmp_path / "sh.h5", light="sky")
    assert not (tmp_path / "sh.h5").exists()
