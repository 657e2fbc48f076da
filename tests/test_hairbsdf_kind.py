"""The ``hair_bsdf`` table kind: recipe refusals, bake → load → lookup, the EXR atlas, split bakes, the CLI.

The tables' numbers come from ``hairlut.hairbsdf._integrals`` (tested in test_hairbsdf_physics.py); these tests
check the kind's plumbing, so most of them bake through a small stand-in with the same entry-wise contract
(``STAND_IN``), and a few through the real quadrature at a tiny resolution.
"""

from __future__ import annotations

import hashlib
import json
import types

import numpy as np
import pytest
from click.testing import CliRunner

from hairlut import errors
from hairlut.assets import read_table
from hairlut.bake import registry
from hairlut.hairbsdf import BAKER, load, resolve_recipe, write_atlas
from hairlut_cli.main import cli

SMALL = {"grid": {"resolution": [6, 5, 4]}, "coverage": {"resolution": [4, 3]}}


def _nodes(span, n):
    lo, hi = span
    return lo + (np.arange(n) + 0.5) * ((hi - lo) / n)


def _stand_in_tables(axes, resolution, *, quadrature, model, which, start=None, stop=None):
    """A smooth stand-in with the quadrature's contract: each row's (values, errors) from its own nodes alone."""
    out = {}
    if "coverage" in which:
        r = _nodes(axes["radius_px"], resolution["radius_px"])[:, None]
        n = _nodes(axes["strand_count"], resolution["strand_count"])[None, :]
        cov = 1 - (1 - np.minimum(1.0, r)) ** np.maximum(n, 0)
        out["coverage"] = (cov, np.full_like(cov, 1e-9))
    grid = [w for w in which if w != "coverage"]
    if grid:
        s = _nodes(axes["sin_theta_o"], resolution["sin_theta_o"])[start:stop, None, None]
        b = _nodes(axes["roughness"], resolution["roughness"])[None, :, None]
        a = _nodes(axes["absorption"], resolution["absorption"])[None, None, :]
        base = np.exp(-2 * (1 - a)) * (1 - 0.5 * s * s) * (0.5 + 0.4 * b)
        alpha = np.radians(model["alpha"])
        fields = {
            "mean_energy": [0.05 + 0.01 * s + 0 * base, 0.5 * base, 0.3 * base * base, 0.05 * base],
            "dual_scattering": [0.6 * base, 0.3 * base + 0.02, -alpha + 0 * base, alpha * (0.5 + 0.5 * s) + 0 * base,
                                b * (1 + s) + 0 * base, 2 * b + 0 * base],
        }  # fmt: skip
        for w in grid:
            v = np.stack(fields[w], axis=-1)
            out[w] = (v, np.full_like(v, 1e-8 / quadrature["nodes"]))
    return out


def _stand_in_montecarlo(axes, resolution, *, sample_scale, seed, model, which, start=None, stop=None):
    """The stand-in's Unreal-style estimate: its exact values plus noise that falls as 1/√(samples)."""
    exact = _stand_in_tables(axes, resolution, quadrature={"nodes": 8}, model=model, which=which, start=start, stop=stop)
    rng = np.random.default_rng([seed, start or 0])
    return {k: v + rng.normal(0, 0.01 / sample_scale, v.shape) for k, (v, _) in exact.items()}


def _stand_in_sigma(absorption, roughness, kind):
    a, r = np.asarray(absorption)[None, :], np.asarray(roughness)[:, None]
    return np.broadcast_to(a, (r.shape[0], a.shape[1])).copy() if kind == "sigma_a" else (np.log(a * a) / (6 - r)) ** 2


STAND_IN = types.SimpleNamespace(
    tables=_stand_in_tables,
    peak_bytes=lambda resolution, quadrature: {"bsdf_row": 1 << 20, "coverage_row": 1 << 20, "montecarlo_row": 1 << 20},
    montecarlo_unreal=_stand_in_montecarlo,
    absorption_sigma=_stand_in_sigma,
    MEAN_ENERGY_FIELDS=("R", "TT", "TRT", "residual"),
    DUAL_SCATTERING_FIELDS=("A_f", "A_b", "alpha_f", "alpha_b", "beta_f", "beta_b"),
)


