"""Hair Shell Volumes and generalized sectors, and the strands that cross them (satf §3.2, §6.2.1).

The cross-sections at t_i = i/s_t (i = 0 … s_t, eq 3) are cut into tracks (the radial
ranges of ``ClusterSpec.track_bounds``: each shell in s_v steps) and into s_u phase
ranges [2πk/s_u, 2π(k+1)/s_u).  A *sector* is one (cluster c, cross-section i, track g,
phase k) cell of a cross-section; sector ids run ((c·(s_t+1) + i)·G + g)·s_u + k with
G = L·s_v tracks.  An HSV (c, i < s_t, g, k) lies between its two boundary sectors,
(c, i, g, k) on top and (c, i+1, g, k) below, so neighbouring HSVs share a sector.

Crossings: each strand assigned to cluster c is intersected, segment by segment, with
the normal plane at T(t_i); of the crossing points inside the shells (core ≤ v ≤ outer
layer) the one nearest T(t_i) is kept.  A strand that crosses the plane only beyond the outer layer (an outlier that
the fit's ellipse, sized to hold 95 % of the crossings, leaves out: :func:`hairlut.geometry.fit_clusters`) is kept
too, pulled in along its own phase to the middle of the outermost track (:data:`RIM`), so that every strand's hair
is counted once.  Dropped, the outliers' α was lost: the long grooms' layered α was 2–6 % below the strand render's
(Sintel from the back −3.7 %, the parted groom −4.5 % and −6.1 %); pulled in, −0.5 %, −2.2 % and −2.3 %, and the mean
|bias| over the picture benchmark's 15 scenes went from 2.8 % to 2.2 % (benchmarks/records.md, 2026-12-05).

Of each kept crossing, its sector, its parametric (s, r) in that sector (s along the phase, r along the radius,
both in [0, 1]), its metric (x, y) in the normal plane (x along the frame reference r, y along the binormal; eq 1
has x = A v cos(q + u), y = B v sin(q + u)) and its 3-D point (an outlier's own, where the strand is) are recorded.

Its radius is the strand's widened for its tilt: a strand at angle γ to the plane's normal is
cut in an ellipse of area π r² / cos γ, and it holds that much hair per unit length of the
cluster, so its splat is the disc of that area, r / √cos γ (1/cos γ, ``crossing_stretch``, capped at
``MAX_TILT_STRETCH``).  The extinction σ_t = κ / r of the planar trace keeps the strand's own r
(``sector_radius``): the optical depth of cylinders is their length per volume times 2r, so the
density's 1/cos γ is the whole correction.  The paper's splat takes r alone, as if every strand ran along its
cluster; curls and waves then lost their extra length: the curly groom's layered α was 13.2 %
below the strand render's with r alone and 2.3 % below with the tilt (Sintel: 6.6 % and 4.1 %;
128², scene maps, defaults, one texel of trim; benchmarks/records.md, hairlut bench --only picture).

Splats: a crossing's Gaussian (see ``splats``) may reach into neighbouring sectors of
the same cross-section; it is entered, in each sector's own (s, r) units, into every
sector within ``halo`` standard deviations, so mass is conserved across sector borders
(up to the tail beyond ``halo``·σ) and only what falls outside the shells is lost.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ValidationError
from ..validate import check_real
from .splats import SIGMA_PER_RADIUS, SplatBatch, pack, param_sigma
from .strandgen import assign_strands
from .strands import Strands
from .sweep import ClusterGeometry

#: The most a crossing's cut is widened for its tilt (1 / cos γ, γ ≤ 75.5°): a strand lying in the plane is a
#: stripe, not a disc, and its cut would grow without bound.
MAX_TILT_STRETCH = 4.0
#: Where an outlier's crossing (beyond the outer layer) is kept, as a fraction of the way from the outermost track's
#: inner bound to the outer layer: its middle, so its splat stays mostly inside the shells (module docstring).
RIM = 0.5


@dataclass(frozen=True, eq=False)
class SectorTable:
    """Sectors (N), strand crossings (X) and splats (J) of a cluster batch; see the module docstring.

    Per sector: ``cluster``, ``t_index``, ``track``, ``layer``, ``u_index`` (int), ``t``,
    ``v_range`` (N, 2), ``u_range`` (N, 2), ``half_axes`` (N, 2) = (A, B) at t,
    ``twist`` (N,), ``corners`` (N, 4, 3) = P at (v0,u0), (v1,u0), (v1,u1), (v0,u1).
    Per crossing: ``crossing_strand``, ``crossing_sector``, ``crossing_sr``, ``crossing_xy``,
    ``crossing_vu``, ``crossing_point``, ``crossing_radius`` (the strand's) and ``crossing_stretch`` (1 / cos γ of its
    tilt, capped: module docstring).  Per splat, grouped by
    sector through ``splat_offsets`` (N + 1): ``splat_crossing``, ``splat_center`` and
    ``splat_sigma`` in the sector's (s, r) units.  ``hsv_sectors`` (H, 2): top and
    bottom sector of each HSV.
    """

    shape: tuple[int, int, int, int]  # (C, s_t + 1, G, s_u)
    s_v: int
    cluster: np.ndarray
    t_index: np.ndarray
    track: np.ndarray
    layer: np.ndarray
    u_index: np.ndarray
    t: np.ndarray
    v_range: np.ndarray
    u_range: np.ndarray
    half_axes: np.ndarray
    twist: np.ndarray
    corners: np.ndarray
    crossing_strand: np.ndarray
    crossing_sector: np.ndarray
    crossing_sr: np.ndarray
    crossing_xy: np.ndarray
    crossing_vu: np.ndarray
    crossing_point: np.ndarray
    crossing_radius: np.ndarray
    crossing_stretch: np.ndarray
    splat_offsets: np.ndarray
    splat_crossing: np.ndarray
    splat_center: np.ndarray
    splat_sigma: np.ndarray
    hsv_sectors: np.ndarray

    @property
    def n_sectors(self) -> int:
        return int(np.prod(self.shape))

    @property
    def n_hsvs(self) -> int:
        return len(self.hsv_sectors)

    def sector_id(self, cluster, t_index, track, u_index) -> np.ndarray:
        """The flat sector index of (cluster, segment along t, track, sector along u), as in the table's arrays."""
        _, n_i, n_g, n_k = self.shape
        return ((np.asarray(cluster) * n_i + t_index) * n_g + track) * n_k + u_index

    def crossings_of(self, sector: int) -> np.ndarray:
        """Indices (into the crossing arrays) of the strands that cross ``sector``."""
        return np.flatnonzero(self.crossing_sector == sector)

    def splat_radius(self) -> np.ndarray:
        """(J,) the radius of each splat's disc: its strand's radius widened to the area of the strand's oblique cut,
        r·√stretch (module docstring), so the splat holds the hair the strand puts in the plane."""
        c = self.splat_crossing
        return self.crossing_radius[c] * np.sqrt(self.crossing_stretch[c])

    def sector_radius(self, fill=None) -> np.ndarray:
        """(N,) the mean strand radius (unwidened: the one extinction σ_t = κ / r needs) of the splats that reach each
        sector; ``fill`` (a number or (N,); default: the median crossing radius) where none does."""
        n = self.n_sectors
        sector = np.repeat(np.arange(n), np.diff(self.splat_offsets))
        count = np.bincount(sector, minlength=n)
        total = np.bincount(sector, weights=self.crossing_radius[self.splat_crossing], minlength=n)
        if fill is None:
            fill = float(np.median(self.crossing_radius)) if self.crossing_radius.size else 1.0
        return np.where(count > 0, total / np.maximum(count, 1), fill)

    def splats(self, sectors=None, *, max_splats: int | None = None) -> SplatBatch:
        """Padded splats of ``sectors`` (default: all, in id order) for the density kernel."""
        ids = np.arange(self.n_sectors) if sectors is None else np.asarray(sectors, dtype=np.int64).ravel()
        counts = np.diff(self.splat_offsets)[ids]
        rows = np.repeat(np.arange(ids.size), counts)
        starts = np.repeat(self.splat_offsets[ids], counts)
        j = starts + np.arange(rows.size) - np.repeat(np.cumsum(counts) - counts, counts)
        du = self.u_range[ids, 1] - self.u_range[ids, 0]
        return pack(
            rows,
            self.splat_center[j],
            self.splat_sigma[j],
            self.splat_radius()[j],
            ids.size,
            self.half_axes[ids, 0] * self.half_axes[ids, 1] * du,
            self.v_range[ids],
            max_splats,
        )


