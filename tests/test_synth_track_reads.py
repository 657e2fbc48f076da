"""``[render] layer_reads = "track"`` (``hairlut.synth._view.sweep_track``) against eq 7's pair read on an
idealised cross-section: a uniform disc (or annulus) cut into tracks and s_u phase sectors, every sector's α row
its own exact projection (the chord length of each pixel's line inside the sector, sampled finely here, not with
the package's geometry).  A camera ray crosses the layer surfaces; the optical depths its fragments read must add
up to the analytic chord through the disc, ρ · 2(√(1 − b²) − √(c² − b²)), each piece counted once.
"""

import functools
from types import SimpleNamespace

import numpy as np
import pytest

from hairlut import errors
from hairlut.scene import resolve_scene
from hairlut.synth import SectorFrames, geometry_index, sweep_sectors

from ._synth_fixtures import scene as base_scene

RADII = (0.5, 0.75, 1.0)
RHO = 0.9  # optical depth per unit path
P = 256  # pixels per sector row
EXTENT = 2.0  # every sector's image half-width (the disc fits)


def _disc(s_u, core=0.0, n_u=1024, reads="track"):
    """The index, per-sector α rows (S, P) and (cos θv, sin θv) (S, 2) of a one-cluster disc seen along +y."""
    fr, table, alpha, cs = _disc_rows(s_u, core)
    return geometry_index(table, fr, len(RADII), (n_u, 2), reads), alpha, cs


