"""The layered model's in-plane α on a straight cylinder against the strands (issue 13).

Measured on H2's straight cylinder (tests/test_render_oblique.py's notes: R 0.1, 600 uniform strands r 0.01 over
v ∈ [0.25, 1], κ 0.01, s_t 4, s_u 8, seen at ψ = 90°, 96², direct maps, oblique off), the pixel row through the
middle of the cluster, mean α over the hair's 26 pixels (through the axis in brackets) per stage:

| stage | smooth on (default) | smooth off |
|---|---|---|
| (a) strands' analytic α / (e) strand render L0 | 0.506 / 0.506 (0.632) | same |
| (b) sector densities' chord integral (= strands cut to the shells) | 0.475 (0.606) | same |
| (c) every sector's direct-map α at the chord, composited | 0.457 | 0.476 |
| (d) texels the renderer reads, composited over the layer hits, track | 0.423 (0.499) | 0.474 |
| (d) the same, pair reads | 0.375 | – |
| (e) the layered render, track | 0.408 | – |

(a)→(b), −6 %: the splats are exact (Σρ·area over a section is the strands' mass inside the shells), but the
strands' Gaussian tails beyond v = 1 and inside the core are cut (0.927 of the mass here).  (b)→(d), −11 %: the
direct maps' §5.1 smoothing (σ = 1.5 × the strand's, 16 of a row's 64 pixels in the inner track), normalised over
the infinite line, moves α past the row's ends and past the sector's own projection, where no read takes it back;
with smoothing off the track reads give the density's integral (0.474 against 0.475).  Full frame (layered /
reference mean α, track, oblique off): 0.715 before the crossing fix below, 0.807 after, 0.876 with smoothing off too.
On the vendored grooms smoothing barely matters (bias +6.81 → +7.26 % Sintel, −1.54 → −1.37 % Ratboy, 128², L0).

Along the cluster (t) the layered α faded over the last HSV row to 0.08 at the t = 0 end: no strand crossed the
t = 0 cross-section, whose plane holds every generated root (the crossing test was a strict sign change of the
ends' signed distances).  Tested here.
"""

from __future__ import annotations

import numpy as np

from hairlut.geometry import ClusterGeometry, ClusterSpec, build_sectors, generate_strands


def test_strands_rooted_on_the_end_planes_cross_every_cross_section():
    """Straight strands from the t = 0 plane to the t = 1 plane (generate_strands' roots and tips lie on them):
    each strand crosses every cross-section exactly once, the end ones included, at its own (x, y)."""
    spec = ClusterSpec(
        trajectory=[[0.0, -0.4, 0.0], [0.0, 0.0, 0.0], [0.0, 0.4, 0.0]], half_axis_a=0.1, half_axis_b=0.1, s_t=4, s_u=8
    )
    geom = ClusterGeometry(spec)
    strands, _ = generate_strands(geom, 120, radius=0.01, seed=3)
    tab = build_sectors(geom, strands, np.zeros(strands.n_strands, np.int64))
    t_index = tab.t_index[tab.crossing_sector]
    assert np.bincount(t_index, minlength=spec.s_t + 1).tolist() == [120] * (spec.s_t + 1)
    for i in range(spec.s_t + 1):
        assert sorted(tab.crossing_strand[t_index == i].tolist()) == list(range(120))
    xy = [tab.crossing_xy[t_index == i][np.argsort(tab.crossing_strand[t_index == i])] for i in (0, spec.s_t)]
    np.testing.assert_allclose(xy[0], xy[1], atol=1e-12)  # straight strands: the same point in every section


def _chord_integrals(tab, geom, spec, rho, section, offsets, z):
    """∫ρ dz of the sector densities (nearest cell) and of the strand Gaussians (peak 1, σ = r/√2) cut to the
    shells, along chords x = b (b in ``offsets``) of ``section``'s normal plane."""
    sec = geom.sections(np.array([section / spec.s_t]))
    a, b_, q = sec.a[0][0], sec.b[0][0], sec.twist[0][0]
    bounds, du = geom.track_bounds[0], 2 * np.pi / spec.s_u
    x, y = np.broadcast_arrays(offsets[:, None], z[None, :])
    v = np.hypot(x / a, y / b_)
    u = np.mod(np.arctan2(y / b_, x / a) - q, 2 * np.pi)
    inside = (v >= bounds[0]) & (v <= bounds[-1])
    g = np.clip(np.searchsorted(bounds, v, side="right") - 1, 0, len(bounds) - 2)
    k = np.minimum((u // du).astype(int), spec.s_u - 1)
    n_s, n_r = rho.shape[1:]
    ci = np.clip(((u - k * du) / du * n_s).astype(int), 0, n_s - 1)
    cj = np.clip(((v - bounds[g]) / (bounds[g + 1] - bounds[g]) * n_r).astype(int), 0, n_r - 1)
    dens = np.where(inside, rho[tab.sector_id(0, section, g, k), ci, cj], 0.0)
    m = tab.t_index[tab.crossing_sector] == section
    gauss = sum(
        np.exp(-((x - x0) ** 2 + (y - y0) ** 2) / r**2) for (x0, y0), r in zip(tab.crossing_xy[m], tab.crossing_radius[m])
    )
    dz = z[1] - z[0]
    return dens.sum(1) * dz, np.where(inside, gauss, 0.0).sum(1) * dz, gauss.sum(1) * dz


def test_sector_density_line_integrals_are_the_strands_cut_to_the_shells():
    """Stage (b) of the module docstring: along chords of a cross-section, the splatted sector densities integrate
    to the strand Gaussians' chord integrals cut to the shells (the splats conserve mass across sector borders; what
    lies beyond the outer layer or inside the core is lost, and only that)."""
    from hairlut.geometry import sector_density

    spec = ClusterSpec(
        trajectory=[[0.0, -0.4, 0.0], [0.0, 0.0, 0.0], [0.0, 0.4, 0.0]], half_axis_a=0.1, half_axis_b=0.1, s_t=2, s_u=8
    )
    geom = ClusterGeometry(spec)
    strands, _ = generate_strands(geom, 80, radius=0.01, seed=5)
    tab = build_sectors(geom, strands, np.zeros(strands.n_strands, np.int64))
    rho = sector_density(tab.splats(), (32, 32), dtype=np.float64)
    offsets = np.linspace(-0.095, 0.095, 20)
    dens, cut, whole = _chord_integrals(tab, geom, spec, rho, 1, offsets, np.linspace(-0.12, 0.12, 2401))
    assert abs(dens.sum() / cut.sum() - 1) < 5e-3
    assert np.abs(dens - cut).max() < 0.03 * cut.max()
    assert cut.sum() < 0.97 * whole.sum()  # the cut is a real loss (7 % of the mass on H2's 600-strand cylinder)