@pytest.fixture
def physics(monkeypatch):
    """Bake through the stand-in quadrature."""
    from hairlut.hairbsdf import _bake

    _bake._coverage.cache_clear()
    monkeypatch.setattr(_bake, "_physics", lambda: STAND_IN)
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "0")
    yield STAND_IN
    _bake._coverage.cache_clear()


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def _sha(path) -> str:
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


# ----------------------------------------------------------------------------- the recipe


@pytest.mark.parametrize(
    "given, key",
    [
        ({"absorption": {"axis": "sigma_a", "sigma_a": [-0.5, 4.0]}}, "absorption.sigma_a"),
        ({"grid": {"roughness": [0.0, 1.5]}}, "grid.roughness"),
        ({"grid": {"roughness": [-0.1, 1.0]}}, "grid.roughness"),
        ({"quadrature": {"nodes": 7}}, "quadrature.nodes"),
        ({"absorption": {"colour": [float("nan"), 1.0]}}, "absorption.colour"),
        ({"absorption": {"sigma_a": [0.0, 2.0]}}, "absorption.sigma_a"),  # the colour axis does not read it
        ({"grid": {"resolution": [64, 64]}}, "grid.resolution"),
        ({"grid": {"sin_theta": [0.5, 0.5]}}, "grid.sin_theta"),
        ({"bsdf": {"eta": 0.9}}, "bsdf.eta"),
        ({"storage": {"dtype": "int8"}}, "storage.dtype"),
        (
            {"dual_scattering": {"bake": False}, "mean_energy": {"bake": False}, "coverage": {"bake": False}},
            "dual_scattering.bake",
        ),
    ],
)
def test_bad_recipes_name_the_key(given, key):
    with pytest.raises(errors.ValidationError) as exc:
        resolve_recipe(given)
    assert exc.value.field == key


def test_a_resolution_beyond_the_memory_budget_is_refused_before_any_allocation(tmp_path, monkeypatch):
    monkeypatch.setenv("HAIRLUT_MEMORY_LIMIT", "64M")
    huge = {"grid": {"resolution": [1024, 1024, 64]}}
    with pytest.raises(errors.BudgetError) as exc:
        resolve_recipe(huge)
    assert exc.value.field == "grid.resolution" and "memory limit" in str(exc.value)
    res = run("bake", "hair_bsdf", "--out", tmp_path / "x.h5", "--set", "grid.resolution=[1024,1024,64]")
    assert res.exit_code == 2 and "grid.resolution" in res.output and not (tmp_path / "x.h5").exists()
    with pytest.raises(errors.BudgetError) as exc:
        resolve_recipe({"coverage": {"resolution": [4096, 4096]}})
    assert exc.value.field == "coverage.resolution"


def test_a_quadrature_whose_kernels_exceed_the_budget_is_refused_before_it_runs(tmp_path, monkeypatch):
    """The recipe's tables fit, the quadrature's row kernel (its own peak_bytes estimate) does not: refused before any
    part is baked, naming the key that drives it."""
    monkeypatch.setenv("HAIRLUT_MEMORY_LIMIT", "100M")
    heavy = {"quadrature": {"nodes": 64, "levels": 8}, "coverage": {"bake": False}}
    resolve_recipe(heavy)  # the tables themselves fit
    with pytest.raises(errors.BudgetError) as exc:
        registry.bake("hair_bsdf", heavy, tmp_path / "x.h5")
    assert exc.value.field == "quadrature.nodes" and "row kernel" in str(exc.value)
    assert not (tmp_path / "x.h5").exists() and not list((tmp_path / "x.h5.parts").glob("part-*"))
    with pytest.raises(errors.BudgetError) as exc:
        registry.bake(
            "hair_bsdf", {"quadrature": {"coverage_nodes": 64}, "coverage": {"resolution": [64, 4096]}}, tmp_path / "c.h5"
        )
    assert exc.value.field == "coverage.resolution"


def test_the_defaults_are_unreals_and_resolve_to_themselves():
    r = resolve_recipe({})
    assert r["grid"]["resolution"] == [64, 64, 16] and r["coverage"]["resolution"] == [64, 64]
    assert resolve_recipe(r) == r and BAKER.resolve_recipe(r) == r
    nbytes, seconds = BAKER.estimate(r)
    assert nbytes > 64 * 64 * 16 * 9 * 4 and seconds > 0


