"""The strands as Gaussian tubes and the exact line integrals of their density (the strand render's geometry).

**Density.**  A strand of radius r is the tube whose cross-section is the 2-D Gaussian the sector
densities use (``hairlut.geometry.splats``: σ = r/√2, mass π r² per unit length), so at distance d
from its axis ρ = π r² · exp(−d²/2σ²)/(2πσ²) = exp(−d²/r²): 1 on the axis, the fraction of area
covered.  A polyline strand is the sum of its segments' tubes, each cut by a box window on its own
axis (0 ≤ a ≤ L): exact for a straight strand, with gaps/overlaps of order r·(bend angle) at joints.

**Extinction.**  σ_t = κ / r with the scene's HRIR recipe κ (``trace.extinction``, 2/π: opaque
discs), as the tracer uses (``hairlut.hrir``): a straight strand seen side-on has optical depth
σ_t r √π · exp(−d²/r²) at distance d from its axis.

**Line integrals.**  Along a ray x(s) = o + s d (unit d) the distance to a segment's axis is
d⊥² = D + A (s − μ)² with A = |d × t|², μ the closest approach and D its squared distance; the window
is an interval of s.  So ∫ ρ ds over any interval is exp(−D/r²) · r/√A · √π/2 · (erf z_b − erf z_a),
z = √A (s − μ)/r (written with erfc tails, which keep float32 precision far from μ; the limit s_b − s_a
as A → 0).  :func:`crossings` gives every (ray, segment) pair's support — the window ∩ s ≥ s_lo ∩
|z| ≤ ``Z_CUT`` — cut into ``n`` equal steps with their exact optical depths.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np
from jax.scipy.special import erfc

from .. import errors

#: Tubes are cut at |z| = Z_CUT (the lost tail is erfc(Z_CUT)/2 ≈ 4e-7 of a crossing's optical depth).
Z_CUT = 3.5
_EPS_A = 1e-7
#: A (ray, segment) pair adds optical depth only where the ray passes within √D2_CUT r of the axis (``support``).
D2_CUT = 21.0
_BIG = 1e20


@dataclass(frozen=True, eq=False)
class Segments:
    """Strand segments: start ``p0`` (S, 3), unit ``tangent`` (S, 3), ``length``, ``radius`` and
    ``sigma_t`` (S,), float64 on the host."""

    p0: np.ndarray
    tangent: np.ndarray
    length: np.ndarray
    radius: np.ndarray
    sigma_t: np.ndarray

    @property
    def n(self) -> int:
        return len(self.length)

    def device(self) -> tuple:
        """The five arrays as float32 device arrays, in field order."""
        return tuple(jnp.asarray(a, jnp.float32) for a in (self.p0, self.tangent, self.length, self.radius, self.sigma_t))

    def bounds(self, pad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """The box (low, high corners) that holds every segment's Gaussian tube to its cut-off, widened by
        ``pad``."""
        p1 = self.p0 + self.tangent * self.length[:, None]
        reach = Z_CUT * self.radius.max() + pad
        return np.minimum(self.p0, p1).min(0) - reach, np.maximum(self.p0, p1).max(0) + reach


def segments_of(strands, kappa: float) -> Segments:
    """Segments of a :class:`~hairlut.geometry.Strands` (or a list of them; radius = half the mean thickness
    of the two end points) with σ_t = κ / r."""
    if not isinstance(strands, (list, tuple)):
        strands = [strands]
    if not (np.isfinite(kappa) and kappa > 0):
        raise errors.ValidationError("trace.extinction", kappa, "κ must be finite and > 0")
    p0s, p1s, rs = [], [], []
    for s in strands:
        if s.thickness is None:
            raise errors.ValidationError("strands.thickness", None, "the strand render needs each strand's thickness")
        pts, th = np.asarray(s.points, np.float64), np.asarray(s.thickness, np.float64)
        last = np.zeros(len(pts), bool)
        last[np.asarray(s.offsets)[1:] - 1] = True
        first = np.flatnonzero(~last)
        p0s.append(pts[first])
        p1s.append(pts[first + 1])
        rs.append(0.25 * (th[first] + th[first + 1]))
    p0, p1, r = np.concatenate(p0s), np.concatenate(p1s), np.concatenate(rs)
    v = p1 - p0
    length = np.linalg.norm(v, axis=1)
    keep = (length > 0) & (r > 0)
    if not keep.any():
        raise errors.ValidationError("strands", "empty", "no segment with length > 0 and radius > 0")
    p0, v, length, r = p0[keep], v[keep], length[keep], r[keep]
    return Segments(p0, v / length[:, None], length, r, kappa / r)


def tail_diff(za, zb, ea, eb):
    """√π/2 · (erf z_b − erf z_a) for z_a ≤ z_b from the tails e = erfc(|z|) (erfc(−z) = 2 − erfc(z) is never formed
    where it would cancel, so float32 keeps its precision far from μ)."""
    return 0.886226925452758 * jnp.where(za >= 0, ea - eb, jnp.where(zb <= 0, eb - ea, 2.0 - ea - eb))


def _edge_diff(z):
    """:func:`tail_diff` of consecutive edges z (…, n + 1) → (…, n), one erfc per edge."""
    e = erfc(jnp.abs(z))
    return tail_diff(z[..., :-1], z[..., 1:], e[..., :-1], e[..., 1:])


def support(o, d, p0, t, length, radius, sigma_t, s_lo):
    """Each (ray, segment) pair's crossing: (s_a, s_b, μ, scale, slanted, peak, near), all (…): the support [s_a, s_b]
    along the ray (the window ∩ s ≥ ``s_lo`` ∩ |z| ≤ ``Z_CUT``; s_b = s_a when empty), the closest approach μ, the
    s per unit z, whether the ray is slanted to the segment (else the integral is the support's length), the density's
    peak σ_t exp(−D/r²) on the ray, and ``near``: the pair can add optical depth (support not empty and
    D < ``D2_CUT`` r²: beyond, a crossing's optical depth is below e^−21 ≈ 7.6e-10 of a side-on one's)."""
    w = [o[..., i] - p0[..., i] for i in range(3)]
    dd = [d[..., i] for i in range(3)]
    tt = [t[..., i] for i in range(3)]
    b = dd[0] * tt[0] + dd[1] * tt[1] + dd[2] * tt[2]
    e1 = dd[0] * w[0] + dd[1] * w[1] + dd[2] * w[2]
    e2 = tt[0] * w[0] + tt[1] * w[1] + tt[2] * w[2]
    c = [dd[1] * tt[2] - dd[2] * tt[1], dd[2] * tt[0] - dd[0] * tt[2], dd[0] * tt[1] - dd[1] * tt[0]]
    a2 = c[0] ** 2 + c[1] ** 2 + c[2] ** 2
    slanted = a2 > _EPS_A
    a_safe = jnp.where(slanted, a2, 1.0)
    wc = w[0] * c[0] + w[1] * c[1] + w[2] * c[2]
    ww = w[0] ** 2 + w[1] ** 2 + w[2] ** 2
    dmin2 = jnp.where(slanted, wc * wc / a_safe, jnp.maximum(ww - e2 * e2, 0.0))
    mu = jnp.where(slanted, (b * e2 - e1) / a_safe, 0.0)
    along = jnp.abs(b) > 1e-12
    b_safe = jnp.where(along, b, 1.0)
    wa, wb = -e2 / b_safe, (length - e2) / b_safe
    inside = (e2 >= 0) & (e2 <= length)
    lo = jnp.where(along, jnp.minimum(wa, wb), jnp.where(inside, -_BIG, _BIG))
    hi = jnp.where(along, jnp.maximum(wa, wb), jnp.where(inside, _BIG, -_BIG))
    scale = radius / jnp.sqrt(a_safe)  # s per unit z
    cut = jnp.where(slanted, Z_CUT * scale, _BIG)
    sa = jnp.maximum(jnp.maximum(lo, s_lo), mu - cut)
    sb = jnp.minimum(hi, mu + cut)
    near = (sb > sa) & (dmin2 < D2_CUT * radius * radius)
    sb = jnp.maximum(sb, sa)
    peak = sigma_t * jnp.exp(-dmin2 / (radius * radius))
    return sa, sb, mu, scale, slanted, peak, near


def steps_of(sa, sb, mu, scale, slanted, peak, n: int):
    """Optical depths (…, n) of ``n`` equal steps over the supports [s_a, s_b] of :func:`support` and their
    mid-points s (…, n)."""
    f = jnp.arange(n + 1, dtype=sa.dtype) / n
    edges = sa[..., None] + (sb - sa)[..., None] * f
    z = (edges - mu[..., None]) / scale[..., None]
    integral = jnp.where(slanted[..., None], scale[..., None] * _edge_diff(z), edges[..., 1:] - edges[..., :-1])
    tau = peak[..., None] * jnp.maximum(integral, 0.0)
    return tau, 0.5 * (edges[..., 1:] + edges[..., :-1])


def crossings(o, d, p0, t, length, radius, sigma_t, s_lo, n: int):
    """Optical depths (…, n) of ``n`` equal steps over each (ray, segment) crossing's support, their
    mid-points s (…, n) along the ray; all inputs broadcast (… , 3) / (…); ``s_lo`` the rays' start."""
    sa, sb, mu, scale, slanted, peak, _ = support(o, d, p0, t, length, radius, sigma_t, s_lo)
    return steps_of(sa, sb, mu, scale, slanted, peak, n)


def inside_clusters(pairs, *, samples: int = 801) -> tuple[list, dict]:
    """The part of each cluster's strands that its sectors can see, as 2-point strands (one per kept segment), and
    the length fractions: ``pairs`` [(ClusterSpec, Strands)] (``hairlut.scene.scene_clusters``).

    A segment is kept when its mid-point lies between the end cross-sections (t ∈ [0, 1] of the trajectory,
    nearest of ``samples`` sections) and between the core and the outer shell (core_radius ≤ v ≤ 1 of eq 1's
    ellipse): where a strand crosses the sectors' planes (``hairlut.geometry.build_sectors``).  Rendering these
    against all the strands separates what the cluster fit leaves out from what the layered model loses."""
    from ..geometry import PLACES, Strands, segment_places

    kept, lost = [], {"before_start": 0.0, "after_end": 0.0, "core": 0.0, "outside": 0.0, "inside": 0.0}
    total = 0.0
    for spec, s in pairs:
        first, length, place = segment_places(spec, s, samples=samples)
        for k, name in enumerate(PLACES):
            lost[name] += float(length[place == k].sum())
        total += float(length.sum())
        f = first[place == 0]
        p = np.asarray(s.points, np.float64)
        th = None if s.thickness is None else np.stack([s.thickness[f], s.thickness[f + 1]], 1).ravel()
        kept.append(Strands(np.stack([p[f], p[f + 1]], 1).reshape(-1, 3).astype(np.float32), np.full(len(f), 2), thickness=th))
    return kept, {k: v / total for k, v in lost.items()}