@functools.cache
def _disc_rows(s_u, core):
    """The disc's sector frames, table layout, α rows and view per sector (:func:`_disc`), made once per
    (s_u, core): the pair and track reads of a test read the same rows."""
    bounds = np.array((core,) + RADII)
    G, n_i = len(RADII), 2  # s_t = 1: two equal cross-sections
    du = 2 * np.pi / s_u
    i, g, k = (a.ravel() for a in np.meshgrid(np.arange(n_i), np.arange(G), np.arange(s_u), indexing="ij"))
    S = i.size
    v0, v1 = bounds[g], bounds[g + 1]
    phi = (k + 0.5) * du
    vm = 0.5 * (v0 + v1)
    centre = np.stack([vm * np.cos(phi), vm * np.sin(phi)], 1)
    ex = np.stack([np.cos(phi), np.sin(phi)], 1)
    ey = np.stack([-ex[:, 1], ex[:, 0]], 1)
    fr = SectorFrames(
        np.zeros((S, 1)),
        centre,
        ex,
        ey,
        np.full(S, EXTENT),
        np.ones((S, 2)),
        np.zeros(S),
        v1,
        np.tile([1.0, 0, 0], (S, 1)),
        np.tile([0, 1.0, 0], (S, 1)),
        np.ones(S, bool),
        v0,
    )
    top = (np.arange(G)[:, None] * s_u + np.arange(s_u)).ravel()
    table = SimpleNamespace(shape=(1, n_i, G, s_u), hsv_sectors=np.stack([top, top + G * s_u], 1))
    view = np.array([0.0, 1.0])  # toward the eye, in the normal plane
    cs = np.stack([ex @ view, ey @ view], 1)
    e = np.array([-view[1], view[0]])
    x = ((np.arange(P) + 0.5) * 2 / P - 1) * EXTENT
    t = np.linspace(-1.0, 1.0, 8001)
    dt = t[1] - t[0]
    alpha = np.empty((S, P))
    for s in range(G * s_u):  # each pixel's line through the sector, sampled along its length (cross-section 0)
        b = centre[s] @ e + x  # the line's offset from the disc centre
        px, py = b[:, None] * e[0] + t * view[0], b[:, None] * e[1] + t * view[1]
        r, ph = np.hypot(px, py), np.mod(np.arctan2(py, px), 2 * np.pi)
        inside = (r >= v0[s]) & (r < v1[s]) & (np.minimum((ph // du).astype(int), s_u - 1) == k[s])
        alpha[s] = 1 - np.exp(-RHO * inside.sum(1) * dt)
    alpha[G * s_u :] = alpha[: G * s_u]  # cross-section 1 is the same
    return fr, table, alpha.astype(np.float32), cs.astype(np.float32)


def _depth(ix, alpha, cs):
    """Each texel's optical depth −ln(1 − α) (K, n_u) from the maps (cross-section row 0)."""
    _, a = sweep_sectors(ix, alpha, alpha[:, None], cs)
    return -np.log1p(-np.minimum(np.asarray(a, np.float64)[0, :, 0], 1 - 1e-7))


def _ray_total(tau, b):
    """The optical depth a vertical ray x = b reads from every layer surface it crosses (front and back hit,
    the texture interpolated linearly in u)."""
    n_u = tau.shape[1]
    u = 2 * np.pi * (np.arange(n_u) + 0.5) / n_u
    total = 0.0
    for k, v in enumerate(RADII):
        if abs(b) < v:
            phi = np.arccos(b / v)
            for p in (phi, 2 * np.pi - phi):
                total += np.interp(p, u, tau[k], period=2 * np.pi)
    return total


def _truth(b, core):
    return RHO * 2 * (np.sqrt(1 - b * b) - np.sqrt(max(core * core - b * b, 0.0)))


RAYS = np.array([-0.93, -0.62, -0.31, -0.07, 0.12, 0.41, 0.58, 0.86])


@pytest.mark.parametrize("s_u,core", [(8, 0.0), (16, 0.0), (8, 0.25), (5, 0.0)])
def test_track_read_sums_to_the_chord_depth(s_u, core):
    """Eq 7 with the track read: the fragments of a ray through the disc read its whole chord, once."""
    ix, alpha, cs = _disc(s_u, core)
    got = np.array([_ray_total(_depth(ix, alpha, cs), b) for b in RAYS])
    truth = np.array([_truth(b, core) for b in RAYS])
    np.testing.assert_allclose(got, truth, rtol=0.02, atol=0.01)
    ixp, _, _ = _disc(s_u, core, reads="pair")
    pair = np.array([_ray_total(_depth(ixp, alpha, cs), b) for b in RAYS])
    assert np.abs(pair / truth - 1).max() > 0.1  # eq 7's two sectors per surface miss or double what the ray crosses


def test_track_read_at_one_sector_halves_the_pair_read():
    """With s_u = 1 a track is one sector: each of a chord's two fragments reads it with half its depth."""
    ix, alpha, cs = _disc(1, n_u=64)
    ixp, _, _ = _disc(1, n_u=64, reads="pair")
    track, pair = _depth(ix, alpha, cs), _depth(ixp, alpha, cs)
    assert pair.max() > 0.5
    np.testing.assert_allclose(track, 0.5 * pair, rtol=1e-4, atol=1e-5)


def test_track_read_reflectance_composites_front_to_back():
    """re (α-premultiplied) of the crossed sectors composited along the ray, each share scaled with its weight:
    with every sector's re = α the composite Σ α'_m Π_{before}(1 − α') is the fragment's α."""
    ix, alpha, cs = _disc(8)
    re, a = (np.asarray(x) for x in sweep_sectors(ix, alpha, alpha[:, None], cs))
    np.testing.assert_allclose(re[:, :, 0], a, atol=2e-6)


def test_layer_reads_is_validated_by_name():
    s = base_scene()
    s["render"] = {**s["render"], "layer_reads": "all"}
    with pytest.raises(errors.ValidationError, match="render.layer_reads"):
        resolve_scene(s)
    with pytest.raises(errors.ValidationError, match="render.layer_reads"):
        _disc(4, reads="both")


def test_satf_track_read_sweeps_every_sectors_own_fetch():
    """The ``satf`` path with the track read (every HSV fetched as non-uniform) gives the maps of every sector's own
    row fetched by the reference k-NN lookup (``_maps.fetch``) swept by ``sweep_sectors``."""
    from hairlut.synth import params_kernel, prepare
    from hairlut.synth._maps import fetch, sector_angles
    from hairlut.synth._view import view_maps

    from ._synth_fixtures import synthetic_db

    db = synthetic_db()
    given = base_scene()
    given["render"] = {**given["render"], "method": "satf", "layer_reads": "track"}
    prep = prepare(given, db)
    sc, ix = prep.scene, prep.index
    re, alpha, uniform = view_maps(ix, db, sc.view, sc.lights, sc.material["k_threshold"])
    assert ix.reads == "track" and not uniform.any()
    sp = sector_angles(prep.frames, sc.view, sc.lights)
    r_ref, a_ref = fetch(db, sp.features, sp.theta_v, sp.theta_l, sc.config["render"]["neighbours"])
    occ = np.asarray(prep.frames.occupied, bool)
    f32 = np.float32
    cs = params_kernel(ix, sc.view.astype(f32), sc.lights.astype(f32), f32(0.0), n_v=1, n_l=1)[2]
    re_ref, alpha_ref = sweep_sectors(ix, a_ref * occ[:, None], r_ref * occ[:, None, None], cs)
    np.testing.assert_allclose(np.asarray(alpha), np.asarray(alpha_ref), atol=2e-5)
    np.testing.assert_allclose(np.asarray(re), np.asarray(re_ref), atol=2e-5)
    assert np.asarray(alpha).max() > 0.1