# ----------------------------------------------------------------------------- bake, load, look up


def test_bake_load_and_lookup_at_the_nodes_returns_the_stored_values(physics, tmp_path):
    rep = registry.bake("hair_bsdf", SMALL, tmp_path / "t.h5")
    assert rep["kind"] == "hair_bsdf" and rep["total_units"] == 6 and rep["max_error"] > 0
    t = load(tmp_path / "t.h5")
    assert set(t.names) == {"A_f", "A_b", "alpha_f", "alpha_b", "beta_f", "beta_b", "R", "TT", "TRT", "residual", "coverage"}
    s, b, a = (t.axes[d] for d in ("sin_theta", "roughness", "absorption"))
    np.testing.assert_allclose(s, (np.arange(6) + 0.5) / 6)
    for name in ("A_f", "beta_b", "TRT"):
        got = t.sample(name, *np.meshgrid(s, b, a, indexing="ij"))
        np.testing.assert_array_equal(got, t.values[name].astype(np.float64))
        assert t.errors[name].min() >= 1e-8 / 12  # the stand-in's estimate at 12 nodes, plus the float32 rounding
    r, n = np.meshgrid(t.axes["radius"], t.axes["strands"], indexing="ij")
    np.testing.assert_array_equal(t.sample("coverage", r, n), t.values["coverage"].astype(np.float64))
    # between nodes: the GPU's linear filter (midway: the mean of the two taps), clamp-to-edge beyond the ends
    mid = t.sample("A_f", (s[1] + s[2]) / 2, b[0], a[0])
    assert mid == pytest.approx((float(t.values["A_f"][1, 0, 0]) + float(t.values["A_f"][2, 0, 0])) / 2, abs=1e-15)
    assert t.sample("A_f", -5.0, 2.0, a[3]) == t.values["A_f"][0, -1, 3]
    assert t.sample("A_f", 0.0, b[-1], 1.0) == t.values["A_f"][0, -1, -1]


def test_the_lookup_interpolates_like_a_gpu_sampler(physics, tmp_path):
    registry.bake("hair_bsdf", SMALL, tmp_path / "t.h5")
    t = load(tmp_path / "t.h5")
    rng = np.random.default_rng(0)
    x = rng.uniform(-0.2, 1.2, (3, 200))
    v = t.values["R"].astype(np.float64)
    # the same trilinear filter written out: texel position u·n − ½, taps clamped to the edge
    pos = [x[i] * v.shape[i] - 0.5 for i in range(3)]
    i0 = [np.floor(p).astype(int) for p in pos]
    f = [p - np.floor(p) for p in pos]
    want = 0.0
    for c in np.ndindex(2, 2, 2):
        idx = tuple(np.clip(i0[k] + c[k], 0, v.shape[k] - 1) for k in range(3))
        w = np.prod([f[k] if c[k] else 1 - f[k] for k in range(3)], axis=0)
        want = want + w * v[idx]
    np.testing.assert_allclose(t.sample("R", *x), want, rtol=0, atol=1e-15)
    coarse = t.sample("R", *x, subtexel_bits=8)  # hardware's 8 fractional bits move a sample by < 1/256 of a step
    assert 0 < np.abs(coarse - want).max() < np.abs(np.diff(v, axis=0)).max() / 256 + np.abs(np.diff(v, axis=1)).max()
    with pytest.raises(errors.ValidationError) as exc:
        t.sample("R", np.nan, 0.5, 0.5)
    assert exc.value.field == "sin_theta"


def test_a_hair_colour_is_looked_up_per_channel(physics, tmp_path):
    registry.bake("hair_bsdf", SMALL, tmp_path / "t.h5")
    t = load(tmp_path / "t.h5")
    brown = np.array([0.35, 0.2, 0.1])  # linear: on Unreal's perceptual axis at √C
    np.testing.assert_array_equal(t.absorption_of(colour=brown), np.sqrt(brown))
    rgb = t.sample_hair("A_b", 0.3, 0.4, colour=brown)
    assert rgb.shape == (3,) and np.all(np.diff(rgb) < 0)  # darker channels scatter less
    np.testing.assert_array_equal(rgb, [t.sample("A_b", 0.3, 0.4, c) for c in np.sqrt(brown)])
    assert t.sigma_a.shape == (5, 4)
    for kwargs, key in (
        ({"colour": [np.nan, 0.2, 0.1]}, "colour"),
        ({"colour": [0.0, 0.2, 0.1]}, "colour"),
        ({"sigma_a": [-1.0, 0.2, 0.1]}, "sigma_a"),
        ({"melanin": [-1.0, 0.0]}, "melanin"),
        ({"sigma_a": [1.0, 0.2, 0.1]}, "roughness"),  # onto the colour axis through β_n: needs the roughness
    ):
        with pytest.raises(errors.ValidationError) as exc:
            t.absorption_of(**kwargs)
        assert exc.value.field == key


