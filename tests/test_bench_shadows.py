"""The shadows bench part's reference and the studies behind benchmarks/light_oriented.py and opacity_maps.py."""

from __future__ import annotations

import numpy as np
import pytest

from hairlut.bench import numpy_opacity_maps, strand_transmittance
from hairlut.geometry import Strands


def _two_strands():
    """Two long straight strands across the light (along x), one at depth 0 and one at depth 2 behind it."""
    x = np.linspace(-50.0, 50.0, 401)
    a = np.stack([x, np.zeros_like(x), np.zeros_like(x)], 1)
    b = a + [0.0, 0.0, -2.0]
    return Strands.from_padded(np.stack([a, b]))


def test_exclude_leaves_out_each_points_own_strand():
    """Points just in front of the far strand and between the strands: the near strand gives both
    Ω = 1/(√(2π) σ); leaving out the far strand (theirs) changes nothing; leaving out the near one gives T = 1."""
    strands, light, kappa, sigma = _two_strands(), np.array([0.0, 0.0, 1.0]), 0.3, 0.25
    pts = np.array([[0.0, 0.0, -1.999], [0.0, 0.0, -1.0]])  # on strand 1 (just in front); between the strands
    near = np.exp(-kappa / (np.sqrt(2 * np.pi) * sigma))
    np.testing.assert_allclose(strand_transmittance(strands, light, pts, kappa, sigma), [near, near], rtol=2e-3)
    np.testing.assert_allclose(
        strand_transmittance(strands, light, pts, kappa, sigma, exclude=np.array([1, 1])), [near, near], rtol=2e-3
    )
    np.testing.assert_allclose(
        strand_transmittance(strands, light, pts, kappa, sigma, exclude=np.array([0, 0])), [1.0, 1.0], atol=1e-12
    )


def test_numpy_table_6_1_matches_the_jitted_maps():
    """Kim's Table 6-1 in NumPy, on the jitted maps' layout, gives the same τ (the same discretisation,
    computed slice by slice instead of by one scatter-add and a cumulative sum)."""
    from hairlut.shadows import opacity_shadow_maps

    rng = np.random.default_rng(4)
    base = rng.uniform(-1, 1, (30, 1, 3))
    walk = np.cumsum(rng.normal(scale=0.15, size=(30, 12, 3)), axis=1)
    strands = Strands.from_padded(base + walk)
    light = np.array([0.2, 0.9, 0.4])
    for n_slices, res in ((4, 8), (16, 32)):
        m = opacity_shadow_maps(strands, light, n_slices=n_slices, resolution=res, kappa=0.4, width=1.0)
        got = numpy_opacity_maps(strands, m, 0.4)
        want = m.at(strands.points)
        assert want.min() < 0.9  # the groom shadows itself
        np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.parametrize("res", [32, 64])
def test_a_maps_footprint_is_half_its_cell(res):
    """The light-oriented map of cell ds matches the strand reference best near σ = ds/2 (box deposit ⊗
    trilinear lookup), not at σ = ds nor ds/4: the reason the part's reference is 1/256 of the extent."""
    from hairlut.bench._shadows import GROOM, KAPPA, LIGHT
    from hairlut.geometry import read_strands
    from hairlut.shadows import light_oriented_map

    strands = read_strands(GROOM)
    pts = np.asarray(strands.points)[::8]
    m = light_oriented_map(strands, LIGHT, resolution=res, kappa=KAPPA)
    t = m.at(pts)
    rms = {
        c: np.sqrt(np.mean((t - strand_transmittance(strands, LIGHT, pts, KAPPA, c * m.spacing)) ** 2)) for c in (0.25, 0.5, 1.0)
    }
    assert rms[0.5] < 0.8 * min(rms[0.25], rms[1.0]), rms


def test_footprint_study_finer_maps_rank_better_against_a_narrower_beam():
    """The check behind the part's footprint: against σ = extent/256 the 128-cell map beats the 64-cell one,
    against extent/128 the reverse; a point's own strand's share of τ doubles as σ halves, the others' holds."""
    from hairlut.bench import footprint_study

    d = footprint_study((128, 256), every=8)
    lo64, lo128 = d["maps"]["light-oriented map, 64 cells"]["rms"], d["maps"]["light-oriented map, 128 cells"]["rms"]
    assert lo64[0] < lo128[0] and lo128[1] < lo64[1], (lo64, lo128)
    assert 1.7 < d["tau_own"][1] / d["tau_own"][0] < 2.3, d["tau_own"]
    assert abs(d["tau_others"][1] / d["tau_others"][0] - 1) < 0.1, d["tau_others"]


def test_the_part_at_its_quick_size(tmp_path):
    """Two tables (the common footprint, each setting's own), one baseline each, the same settings in both; the
    paper's 128-cell map is the most accurate light-oriented row against the common footprint (1/256)."""
    from hairlut.bench import PARTS, run_bench
    from hairlut.bench._shadows import TABLE, TABLE_OWN

    res = run_bench(tmp_path, registry=PARTS, only=["shadows"], quick=True)
    assert res["parts"]["shadows"]["status"] == "ok", res["parts"]["shadows"]
    figs = res["figures"]
    by = {t: [f for f in figs if f["table"] == t] for t in (TABLE, TABLE_OWN)}
    for rows in by.values():
        assert sum(f["baseline"] for f in rows) == 1 and all(np.isfinite(f["error"]) for f in rows)
    assert {f["label"] for f in by[TABLE_OWN]} <= {f["label"] for f in by[TABLE]}
    lom = {
        f["knobs"]["cells"]: f["error"]
        for f in by[TABLE]
        if f["label"].startswith("light-oriented") and "storage" not in f["knobs"]
    }
    assert min(lom, key=lom.get) == 128, lom