def _strand_radii(strands: Strands, radius) -> np.ndarray:
    if radius is not None:
        return np.full(strands.n_points, check_real(radius, "radius", 0, lo_open=True))
    if strands.thickness is None:
        raise ValidationError("radius", None, "the strands carry no thickness: give a strand radius")
    return strands.thickness.astype(np.float64) / 2.0  # thickness is a diameter (.hair convention)


def _crossings(geom: ClusterGeometry, strands: Strands, assignment: np.ndarray, radii: np.ndarray, sec) -> dict:
    """Nearest in-shell crossing of every (cluster, cross-section, strand), or, for a strand with none, its nearest
    crossing beyond the outer layer pulled in to the rim (module docstring)."""
    pts = strands.points.astype(np.float64)
    seg = strands.segments
    seg_strand = np.repeat(np.arange(strands.n_strands), strands.counts - 1)
    out = []
    for c in range(geom.n_clusters):
        e = np.flatnonzero(assignment[seg_strand] == c)
        if not e.size:
            continue
        a, b = pts[seg[e, 0]], pts[seg[e, 1]]
        o, n = sec.origin[c], sec.tangent[c]  # (I, 3)
        da = np.einsum("ik,ek->ie", n, a) - np.sum(n * o, axis=1)[:, None]
        db = np.einsum("ik,ek->ie", n, b) - np.sum(n * o, axis=1)[:, None]
        # a segment crosses the plane where its ends' signed distances differ in sign or one is 0 (a strand's first
        # or last point exactly on t = 0 or 1, as generated roots are: `(da < 0) != (db < 0)` lost every root on
        # the t = 0 plane); an in-plane segment (da = db = 0) has no single crossing; a vertex on the plane found by
        # both its segments is one point, kept once below (nearest crossing per strand)
        ii, ee = np.nonzero((np.minimum(da, db) <= 0) & (np.maximum(da, db) >= 0) & (da != db))
        lam = da[ii, ee] / (da[ii, ee] - db[ii, ee])
        p = a[ee] + lam[:, None] * (b[ee] - a[ee])
        rel = p - o[ii]
        x = np.sum(rel * sec.normal[c][ii], axis=1)
        y = np.sum(rel * sec.binormal[c][ii], axis=1)
        big_a, big_b, q = sec.a[c][ii], sec.b[c][ii], sec.twist[c][ii]
        v = np.hypot(x / big_a, y / big_b)
        bounds = geom.track_bounds[c]
        inside = v <= bounds[-1]
        strand = seg_strand[e[ee]]
        dist = np.linalg.norm(rel, axis=1)
        keep = np.flatnonzero(v >= bounds[0])  # not in the core; in the shells first, then the nearest outlier
        keep = keep[np.lexsort((dist[keep], ~inside[keep], strand[keep], ii[keep]))]
        first = np.ones(keep.size, dtype=bool)
        first[1:] = (ii[keep][1:] != ii[keep][:-1]) | (strand[keep][1:] != strand[keep][:-1])
        k = keep[first]
        ra, rb = radii[seg[e[ee[k]], 0]], radii[seg[e[ee[k]], 1]]
        # the strand's cut by the normal plane is an ellipse of area π r² / cos γ (γ: its tilt from the plane's
        # normal); its splat is the disc of that area, so a tilted strand (a curl, a wave) keeps its hair per unit
        # trajectory length, capped at MAX_TILT_STRETCH where the strand nearly lies in the plane
        seg_len = np.linalg.norm(b[ee[k]] - a[ee[k]], axis=1)
        cos_tilt = np.abs(da[ii[k], ee[k]] - db[ii[k], ee[k]]) / np.maximum(seg_len, 1e-300)
        stretch = 1.0 / np.maximum(cos_tilt, 1.0 / MAX_TILT_STRETCH)
        phi = np.arctan2(y[k] / big_b[k], x[k] / big_a[k])
        rim = bounds[-2] + RIM * (bounds[-1] - bounds[-2])
        pull = np.where(inside[k], 1.0, rim / np.maximum(v[k], 1e-300))  # an outlier to the rim, at its own phase
        x, y, v = x[k] * pull, y[k] * pull, v[k] * pull
        out.append(
            {
                "cluster": np.full(k.size, c),
                "t_index": ii[k],
                "strand": strand[k],
                "x": x,
                "y": y,
                "v": v,
                "phi": phi,
                "u": np.mod(phi - q[k], 2 * np.pi),
                "point": p[k],
                "radius": ra + lam[k] * (rb - ra),
                "stretch": stretch,
                "a": big_a[k],
                "b": big_b[k],
            }
        )
    keys = ("cluster", "t_index", "strand", "x", "y", "v", "phi", "u", "point", "radius", "stretch", "a", "b")
    if not out:
        return {
            k: np.zeros((0, 3) if k == "point" else 0, dtype=np.int64 if k in ("cluster", "t_index", "strand") else float)
            for k in keys
        }
    return {k: np.concatenate([d[k] for d in out]) for k in keys}


