"""Part ``shadows``: the shadow methods against an exact strand-level transmittance.

Every method estimates T = exp(−κ Ω) toward a distant light at the strand vertices, Ω being the
hair length per unit area in front of the point (Beer–Lambert with κ the light-blocking width
of a fibre: bertails eqs 1–3, kim eqs 6-1, 6-2, xing §5).  The reference,
:func:`strand_transmittance`, needs no grid: every strand segment is cut into pieces of at
most half the footprint σ, and Ω(p) sums each piece nearer the light than p (its depth along
the light beyond p's) weighted by its length and a normalised 2-D Gaussian of σ in the plane
across the light, evaluated exactly per piece (a k-d tree keeps the pieces within 4σ).

The footprint σ is a choice, not a discretisation to refine: the part of Ω that a point's own
strand gives grows as 1/σ (a line of hair seen through a beam of width σ), so there is no
beam-free limit.  A grid method has a footprint too: a cell of edge ds deposits length into a
box (variance ds²/12) and is read trilinearly (a tent, variance ds²/6), so its footprint has
standard deviation ds/2.  The first table is against σ = 1/256 of the hair's extent across the
light, the footprint of the light-oriented map at the paper's 128 cells (bertails); the second
measures each setting against the reference at its own footprint, σ = half its cell, the error
of the method apart from the choice of footprint.

Methods: ``light_oriented_map`` (cells along the longest side; bertails uses 128),
``opacity_shadow_maps`` (slices × texels), the voxel SH transmittance (xing §5: T(ω) projected
on SH of order lmax at sample voxels every ``stride``, interpolated, evaluated toward the light;
the paper keeps 9 coefficients, lmax 2), and the straightforward baseline, a NumPy ray march
through a world-aligned density (``hairlut.shadows.ray_march``).  The s-map (satf eq 12) needs
a view's α-maps, not strand positions; it is measured with the maps and render parts.
"""

from __future__ import annotations

import time

import numpy as np

from ._figure import Figure
from ._parts import Context, example, timed

PART = "shadows"
TABLE = "transmittance at the strand vertices against the strand-level reference"
TABLE_OWN = "transmittance at the strand vertices against the strand-level reference at each setting's own footprint"
GROOM = example("grooms/sintel_lite.tfx")
LIGHT = np.array([0.3, 0.8, 0.5]) / np.linalg.norm([0.3, 0.8, 0.5])
KAPPA = 0.05
#: The reference's footprint σ is the hair's extent across the light over FOOTPRINT: half the cell of the
#: paper's 128-cell light-oriented map (a cell's box deposit and trilinear lookup have standard deviation ds/2).
FOOTPRINT = 256
#: The full sweep's light-oriented map cells and opacity-map (slices, texels).
LOM_CELLS = (16, 32, 64, 128, 256)
OSM_SETTINGS = ((8, 32), (16, 64), (32, 128), (64, 128), (64, 256))