def test_the_file_opens_in_xarray(physics, tmp_path):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    registry.bake("hair_bsdf", SMALL, tmp_path / "t.h5")
    with xr.open_dataset(tmp_path / "t.h5", engine="h5netcdf") as ds:
        assert ds["A_f"].dims == ("sin_theta", "roughness", "absorption") and ds["coverage"].dims == ("radius", "strands")
        np.testing.assert_array_equal(ds["A_f_error"].values, read_table(tmp_path / "t.h5")["A_f_error"])
        np.testing.assert_allclose(ds["roughness"].values, (np.arange(5) + 0.5) / 5)
        assert ds["sigma_a"].dims == ("roughness", "absorption")


TINY = {"grid": {"resolution": [3, 3, 2]}, "coverage": {"resolution": [2, 3]}}


def test_the_real_quadrature_through_the_kind(tmp_path, monkeypatch):
    """The kind's plumbing on hairlut.hairbsdf._integrals itself: fields land under their names (A_f + A_b is the
    sum of the lobes' energies), a split bake is bitwise the one-shot bake, and the lookup returns the nodes."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "0")
    one = registry.bake("hair_bsdf", TINY, tmp_path / "one.h5", options={"block": 3})
    split = registry.bake("hair_bsdf", TINY, tmp_path / "split.h5", options={"block": 1})
    assert _sha(one["out"]) == _sha(split["out"])
    t = load(one["out"])
    energy = sum(t.values[q].astype(np.float64) for q in ("R", "TT", "TRT", "residual"))
    both = t.values["A_f"].astype(np.float64) + t.values["A_b"]
    slack = sum(t.errors[q] for q in ("A_f", "A_b", "R", "TT", "TRT", "residual"))
    assert np.all(np.abs(both - energy) <= slack)
    assert np.all((t.values["coverage"] >= 0) & (t.values["coverage"] <= 1)) and t.sigma_a.shape == (3, 2)
    s, b, a = np.meshgrid(*(t.axes[d] for d in ("sin_theta", "roughness", "absorption")), indexing="ij")
    np.testing.assert_array_equal(t.sample("TT", s, b, a), t.values["TT"].astype(np.float64))
    np.testing.assert_allclose(t.absorption_of(sigma_a=t.sigma_a[1, 0], roughness=t.axes["roughness"][1]), a[0, 1, 0])


# ----------------------------------------------------------------------------- the EXR atlas


def test_the_atlas_layout_round_trips_through_inspect(physics, tmp_path):
    res = run("bake", "hair_bsdf", "--out", tmp_path / "t.h5", "--atlas", tmp_path / "t.exr", *_sets(SMALL))
    assert res.exit_code == 0, res.output
    assert f"wrote {tmp_path / 't.exr'}" in res.output
    doc = json.loads(run("inspect", "--json", tmp_path / "t.exr").stdout)
    assert doc["kind"] == "hair_bsdf_atlas" and doc["checksum"] == "verified"
    layout = json.loads(doc["attributes"]["hairlut:atlas"])
    ds = layout["tables"]["dual_scattering"]
    assert ds["tile"] == [6, 5] and ds["tiles"] == [2, 2] and ds["slice"]["count"] == 4
    assert [p["name"] for p in doc["parts"]] == ["dual_scattering", "mean_energy", "coverage"]
    assert doc["parts"][0]["shape"] == [2 * 5, 2 * 6]  # rows × columns: 2 × 2 tiles of 5 roughness × 6 sin θ
    text = run("inspect", tmp_path / "t.exr").output
    assert "hairlut:atlas" in text and "tiles" in text
    # the layout alone rebuilds the 3-D tables from the pixels
    t, atlas = load(tmp_path / "t.h5"), load(tmp_path / "t.exr")
    assert atlas.errors is None and set(atlas.names) == set(t.names)
    for name in t.names:
        np.testing.assert_array_equal(atlas.values[name], t.values[name].astype(np.float32))
    x = np.random.default_rng(1).uniform(0, 1, (3, 50))
    np.testing.assert_array_equal(atlas.sample("TT", *x), t.sample("TT", *x))
    write_atlas(tmp_path / "again.exr", t)
    assert load(tmp_path / "again.exr").values["A_f"].tobytes() == atlas.values["A_f"].tobytes()


def _sets(recipe: dict, prefix: str = "") -> list[str]:
    out = []
    for k, v in recipe.items():
        if isinstance(v, dict):
            out += _sets(v, f"{prefix}{k}.")
        else:
            out += ["--set", f"{prefix}{k}={json.dumps(v)}"]
    return out


# ----------------------------------------------------------------------------- split bakes


def test_bitwise_reproducible_and_equal_whole_or_split(physics, tmp_path):
    whole = registry.bake("hair_bsdf", SMALL, tmp_path / "whole.h5", options={"block": 6})
    again = registry.bake("hair_bsdf", SMALL, tmp_path / "again.h5", options={"block": 6})
    parts = registry.bake("hair_bsdf", SMALL, tmp_path / "parts.h5", options={"block": 1})
    assert _sha(whole["out"]) == _sha(again["out"]) == _sha(parts["out"])
    shards = [
        registry.bake("hair_bsdf", SMALL, tmp_path / f"s{k}.h5", shard=f"{k}/3", options={"block": 2})["out"] for k in range(3)
    ]
    assert [read_table(s).attrs["sin_theta_start"] for s in shards] == [0, 2, 4]
    merged = registry.merge(shards[::-1], tmp_path / "merged.h5")
    assert merged["units"] == 6 and _sha(merged["out"]) == _sha(whole["out"])
    virtual = registry.bake("hair_bsdf", SMALL, tmp_path / "v.h5", merge="virtual", options={"block": 4})
    tv, tw = load(virtual["out"]), load(whole["out"])
    for name in tw.names:
        assert tv.values[name].tobytes() == tw.values[name].tobytes()
        assert tv.errors[name].tobytes() == tw.errors[name].tobytes()
    assert tv.attrs["max_error"] == tw.attrs["max_error"]


def test_an_interrupted_bake_resumes_to_the_same_bytes(physics, tmp_path):
    class Stop(Exception):
        pass

    def die(done, total):
        if done >= 2:
            raise Stop

    with pytest.raises(Stop):
        registry.bake("hair_bsdf", SMALL, tmp_path / "t.h5", progress=die, options={"block": 2})
    assert not (tmp_path / "t.h5").exists() and (tmp_path / "t.h5.parts").is_dir()
    seen = []
    rep = registry.bake("hair_bsdf", SMALL, tmp_path / "t.h5", progress=lambda d, n: seen.append(d), options={"block": 2})
    assert rep["resumed"] == 2 and seen[0] == 2
    ref = registry.bake("hair_bsdf", SMALL, tmp_path / "ref.h5", options={"block": 3})
    assert _sha(rep["out"]) == _sha(ref["out"])


def test_coverage_alone_bakes_whole_and_refuses_the_split_options(physics, tmp_path):
    only = {"dual_scattering": {"bake": False}, "mean_energy": {"bake": False}, "coverage": {"resolution": [5, 4]}}
    rep = registry.bake("hair_bsdf", only, tmp_path / "c.h5")
    t = load(rep["out"])
    assert t.names == ["coverage"] and t.sigma_a is None and t.values["coverage"].shape == (5, 4)
    with pytest.raises(errors.ValidationError) as exc:
        registry.bake("hair_bsdf", only, tmp_path / "x.h5", shard="0/2")
    assert exc.value.field == "shard" and "sin θ rows" in exc.value.reason


def test_a_table_beyond_its_physical_bound_is_never_written(physics, tmp_path, monkeypatch):
    def too_bright(axes, resolution, **kw):
        out = _stand_in_tables(axes, resolution, **kw)
        if "dual_scattering" in out:
            v, e = out["dual_scattering"]
            out["dual_scattering"] = (v + np.eye(6)[0], e)  # A_f + 1
        return out

    from hairlut.hairbsdf import _bake

    monkeypatch.setattr(_bake, "_physics", lambda: types.SimpleNamespace(**{**vars(STAND_IN), "tables": too_bright}))
    with pytest.raises(errors.BoundsError, match="A_f.*0 ≤ A_f ≤ 1"):
        registry.bake("hair_bsdf", SMALL, tmp_path / "t.h5")
    assert not (tmp_path / "t.h5").exists()


# ----------------------------------------------------------------------------- the command line


def test_the_command_teaches():
    res = run("bake", "hair_bsdf", "--help")
    assert res.exit_code == 0
    for words in ("dual_scattering", "mean_energy", "coverage", "--atlas", "--block", "--shard", "Examples", "xarray"):
        assert words in res.output, words
    assert "hair_bsdf" in run("bake", "--help").output


def test_an_atlas_of_a_shard_is_refused(physics, tmp_path):
    res = run("bake", "hair_bsdf", "--out", tmp_path / "s.h5", "--shard", "0/2", "--atlas", tmp_path / "a.exr", *_sets(SMALL))
    assert res.exit_code == 2 and "atlas" in res.output and not (tmp_path / "a.exr").exists()


# ----------------------------------------------------------------------------- the bench part


def test_the_bench_part_compares_with_monte_carlo_and_draws_where_it_errs(physics, tmp_path):
    from hairlut.bench import PARTS, run_bench

    res = run_bench(tmp_path, registry=PARTS, only="hair_bsdf", quick=True)
    info = res["parts"]["hair_bsdf"]
    assert info["status"] == "ok", info
    labels = [f["label"] for f in res["figures"]]
    for k in (1, 4, 16):
        assert f"Unreal-style Monte Carlo, {k}× Unreal's counts" in labels
    assert "hairlut quadrature (converged)" in labels
    assert "hair_bsdf/where the Monte Carlo tables err most" in res["plots"]
    md = (tmp_path / "report.md").read_text()
    assert "### where the Monte Carlo tables err most" in md
    assert (tmp_path / res["plots"]["hair_bsdf/where the Monte Carlo tables err most"]).is_file()
    assert any("the whole bake" in n for n in info["notes"])


# ----------------------------------------------------------------------------- the planner


def _scene(tables=None):
    from tests._synth_fixtures import scene as base_scene

    s = base_scene()
    s["render"] = {**s.get("render", {}), "method": "direct"}  # no per-scene table to plan
    s["tables"] = dict(tables or {})
    return s


def test_the_planner_bakes_hair_bsdf_when_the_scene_asks_and_skips_it_otherwise(physics, tmp_path):
    from hairlut.planner import Plan, bake, find_assets, plan

    skipped = plan(_scene(), tmp_path).step("hair_bsdf")
    assert skipped.action == "skip" and "nothing reads it" in skipped.reason and "hair_bsdf = true" in skipped.reason
    p = plan(_scene({"hair_bsdf": {"grid": {"resolution": [6, 5, 4]}, "coverage": {"resolution": [4, 3]}}}), tmp_path)
    step = p.step("hair_bsdf")
    assert step.action == "bake" and step.kind == "hair_bsdf" and step.bytes > 0 and step.seconds > 0
    assert step.recipe == resolve_recipe(SMALL) and "[tables] hair_bsdf" in step.reason
    done = bake(Plan(p.scene, (step,), p.cache_dir))
    assert done["hair_bsdf"]["status"] == "baked"
    again = plan(_scene({"hair_bsdf": SMALL}), tmp_path).step("hair_bsdf")
    assert again.action == "reuse" and again.path == done["hair_bsdf"]["path"]
    assert "hair_bsdf" not in find_assets(_scene({"hair_bsdf": SMALL}), tmp_path)  # the online module does not read it
    assert plan(_scene({"hair_bsdf": True}), tmp_path).step("hair_bsdf").recipe == resolve_recipe({})
    with pytest.raises(errors.ValidationError) as exc:
        plan(_scene({"hair_bsdf": {"grid": {"roughness": [0.0, 2.0]}}}), tmp_path)
    assert exc.value.field == "tables.hair_bsdf.grid.roughness"
