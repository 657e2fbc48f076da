"""What the planner chooses for a scene that leaves a knob out (issue 26, deliverable 1): ``hairlut.scene``'s rules,
checked against independent facts (a straight strand turns 0 times, a circle once), the issue's orderings (a curly
groom gets more clusters than a straight one of the same strand count) and the promise that a scene's own value is
always kept."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hairlut.bench import _grooms as g
from hairlut.geometry import Strands
from hairlut.geometry.splats import SIGMA_PER_RADIUS
from hairlut.scene import cluster_count, layer_reads, layer_shells, load_scene, sector_grid, table_layout, texel_resolution
from hairlut.scene._choices import (
    CLUSTERS_MAX,
    CLUSTERS_MIN,
    GRID,
    GRID_STEP,
    SIGMA_CELLS,
    STRANDS_PER_CLUSTER,
    TRACK_SECTORS,
    strand_turns,
)


def _polyline(points: np.ndarray, copies: int = 1) -> Strands:
    pts = np.concatenate([points + [0.0, 0.0, 0.01 * i] for i in range(copies)]).astype(np.float32)
    return Strands(pts, np.full(copies, len(points)), thickness=np.full(len(pts), 0.01, np.float32))


def test_a_straight_strand_turns_zero_times_and_a_circle_once():
    line = np.stack([np.linspace(0, 1, 20), np.zeros(20), np.zeros(20)], axis=1)
    assert strand_turns(_polyline(line, 3)) == pytest.approx(0.0, abs=1e-12)
    n = 400  # a closed circle sampled at n + 1 points: exterior angles sum to 2π less the one at the closing point
    t = np.linspace(0, 2 * math.pi, n + 1)
    circle = np.stack([np.cos(t), np.sin(t), np.zeros_like(t)], axis=1)
    assert strand_turns(_polyline(circle)) == pytest.approx((n - 1) / n, rel=1e-6)


def test_two_strands_do_not_turn_across_their_join():
    """The step from one strand's last point to the next strand's first is no turn of either strand."""
    a = np.stack([np.linspace(0, 1, 5), np.zeros(5), np.zeros(5)], axis=1)
    b = np.stack([np.zeros(5), np.linspace(0, 1, 5), np.full(5, 3.0)], axis=1)
    s = Strands(np.concatenate([a, b]).astype(np.float32), np.array([5, 5]))
    assert strand_turns(s) == pytest.approx(0.0, abs=1e-12)


def test_a_curly_groom_gets_more_clusters_than_a_straight_one_of_the_same_strand_count():
    curly, straight = g.curly(n_strands=300, seed=1), g.parted(n_strands=300, seed=1)
    c, s = cluster_count(curly), cluster_count(straight)
    assert not c.given and not s.given
    assert c.value > s.value >= CLUSTERS_MIN
    assert "turns" in c.reason and c.predicted


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 5000), st.floats(0.0, 10.0))
def test_the_count_stays_in_its_bounds_and_every_cluster_can_hold_its_strands(strands, turns):
    class Fake:  # strand_turns is tested above; here only the arithmetic of the bounds
        n_strands = strands

    from hairlut.scene import _choices

    orig = _choices.strand_turns
    _choices.strand_turns = lambda s: turns
    try:
        n = cluster_count(Fake()).value
    finally:
        _choices.strand_turns = orig
    assert 1 <= n <= CLUSTERS_MAX and n <= strands
    assert n <= max(CLUSTERS_MIN, strands // STRANDS_PER_CLUSTER)


def test_an_explicit_value_is_always_kept():
    groom = g.curly(n_strands=100, seed=2)
    assert cluster_count(groom, 7).value == 7 and cluster_count(groom, 7).given
    assert cluster_count(groom, 10_000).value == 100  # never more clusters than strands
    for v in ("pair", "track"):
        assert layer_reads(v, 10**9).value == v and layer_reads(v, 1).given


def test_the_layer_shells_are_the_measured_default_unless_given():
    from hairlut.geometry.cluster_defaults import STRUCTURE_DEFAULTS

    chosen = layer_shells()
    assert chosen.value == list(STRUCTURE_DEFAULTS["layer_radii"]) and not chosen.given and "shells" in chosen.reason
    assert layer_shells([0.3, 1.0]).value == [0.3, 1.0] and layer_shells([0.3, 1.0]).given


def test_layer_reads_follow_the_sector_count():
    assert layer_reads("auto", TRACK_SECTORS).value == "track"
    far = layer_reads("auto", TRACK_SECTORS + 1)
    assert far.value == "pair" and "ms a frame" in far.reason


def test_the_plan_prints_every_choice_and_a_given_value_is_set(tmp_path):
    from hairlut.planner import choices

    scenes = g.groom_scenes(tmp_path, kinds=("curly",), sizes={"curly": {"n_strands": 60, "points": 8}}, resolution=(32, 32))
    sc = load_scene(scenes["curly"])
    chosen = {c.key: c for c in choices(sc)}
    assert set(chosen) == {
        "groom.clusters",
        "groom.layer_radii",
        "render.resolution",
        "tables.hrir.sectors.grid",
        "render.views",
        "render.shading_pixels",
        "render.layer_reads",
        "shadows.method",
    }
    assert not any(c.given for c in chosen.values())
    text = scenes["curly"].read_text() + '\n[render]\nlayer_reads = "pair"\n'
    scenes["curly"].write_text(text.replace("[groom]\n", "[groom]\nclusters = 5\n"))
    again = {c.key: c for c in choices(load_scene(scenes["curly"]))}
    assert again["groom.clusters"].value == 5 and again["groom.clusters"].given
    assert again["render.layer_reads"].value == "pair" and again["render.layer_reads"].given


# ----------------------------------------------------------------------------- render.resolution


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(0.0, 1e5), min_size=1, max_size=60),
    st.lists(st.floats(0.0, 1e4), min_size=1, max_size=60),
    st.integers(1, 600),
)
def test_chosen_texels_are_bounded_rounded_and_within_the_budget(lengths, widths, layers):
    from hairlut.budget import AUTO_TEXELS
    from hairlut.scene._choices import COLUMNS, ROWS, TEXEL_STEP

    c = texel_resolution("auto", lengths, widths, layers)
    cols, rows = c.value
    assert not c.given and c.key == "render.resolution"
    assert ROWS[0] <= rows <= ROWS[1] and COLUMNS[0] <= cols <= COLUMNS[1]
    assert rows % TEXEL_STEP == 0 and cols % TEXEL_STEP == 0
    assert rows * cols * layers <= AUTO_TEXELS or (rows, cols) == (ROWS[0], COLUMNS[0])


def test_texels_follow_the_projected_size_a_row_every_few_pixels_along_and_a_column_across():
    from hairlut.scene._choices import COLUMN_PIXELS, ROW_PIXELS

    cols, rows = texel_resolution("auto", [100.0, 80.0, 60.0], [20.0, 24.0, 16.0], 3).value
    assert rows == 4 * math.ceil(np.percentile([100, 80, 60], 90) / ROW_PIXELS / 4)
    assert cols == 4 * math.ceil(math.pi * np.percentile([20, 24, 16], 90) / COLUMN_PIXELS / 4)
    bigger = texel_resolution("auto", [200.0, 160.0, 120.0], [40.0, 48.0, 32.0], 3).value
    assert bigger[0] > cols and bigger[1] > rows  # a closer camera or a larger frame: finer texels


@pytest.mark.parametrize(("s_u", "s_t"), [(8, 8), (4, 16), (3, 5)])
def test_a_small_cluster_still_gets_four_texels_a_sector_each_way(s_u, s_t):
    from hairlut.scene._choices import TEXELS_PER_SECTOR

    assert TEXELS_PER_SECTOR == 4
    cols, rows = texel_resolution("auto", [3.0], [1.0], 3, (s_u, s_t)).value
    assert cols == max(16, 4 * math.ceil(4 * s_u / 4)) and rows == max(8, 4 * math.ceil(4 * s_t / 4))


def test_a_given_texel_resolution_is_kept():
    c = texel_resolution([12, 6], [1e4], [1e4], 1000)
    assert c.value == [12, 6] and c.given


def test_the_camera_chooses_the_texels_of_a_groom_scene(tmp_path):
    """A 4× larger frame of the same groom gets finer texels (until the budget), and ``hairlut plan`` says why."""
    from hairlut.scene import texel_choice

    size = {"curly": {"n_strands": 60, "points": 8}}
    small = g.groom_scenes(tmp_path / "a", kinds=("curly",), sizes=size, resolution=(32, 32))
    large = g.groom_scenes(tmp_path / "b", kinds=("curly",), sizes=size, resolution=(128, 128))
    a, b = texel_choice(load_scene(small["curly"])), texel_choice(load_scene(large["curly"]))
    assert b.value[1] > a.value[1] and b.value[0] > a.value[0]
    assert "px long" in a.reason and not a.given


# ----------------------------------------------------------------------------- tables.hrir.sectors.grid


@settings(max_examples=80, deadline=None)
@given(st.lists(st.one_of(st.floats(1e-6, 2.0), st.just(float("nan"))), min_size=1, max_size=40), st.floats(0.1, 0.99))
def test_a_thinner_strand_gets_a_grid_at_least_as_fine_and_its_sigma_spans_the_cells(radii, thinner):
    """The grid is a multiple of its step within its bounds; thinner strands (every radius scaled down) never get a
    coarser one; the median strand's σ = r/√2 spans at least :data:`SIGMA_CELLS` cells unless the bound stops it."""
    a = sector_grid({}, radii)
    b = sector_grid({}, [thinner * r for r in radii])
    for c in (a, b):
        n = c.value[0]
        assert c.value == [n, n] and not c.given
        assert GRID[0] <= n <= GRID[1] and n % GRID_STEP == 0
    assert b.value[0] >= a.value[0]
    finite = [r for r in radii if math.isfinite(r)]
    if finite:
        cells = SIGMA_PER_RADIUS * float(np.median(finite)) * a.value[0]
        assert cells >= SIGMA_CELLS * (1 - 1e-9) or a.value[0] == GRID[1]
    else:
        assert a.value == [GRID[0]] * 2