def strand_transmittance(strands, light, points, kappa: float, sigma: float, *, exclude=None) -> np.ndarray:
    """T = exp(−κ Ω) at ``points`` from the strand segments themselves (see the module doc).

    ``exclude``: an optional strand index per point; that strand's segments are left out of the point's Ω
    (Ω of the other strands alone: the rest is the part a point's own strand gives)."""
    from scipy.spatial import cKDTree

    from hairlut.shadows import light_frame

    frame = light_frame(light)  # rows x, y, depth (depth = −light)
    seg = strands.segments
    pts = np.asarray(strands.points, np.float64)
    a, b = pts[seg[:, 0]], pts[seg[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    n = np.maximum(1, np.ceil(length / (0.5 * sigma))).astype(np.int64)
    rep = np.repeat(np.arange(len(seg)), n)
    k = np.arange(rep.size) - np.repeat(np.cumsum(n) - n, n)
    mid = a[rep] + ((k + 0.5) / n[rep])[:, None] * (b[rep] - a[rep])
    w = (length / n)[rep]
    owner = np.repeat(np.arange(strands.n_strands), np.asarray(strands.counts))[seg[rep, 0]] if exclude is not None else None
    q = mid @ frame.T
    p = np.asarray(points, np.float64) @ frame.T
    tree = cKDTree(q[:, :2])
    omega = np.zeros(len(p))
    norm = 1.0 / (2 * np.pi * sigma**2)
    for lo in range(0, len(p), 256):
        hi = min(lo + 256, len(p))
        for i, idx in zip(range(lo, hi), tree.query_ball_point(p[lo:hi, :2], 4 * sigma)):
            idx = np.asarray(idx, np.int64)
            idx = idx[q[idx, 2] < p[i, 2]]  # nearer the light: smaller depth
            if owner is not None:
                idx = idx[owner[idx] != exclude[i]]
            d2 = ((q[idx, :2] - p[i, :2]) ** 2).sum(1)
            omega[i] = norm * (w[idx] * np.exp(-0.5 * d2 / sigma**2)).sum()
    return np.exp(-kappa * omega)


def stored(m, dtype):
    """The light-oriented map ``m`` with its transmittance grid stored as ``dtype`` (and read back in float64)."""
    from hairlut.shadows import LightOrientedMap

    return LightOrientedMap(m.frame, m.origin, m.spacing, m.density, m.transmittance.astype(dtype).astype(np.float64), m.kappa)


def _voxel_sh(strands, pts, res, lmax, stride):
    from hairlut.sh import real_sh
    from hairlut.shadows import transmittance, voxelize

    vol = voxelize(strands, res)
    tr = transmittance(vol, KAPPA / vol.size**2, lmax=lmax, stride=stride)  # its ρ is length per voxel edge
    y = np.asarray(real_sh(lmax, LIGHT[None, :]), np.float64)[0]
    return tr.at(pts) @ y


def _err(t, ref):
    return float(np.sqrt(np.mean((t - ref) ** 2)))


def _beam_split(strands, pts, owner, span, divisors):
    """Mean τ = −ln T of the reference over the points, split into the points' own strands and the others."""
    out = []
    for d in divisors:
        total = -np.log(strand_transmittance(strands, LIGHT, pts, KAPPA, span / d))
        others = -np.log(strand_transmittance(strands, LIGHT, pts, KAPPA, span / d, exclude=owner))
        out.append(f"1/{d}: own {np.mean(total - others):.3f}, others {np.mean(others):.3f}")
    return "; ".join(out)


def run(ctx: Context) -> list[Figure]:
    from hairlut.geometry import read_strands
    from hairlut.shadows import light_frame, light_oriented_map, opacity_shadow_maps, ray_march, voxelize

    strands = read_strands(GROOM)
    every = 8 if ctx.quick else 2
    pts = np.asarray(strands.points, np.float64)[::every]
    owner = np.repeat(np.arange(strands.n_strands), np.asarray(strands.counts))[::every]
    span = np.ptp(np.asarray(strands.points, np.float64) @ light_frame(LIGHT).T, axis=0).max()
    sigma = span / FOOTPRINT
    t0 = time.perf_counter()
    ref = strand_transmittance(strands, LIGHT, pts, KAPPA, sigma)
    ref_s = time.perf_counter() - t0
    own_refs: dict[float, np.ndarray] = {}
    figs, name = [], "RMS |ΔT|"

    def add(label, sec, t, knobs, cell, **kw):
        """The setting's row in both tables: against the common footprint and against its own (σ = cell / 2)."""
        if cell not in own_refs:
            own_refs[cell] = strand_transmittance(strands, LIGHT, pts, KAPPA, cell / 2)
        extra = {**kw.pop("extra", {}), "cell": cell}
        figs.append(Figure(PART, TABLE, label, sec, _err(t, ref), name, knobs, extra=extra, **kw))
        figs.append(Figure(PART, TABLE_OWN, label, sec, _err(t, own_refs[cell]), name, knobs, extra=extra, **kw))

    base_res = 32 if ctx.quick else 64
    for res in (base_res,) if ctx.quick else (32, 64):
        sec, t = timed(lambda: ray_march(pts, LIGHT, KAPPA, strands, res), repeat=1 if ctx.quick else 2)
        add(f"NumPy ray march, {res} cells", sec, t, {"cells": res}, voxelize(strands, res).size, baseline=res == base_res)
    for res in (32, 64, 128) if ctx.quick else LOM_CELLS:
        light_oriented_map(strands, LIGHT, resolution=res, kappa=KAPPA).at(pts)  # compile
        sec, t = timed(lambda: light_oriented_map(strands, LIGHT, resolution=res, kappa=KAPPA).at(pts), repeat=3)
        m = light_oriented_map(strands, LIGHT, resolution=res, kappa=KAPPA)
        add(f"light-oriented map, {res} cells", sec, t, {"cells": res}, m.spacing, paper=res == 128)
        if res == 128:
            figs.append(
                Figure(
                    PART,
                    TABLE,
                    "light-oriented map, 128 cells, stored as float16",
                    None,
                    _err(stored(m, np.float16).at(pts), ref),
                    name,
                    {"cells": res, "storage": "float16"},
                )
            )
    for slices, res in OSM_SETTINGS[:2] if ctx.quick else OSM_SETTINGS:
        opacity_shadow_maps(strands, LIGHT, n_slices=slices, resolution=res, kappa=KAPPA, width=1.0).at(pts)
        sec, t = timed(
            lambda: opacity_shadow_maps(strands, LIGHT, n_slices=slices, resolution=res, kappa=KAPPA, width=1.0).at(pts), repeat=3
        )
        m = opacity_shadow_maps(strands, LIGHT, n_slices=slices, resolution=res, kappa=KAPPA, width=1.0)
        add(f"opacity maps, {slices} slices × {res}", sec, t, {"slices": slices, "texels": res}, m.spacing)
    voxel = [(16, 2, 2)] if ctx.quick else [(16, 2, 2), (32, 2, 2), (32, 4, 2), (32, 2, 4), (64, 2, 4)]
    for res, lmax, stride in voxel:
        _voxel_sh(strands, pts, res, lmax, stride)
        sec, t = timed(lambda: _voxel_sh(strands, pts, res, lmax, stride), repeat=1 if ctx.quick else 2)
        add(
            f"voxel SH, {res} cells, lmax {lmax}, stride {stride}",
            sec,
            t,
            {"cells": res, "lmax": lmax, "stride": stride},
            voxelize(strands, res).size,
            paper=lmax == 2,
            extra={"min_T": float(t.min()), "max_T": float(t.max())},
        )
    ctx.note(
        PART,
        f"{GROOM.name}: {len(pts)} vertices, light {np.round(LIGHT, 3).tolist()}, κ = {KAPPA}; reference: "
        f"strand-level Ω with footprint σ = {sigma:.3g} (1/{FOOTPRINT} of the hair's extent across the light: "
        f"the footprint, ds/2, of the paper's 128-cell light-oriented map), {ref_s:.1f} s; reference T: "
        f"mean {ref.mean():.3f}, min {ref.min():.3f}",
    )
    ctx.note(
        PART,
        "the footprint is a choice, with no beam-free limit: mean τ = −ln T of the reference from the "
        "points' own strands and from the others, σ = extent × "
        + _beam_split(strands, pts, owner, span, (128, 256) if ctx.quick else (128, 256, 512))
        + " (a strand's own part doubles as σ halves); a grid of cell ds has footprint ds/2 (box deposit ⊗ "
        "trilinear lookup), so finer grids resolve more of it and come out darker than a wider beam",
    )
    ctx.note(
        PART,
        "second table: each setting against the reference at its own footprint (σ = half its cell, world "
        "voxels for the ray march and voxel SH): the method's error apart from the choice of footprint",
    )
    ctx.note(PART, "the s-map (satf eq 12) works on a view's α-maps, not on strand positions: see the maps part")
    return figs