def _track_of(bounds: np.ndarray, cluster: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Track index of radius v in each item's cluster (clipped to the shells), vectorised."""
    n_c, n_b = bounds.shape
    shift = 4.0 * np.arange(n_c)
    flat = (bounds + shift[:, None]).ravel()
    pos = np.searchsorted(flat, np.clip(v, -1.0, 2.0) + shift[cluster], side="right") - 1 - cluster * n_b
    return np.clip(pos, 0, n_b - 2).astype(np.int64)


def build_sectors(
    geometry: ClusterGeometry,
    strands: Strands,
    assignment=None,
    *,
    radius: float | None = None,
    sigma_per_radius: float = SIGMA_PER_RADIUS,
    halo: float = 5.0,
) -> SectorTable:
    """Sectors, HSVs, crossings and splats of ``strands`` in ``geometry`` (float64 NumPy).

    ``assignment`` (S,) gives each strand's cluster (−1: none); by default
    :func:`hairlut.geometry.strandgen.assign_strands`.  ``radius`` overrides the strand
    radius; without it the strands' ``thickness`` (a diameter) is used.
    """
    if not isinstance(strands, Strands):
        raise ValidationError("strands", type(strands).__name__, "must be a hairlut.geometry.Strands")
    if not (np.isfinite(halo) and halo > 0):
        raise ValidationError("halo", halo, "must be > 0 (in standard deviations)")
    if not (np.isfinite(sigma_per_radius) and sigma_per_radius > 0):
        raise ValidationError("sigma_per_radius", sigma_per_radius, "must be > 0")
    assign = assign_strands(strands, geometry) if assignment is None else np.asarray(assignment)
    if assign.shape != (strands.n_strands,) or assign.dtype.kind not in "iu":
        raise ValidationError("assignment", getattr(assign, "shape", assign), f"need ({strands.n_strands},) cluster indices")
    radii = _strand_radii(strands, radius)
    s_t, s_v, s_u = geometry.sampling
    n_c, n_i, n_g = geometry.n_clusters, s_t + 1, geometry.track_bounds.shape[1] - 1
    du = 2 * np.pi / s_u
    sec = geometry.sections(np.linspace(0.0, 1.0, n_i))

    cl, ti, tr, uk = (
        a.ravel() for a in np.meshgrid(np.arange(n_c), np.arange(n_i), np.arange(n_g), np.arange(s_u), indexing="ij")
    )
    bounds = geometry.track_bounds
    v_range = np.stack([bounds[cl, tr], bounds[cl, tr + 1]], axis=1)
    u_range = np.stack([uk * du, (uk + 1) * du], axis=1)
    t = ti / s_t
    cv = np.stack([v_range[:, 0], v_range[:, 1], v_range[:, 1], v_range[:, 0]], axis=1)
    cu = np.stack([u_range[:, 0], u_range[:, 0], u_range[:, 1], u_range[:, 1]], axis=1)
    corners = sec.take(cl, ti).take(slice(None), None).point(cv, cu)

    x = _crossings(geometry, strands, assign, radii, sec)
    g = _track_of(bounds, x["cluster"], x["v"])
    k = np.minimum((x["u"] // du).astype(np.int64), s_u - 1)
    lo, hi = bounds[x["cluster"], g], bounds[x["cluster"], g + 1]
    sid = ((x["cluster"] * n_i + x["t_index"]) * n_g + g) * s_u + k
    sr = np.stack([(x["u"] - k * du) / du, (x["v"] - lo) / (hi - lo)], axis=1)

    # splats: every sector within `halo` standard deviations of each crossing
    sig_u, sig_v = param_sigma(sigma_per_radius * x["radius"] * np.sqrt(x["stretch"]), x["v"], x["phi"], x["a"], x["b"])
    k_lo = np.floor((x["u"] - halo * sig_u) / du).astype(np.int64)
    k_hi = np.floor((x["u"] + halo * sig_u) / du).astype(np.int64)
    g_lo = _track_of(bounds, x["cluster"], x["v"] - halo * sig_v)
    g_hi = _track_of(bounds, x["cluster"], x["v"] + halo * sig_v)
    n_k, n_gg = k_hi - k_lo + 1, g_hi - g_lo + 1
    per = n_k * n_gg
    src = np.repeat(np.arange(per.size), per)
    local = np.arange(src.size) - np.repeat(np.cumsum(per) - per, per)
    kk = k_lo[src] + local % n_k[src]
    gg = g_lo[src] + local // n_k[src]
    c_src = x["cluster"][src]
    glo, ghi = bounds[c_src, gg], bounds[c_src, gg + 1]
    s_sid = ((c_src * n_i + x["t_index"][src]) * n_g + gg) * s_u + np.mod(kk, s_u)
    center = np.stack([(x["u"][src] - kk * du) / du, (x["v"][src] - glo) / (ghi - glo)], axis=1)
    sigma = np.stack([sig_u[src] / du, sig_v[src] / (ghi - glo)], axis=1)
    order = np.argsort(s_sid, kind="stable")
    offsets = np.concatenate([[0], np.cumsum(np.bincount(s_sid, minlength=n_c * n_i * n_g * s_u))])

    hc, hi_, hg, hk = (
        a.ravel() for a in np.meshgrid(np.arange(n_c), np.arange(s_t), np.arange(n_g), np.arange(s_u), indexing="ij")
    )
    top = ((hc * n_i + hi_) * n_g + hg) * s_u + hk
    hsv = np.stack([top, top + n_g * s_u], axis=1)
    return SectorTable(
        shape=(n_c, n_i, n_g, s_u),
        s_v=s_v,
        cluster=cl,
        t_index=ti,
        track=tr,
        layer=tr // s_v,
        u_index=uk,
        t=t,
        v_range=v_range,
        u_range=u_range,
        half_axes=np.stack([sec.a[cl, ti], sec.b[cl, ti]], axis=1),
        twist=sec.twist[cl, ti],
        corners=corners,
        crossing_strand=x["strand"],
        crossing_sector=sid,
        crossing_sr=sr,
        crossing_xy=np.stack([x["x"], x["y"]], axis=1),
        crossing_vu=np.stack([x["v"], x["u"]], axis=1),
        crossing_point=x["point"],
        crossing_radius=x["radius"],
        crossing_stretch=x["stretch"],
        splat_offsets=offsets,
        splat_crossing=src[order],
        splat_center=center[order],
        splat_sigma=sigma[order],
        hsv_sectors=hsv,
    )