def test_a_given_grid_is_kept_and_a_thick_strand_keeps_the_default_recipe():
    from hairlut.hrir import resolve_recipe
    from hairlut.scene import hrir_with_grid

    given = {"sectors": {"grid": [20, 24]}}
    c = sector_grid(given, [1e-4])
    assert c.value == [20, 24] and c.given and hrir_with_grid(given, c) == given
    thick = sector_grid({}, [0.2, 0.3])  # σ = 0.14 √area spans 1.2 cells on far fewer than 32
    assert thick.value == [GRID[0]] * 2
    assert resolve_recipe(hrir_with_grid({}, thick)) == resolve_recipe({})  # the database and table hashes stay
    thin = sector_grid({"trace": {"steps": 40}}, [0.01])
    folded = hrir_with_grid({"trace": {"steps": 40}}, thin)
    assert folded["sectors"]["grid"] == thin.value and folded["trace"]["steps"] == 40  # a given step count is kept


def test_the_same_groom_with_thinner_strands_is_traced_on_a_finer_grid(tmp_path):
    """Issue 26's ordering: the planner gives a groom of thinner strands a finer sector grid, the direct maps trace on
    it with two steps a cell, and ``hairlut plan`` lists it."""
    from hairlut.planner import choices, direct_recipe

    def scene(radius, folder):
        groom = g.write_groom(folder, "crop", g.crop(n_strands=80, seed=1, radius=radius), formats=("hair",))["hair"]
        return load_scene(g.write_scene(folder / "crop.toml", groom, resolution=(32, 32)))

    thick, thin = scene(0.1, tmp_path / "thick"), scene(0.01, tmp_path / "thin")
    a, b = (next(c for c in choices(s) if c.key == "tables.hrir.sectors.grid") for s in (thick, thin))
    assert b.value[0] > a.value[0] and "median strand radius" in b.reason
    rec = direct_recipe(thin)
    assert rec["sectors"]["grid"] == b.value and rec["trace"]["steps"] == 2 * b.value[0]
    from hairlut.planner import scene_maps_recipe

    t_thick, t_thin = (scene_maps_recipe(s)["table"] for s in (thick, thin))
    assert (t_thick["views"], t_thick["shading_pixels"]) == (64, 8)  # the defaults on the default grid
    assert t_thin["views"] >= t_thick["views"] and t_thin["shading_pixels"] > t_thick["shading_pixels"]


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 512), st.sampled_from([8, 16, 32, 64, 96, 128, 256]))
def test_the_scene_table_follows_the_grid_its_bins_divide_the_pixels(grid, pixels):
    auto = {"views": "auto", "shading_pixels": "auto"}
    views, bins = table_layout(auto, grid, pixels)
    assert views.value % 32 == 0 and views.value >= 64 and views.value >= 4 * grid / 3 - 1e-9
    assert pixels % bins.value == 0 and (bins.value >= grid / 4 or bins.value == pixels)
    finer_views, finer_bins = table_layout(auto, 2 * grid, pixels)
    assert finer_views.value >= views.value and finer_bins.value >= bins.value
    assert [c.value for c in table_layout(auto, 32, 64)] == [64, 8]  # the former defaults on the default grid
    kept = table_layout({"views": 10, "shading_pixels": 3}, grid, pixels)
    assert [c.value for c in kept] == [10, 3] and all(c.given for c in kept)
