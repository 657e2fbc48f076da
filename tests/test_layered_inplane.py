"""The layered model's in-plane α on a straight cylinder against the strands (issue 13).

Measured on H2's straight cylinder (R 0.1, 600 uniform strands r 0.01 over v ∈ [0.25, 1], κ 0.01, seen at ψ = 90°,
96², direct maps, track reads; the pixel row through the middle of the cluster), the mean α over the hair's pixels
of each stage: the strands' analytic α 0.506 and the strand reference 0.506; the sector densities' own line
integral 0.475 (exactly the strand Gaussians cut to the shells: Σρ·area is 0.927 of the strands' π r² here, the
tails beyond v = 1 and inside the core are lost); the texels the renderer reads (track reads), composited over the
layer hits, 0.423, and the render 0.408.  Through the axis: 0.632 (strands), 0.606 (density), 0.499 (texels).

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
    spec = ClusterSpec(trajectory=[[0.0, -0.4, 0.0], [0.0, 0.0, 0.0], [0.0, 0.4, 0.0]], half_axis_a=0.1, half_axis_b=0.1,
                       s_t=4, s_u=8)
    geom = ClusterGeometry(spec)
    strands, _ = generate_strands(geom, 120, radius=0.01, seed=3)
    tab = build_sectors(geom, strands, np.zeros(strands.n_strands, np.int64))
    t_index = tab.t_index[tab.crossing_sector]
    assert np.bincount(t_index, minlength=spec.s_t + 1).tolist() == [120] * (spec.s_t + 1)
    for i in range(spec.s_t + 1):
        assert sorted(tab.crossing_strand[t_index == i].tolist()) == list(range(120))
    xy = [tab.crossing_xy[t_index == i][np.argsort(tab.crossing_strand[t_index == i])] for i in (0, spec.s_t)]
    np.testing.assert_allclose(xy[0], xy[1], atol=1e-12)  # straight strands: the same point in every section
