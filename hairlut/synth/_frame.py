"""The per-frame path of eqs 6–7 (satf §6.2): the index once, then three jitted kernels a frame.

:func:`map_index` (once per scene, in ``prepare``) keeps what does not change with the view
or the lights; :func:`frame_maps` runs :func:`params_kernel` (angles, eq 6),
:func:`fetch_kernel` (the SATF rows, non-uniform HSVs compacted on the host) and
:func:`sweep_rows` (eq 7).  Conventions and the reference implementation: ``_maps``.

``[render] layer_reads = "track"`` replaces eq 7's two reads per texel (its HSV's top and bottom sector at the
texel's pixel) by :func:`sweep_track`: in each of the two cross-sections, every sector the texel's in-plane ray
crosses in its track on its side of the chord (:func:`track_window`), so that a ray's fragments together read
the whole path through the cluster once; then the same γ interpolation.  It needs every sector's own row (no
eq 6 shortcut on the ``satf`` path).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..hrir import interpolate, neighbours_kernel
from ._maps import TWO_PI, SectorFrames, _bucket, _check_k, _device_db, _sample, _texel_cells, texel_offsets


#: Phase overlap (radians) below which a segment does not count as crossing a sector (float32 rounding at a
#: sector border: both fragments of a chord must agree on which of them crosses it).
EPS_PHASE = 1e-5
#: ``[render] layer_reads``: what a layer texel reads of its track (:func:`sweep_rows` / :func:`sweep_track`).
LAYER_READS = ("pair", "track")


@partial(jax.tree_util.register_dataclass, data_fields=["axes", "nbr", "wgt", "dz2", "nbr_ave", "wgt_ave", "gamma", "offset",
                                                        "track"],
         meta_fields=["grid", "layers", "rows", "cols", "reads"])
@dataclass(frozen=True, eq=False)
class MapIndex:
    """§6.2.1's index: what eqs 6–7 need that does not change with the view or the lights, as
    device arrays over the sectors (S; grid (C, s_t + 1, G, s_u)), HSVs (H; (C, s_t, G, s_u))
    and texels ((C, K, n_t, n_u); texel (i, j) of layer k lies in HSV row ``rows[i]``, column
    ``cols[j]``, track k).  Per sector: ``axes`` (2, S, 3), its +x and +y in 3-D; ``nbr``,
    ``wgt`` (S, k), the SATF neighbours of its features (``hairlut.hrir.neighbours``; zero
    weights for an empty sector, which holds no hair: α = re = 0).
    Per HSV: ``dz2``, eq 6's feature term Σ Δz² (∞ when one of its sectors is empty: never
    uniform); ``nbr_ave``, ``wgt_ave``, the neighbours of its averaged features.  Per texel row: ``gamma`` (n_t,), γ along the HSV.  Per texel:
    ``offset`` (2, 2, …) of :func:`texel_offsets`.  ``reads``: one of :data:`LAYER_READS`; for ``"track"``,
    ``track`` (S, 12) per sector: its cross-section's half axes A, B and twist q, its track's radii v0, v1,
    its centre (2), extent R, +x and +y (2 each) in the normal plane (:func:`sweep_track`)."""

    axes: jax.Array
    nbr: jax.Array
    wgt: jax.Array
    dz2: jax.Array
    nbr_ave: jax.Array
    wgt_ave: jax.Array
    gamma: jax.Array
    offset: jax.Array
    grid: tuple
    layers: int
    rows: tuple
    cols: tuple
    track: jax.Array | None = None
    reads: str = "pair"


def _track_table(fr: SectorFrames, reads: str):
    """:class:`MapIndex`'s ``track`` (S, 12) for ``reads = "track"`` (None for ``"pair"``); checks ``reads``."""
    if reads not in LAYER_READS:
        raise errors.ValidationError("render.layer_reads", reads, f"one of {', '.join(LAYER_READS)}")
    if reads == "pair":
        return None
    cols = (fr.half_axes, fr.twist[:, None], fr.v_inner[:, None], fr.v_outer[:, None], fr.centre, fr.extent[:, None],
            fr.ex, fr.ey)
    return jnp.asarray(np.concatenate([np.asarray(c, np.float64).reshape(len(fr.extent), -1) for c in cols], 1),
                       jnp.float32)


def map_index(db, table, fr: SectorFrames, n_layers: int, resolution, k: int, reads: str = "pair") -> MapIndex:
    """The :class:`MapIndex` of a (multi-cluster) sector table; its neighbours are those ``fetch`` finds;
    ``reads``: ``[render] layer_reads`` (:data:`LAYER_READS`)."""
    _check_k(db, k)
    track = _track_table(fr, reads)
    zdb, _, _, mean, std = _device_db(db)
    n_c, n_i, n_g, s_u = table.shape
    top = ((np.arange(n_c)[:, None] * n_i + np.arange(n_i - 1)) * n_g * s_u)[..., None] + np.arange(n_g * s_u)
    if not np.array_equal(table.hsv_sectors, np.stack([top.ravel(), top.ravel() + n_g * s_u], 1)):
        raise errors.ValidationError("table.hsv_sectors", table.shape, "need the sector table's HSV order")
    top, bot = table.hsv_sectors[:, 0], table.hsv_sectors[:, 1]

    def knn(f):
        return neighbours_kernel(jnp.asarray((f - mean) / std, jnp.float32), zdb, int(k))

    occ = np.asarray(fr.occupied, bool)  # an empty sector holds no hair: zero weights give α = re = 0
    nbr, wgt = knn(fr.features)
    nbr_ave, wgt_ave = knn(0.5 * (fr.features[top] + fr.features[bot]))
    wgt, wgt_ave = wgt * occ[:, None], wgt_ave * (occ[top] & occ[bot])[:, None]
    axes = np.stack([fr.ex[:, :1] * fr.reference + fr.ex[:, 1:] * fr.binormal,
                     fr.ey[:, :1] * fr.reference + fr.ey[:, 1:] * fr.binormal])
    dz2 = np.sum(((fr.features[top] - fr.features[bot]) / std) ** 2, -1)
    dz2 = np.where(occ[top] == occ[bot], dz2, np.inf)  # a half-empty HSV is never uniform: eq 7 fades to its empty end
    rows, gamma, cols = _texel_cells(table.shape, resolution)
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    return MapIndex(f32(axes), nbr, wgt, f32(dz2), nbr_ave, wgt_ave, f32(gamma),
                    f32(texel_offsets(table, fr, n_layers, resolution)[2]), (n_c, n_i - 1, n_g, s_u), int(n_layers),
                    tuple(rows.tolist()), tuple(cols.tolist()), track, reads)


def _wrap(x):
    return jnp.mod(x + jnp.pi, TWO_PI) - jnp.pi


def _take(x, idx: tuple, axis: int):
    """x[..., idx, ...] along ``axis`` for a static index: a broadcast where idx = 0…0, 1…1, … (m each)."""
    m = len(idx) // max(x.shape[axis], 1)
    if m * x.shape[axis] == len(idx) and idx == tuple(i // m for i in range(len(idx))):
        return jnp.repeat(x, m, axis=axis)
    return jnp.take(x, np.asarray(idx), axis=axis)


def _split(ix: MapIndex, x):
    """Per-sector values (S, …) at every HSV's top and bottom sector: two (H, …) arrays (slices, no gather)."""
    n_c, s_t, n_g, s_u = ix.grid
    x = x.reshape(n_c, s_t + 1, n_g * s_u, *x.shape[1:])
    return x[:, :-1].reshape(-1, *x.shape[3:]), x[:, 1:].reshape(-1, *x.shape[3:])


def _texels(ix: MapIndex, x):
    """Per-HSV values (H, …) → per texel (C, K, n_t, n_u, …)."""
    n_c, s_t, n_g, s_u = ix.grid
    x = jnp.swapaxes(x.reshape(n_c, s_t, n_g, s_u, *x.shape[1:])[:, :, :ix.layers], 1, 2)
    return _take(_take(x, ix.rows, 2), ix.cols, 3)


@partial(jax.jit, static_argnames=("n_v", "n_l"))
def params_kernel(ix: MapIndex, view, lights, k_threshold, *, n_v: int, n_l: int):
    """Params(b) angles of every sector, θv (S,) and θl (S, Lt), with the view's (cos θv, sin θv)
    (S, 2), and eq 6 per HSV: the distance and the uniform mask (H,) (module docstring)."""
    def project(d):  # (…, 3) → components on each sector's +x, +y: (S, …) twice
        return (sum(ix.axes[i, :, j, None] * d[..., j] for j in range(3)) for i in (0, 1))

    x, y = project(jnp.concatenate([view[None], lights]))
    theta = jnp.mod(jnp.arctan2(y, x), TWO_PI)
    r = jnp.hypot(x[:, 0], y[:, 0])
    r1 = jnp.where(r > 0, r, 1.0)  # atan2(0, 0) = 0
    cs = jnp.stack([jnp.where(r > 0, x[:, 0] / r1, 1.0), y[:, 0] / r1], -1)
    (top, bot) = _split(ix, theta)
    dv = _wrap(top[:, 0] - bot[:, 0]) / (TWO_PI / n_v)
    dl = _wrap(top[:, 1:] - bot[:, 1:]) / (TWO_PI / n_l)
    dist = jnp.sqrt(ix.dz2 + dv**2 + jnp.sum(dl**2, -1))
    return theta[:, 0], theta[:, 1:], cs, dist, dist < k_threshold


@partial(jax.jit, donate_argnames=("scratch",), keep_unused=True)
def fetch_kernel(ix: MapIndex, alpha, refl, tv, tl, uniform, nonuniform, scratch):
    """The SATF rows of a frame from the index's neighbours (``hairlut.hrir.interpolate``):
    re (M, Lt, P), α (M, P).  Row h < H is HSV h's first HRIR (at Params_ave if it is uniform,
    else its top sector's); row H + i the bottom sector's HRIR of HSV ``nonuniform[i]``.
    ``scratch``: two arrays of those shapes, donated, so that the rows reuse their memory."""
    u = uniform[:, None]
    (n1, n2), (w1, w2), (v1, v2), (l1, l2) = (_split(ix, x) for x in (ix.nbr, ix.wgt, tv, tl))
    q = (jnp.where(u, ix.nbr_ave, n1), jnp.where(u, ix.wgt_ave, w1),
         jnp.where(uniform, v1 + 0.5 * _wrap(v2 - v1), v1), jnp.where(u, l1 + 0.5 * _wrap(l2 - l1), l1))
    return interpolate(*(jnp.concatenate([a, b[nonuniform]]) for a, b in zip(q, (n2, w2, v2, l2))), alpha, refl)


def track_window(ix: MapIndex, cs, e: int):
    """The sectors a texel's in-plane ray crosses in its track, on its side of the chord, in cross-section ``e``
    (0: its HSV's top, 1: bottom): per texel (C, K, n_t, n_u), for m < M = min(s_u, ⌊s_u/4⌋ + 2), the phase
    column ``col[m]`` (0 … s_u − 1) of the m-th sector from the texel's point p inward along the ray, its weight
    ``w[m]`` (1; ½ when the chord's other fragment crosses it too; 0 past the segment's end) and its image-line
    coordinate ``x[m]`` = (p − c_s)·e / R_s (e the in-plane view turned +90°); and ``front`` (the ray enters the
    track at p: m runs front to back; else back to front).

    Geometry (satf eq 1: x = A v cos(q + u), y = B v sin(q + u), so in (x/A, y/B) the track is the annulus
    v0 ≤ |·| ≤ v1 and a straight line stays straight): the camera ray through p, projected into the normal
    plane, crosses the track in one chord (entry and exit on the layer surface v1) or, when it meets the inner
    surface v0 > 0, in two segments.  The texel's segment runs from p inward to the inner surface, or to the
    chord's midpoint; the chord's other fragment (the layer surface's other hit) takes the rest, so every
    piece of the path is read once.  The polar angle is monotonic along a line and a half chord turns by at
    most π/2, so the segment crosses a contiguous window of at most M phase columns; a column both segments
    cross (by more than :data:`EPS_PHASE` of phase) is split between them (weight ½ each: the sector's own
    projection counts once in all)."""
    n_c, s_t, n_g, s_u = ix.grid
    S = n_c * (s_t + 1) * n_g * s_u
    n_u = ix.offset.shape[-1]
    du = TWO_PI / s_u
    u = (TWO_PI * (jnp.arange(n_u) + 0.5) / n_u).astype(jnp.float32)
    sid = _texels(ix, _split(ix, jnp.arange(S, dtype=jnp.int32))[e])
    g = ix.track[sid]
    A, B, q, v0, v1, cx, cy, R, exx, exy, eyx, eyy = (g[..., i] for i in range(12))
    c = cs[sid]
    dx, dy = c[..., 0] * exx + c[..., 1] * eyx, c[..., 0] * exy + c[..., 1] * eyy  # in-plane view (toward the eye)
    px, py = v1 * jnp.cos(q + u), v1 * jnp.sin(q + u)  # p in (x/A, y/B)
    wx, wy = -dx / A, -dy / B  # the ray, away from the eye
    pw = px * wx + py * wy
    front = pw < 0
    sgn = jnp.where(front, 1.0, -1.0)
    wx, wy, pw = sgn * wx, sgn * wy, sgn * pw  # now inward from p: pw ≤ 0
    ww = wx * wx + wy * wy
    s_mid = -pw / ww
    disc = pw * pw - ww * (v1 * v1 - v0 * v0)
    s_end = jnp.where((disc > 0) & (v0 > 0), (-pw - jnp.sqrt(jnp.maximum(disc, 0.0))) / ww, s_mid)
    cr = px * wy - py * wx
    sig = jnp.where(cr >= 0, 1, -1)

    def phase(s):  # unwrapped phase of p + s w: the polar angle turns by sig · atan2(|s cr|, v1² + s pw)
        return u + sig * jnp.arctan2(jnp.abs(s * cr), v1 * v1 + s * pw)

    own = (u, phase(s_end))
    other = (phase(2 * s_mid - s_end), phase(2 * s_mid))

    turns = (-s_u, 0, s_u) if s_u == 1 else (0,)  # from s_u = 2 on, the chord's columns never wrap onto each other

    def crossed(j, ends):  # phase length of column j (any turn of the circle) inside the interval between ends
        lo, hi = jnp.minimum(*ends), jnp.maximum(*ends)
        over = [jnp.minimum(hi, (j + n + 1) * du) - jnp.maximum(lo, (j + n) * du) for n in turns]
        return over[0] if len(over) == 1 else jnp.max(jnp.stack(over), axis=0)

    j0 = jnp.floor(u / du).astype(jnp.int32) + jnp.zeros_like(sig)  # unwrapped column of p
    Px, Py, base = A * px, B * py, sid - jnp.mod(sid, s_u)
    frame = ix.track[:, 5:8]  # centre, extent
    cols, ws, xs = [], [], []
    for m in range(min(s_u, s_u // 4 + 2)):
        j = j0 + sig * m
        k = jnp.mod(j, s_u)
        w = jnp.where(crossed(j, own) > EPS_PHASE, jnp.where(crossed(j, other) > EPS_PHASE, 0.5, 1.0), 0.0)
        h = frame[base + k]
        xs.append(((Px - h[..., 0]) * -dy + (Py - h[..., 1]) * dx) / h[..., 2])
        cols.append(k)
        ws.append(w)
    return cols, ws, xs, front


def sweep_track(ix: MapIndex, rows_re, rows_a, cs):
    """``layer_reads = "track"``: each texel's α and re from every sector its in-plane ray crosses in its track
    (:func:`track_window`), in both of its HSV's cross-sections, then eq 7's γ interpolation between them.  Rows:
    HSV h's top sector's at row h, its bottom sector's at row H + h (``sweep_sectors``' layout; ``fetch_kernel``'s
    with every HSV non-uniform).  Per cross-section, with weight w a sector's pixel gives α' = 1 − (1 − α)^w
    (its optical depth times w) and re' = re α'/α (re is α-premultiplied), composited along the ray front to
    back: α = 1 − Π(1 − α'), re = Σ re' Π_{before}(1 − α').

    Cost: up to 2M samples per texel instead of 2, plus the window's geometry; on the paper-scale model
    (53,040 sectors, 208,896 texels, s_u = 16: M = 6) 246–401 CPU-ms against eq 7's 6.5 in the same run
    (``benchmarks/layer_reads.py --paper``, loaded 2-core CPU), which is why ``pair`` stays the default."""
    n_c, s_t, n_g, s_u = ix.grid
    H = n_c * s_t * n_g * s_u
    Lt, P = rows_re.shape[1:]
    h = _texels(ix, jnp.arange(H, dtype=jnp.int32))
    flat_re, flat_a = rows_re.reshape(-1), rows_a.reshape(-1)
    out = []
    for e in (0, 1):
        # materialised: XLA:CPU would otherwise recompute the window's geometry inside every gather that reads it
        cols, ws, xs, front = jax.lax.optimization_barrier(tuple(jnp.stack(a) if isinstance(a, list) else a
                                                                 for a in track_window(ix, cs, e)))
        row0 = e * H + h - jnp.mod(h, s_u)
        acc = jnp.zeros(h.shape + (Lt,), jnp.float32)
        trans = jnp.ones(h.shape, jnp.float32)
        for k, w, x in zip(cols, ws, xs):
            row, p = row0 + k, (x + 1.0) * P / 2.0 - 0.5
            a = jnp.clip(_sample(flat_a, row, p, P), 0.0, 1.0)
            a_w = jnp.where(w == 1.0, a, jnp.where(w == 0.0, 0.0, 1.0 - jnp.sqrt(1.0 - a)))  # 1 − (1 − α)^w
            scale = jnp.where(a > 0, a_w / jnp.where(a > 0, a, 1.0), 0.0)
            re = jnp.stack([_sample(flat_re, row * Lt + j, p, P) for j in range(Lt)], -1) * scale[..., None]
            acc = jnp.where(front[..., None], acc + trans[..., None] * re, re + (1.0 - a_w[..., None]) * acc)
            trans = trans * (1.0 - a_w)
        out.append((acc, 1.0 - trans))
    g = ix.gamma[:, None]
    re = (1 - g[..., None]) * out[0][0] + g[..., None] * out[1][0]
    a = (1 - g) * out[0][1] + g * out[1][1]
    return jnp.moveaxis(re, -1, 2), jnp.clip(a, 0.0, 1.0)


@jax.jit
def sweep_rows(ix: MapIndex, rows_re, rows_a, cs, uniform, slot):
    """Eq 7 per texel from :func:`fetch_kernel`'s rows: re (C, K, Lt, n_t, n_u), α (C, K, n_t, n_u).

    A texel samples its HSV's row h at x⊤ and, with weight γ, row H + ``slot[h]`` at x⊥; a
    uniform HSV's texels sample row h twice at x̄ (module docstring).  With ``ix.reads = "track"``
    (every HSV non-uniform, ``slot[h] = h``): :func:`sweep_track`."""
    if ix.reads == "track":
        return sweep_track(ix, rows_re, rows_a, cs)
    H, (Lt, P) = uniform.shape[0], rows_re.shape[1:]
    c1, c2 = (_texels(ix, x) for x in _split(ix, cs))  # (C, K, n_t, n_u, 2) each
    pix = [((-c[..., 1] * o[0] + c[..., 0] * o[1]) + 1.0) * P / 2.0 - 0.5 for c, o in zip((c1, c2), ix.offset)]
    un, h = _texels(ix, uniform), _texels(ix, jnp.arange(H, dtype=jnp.int32))
    p_ave = 0.5 * (pix[0] + pix[1])
    p1, p2 = jnp.where(un, p_ave, pix[0]), jnp.where(un, p_ave, pix[1])
    h2 = jnp.where(un, h, H + _texels(ix, slot))
    g = ix.gamma[:, None]

    def eq7(rows, r1, r2):
        flat = rows.reshape(-1)
        return (1 - g) * _sample(flat, r1, p1, P) + g * _sample(flat, r2, p2, P)

    re = jnp.stack([eq7(rows_re, h * Lt + j, h2 * Lt + j) for j in range(Lt)], axis=2)
    return re, jnp.clip(eq7(rows_a, h, h2), 0.0, 1.0)


_SCRATCH: dict[int, tuple] = {}


def frame_rows(ix: MapIndex, db, view, lights, k_threshold: float):
    """Eq 6 and the SATF fetches of one frame: :func:`sweep_rows`'s arguments after ``ix`` (device
    arrays) and the uniform mask (H,) on the host.  Two kernels: the uniformity test, then, with the
    few non-uniform HSVs compacted on the host (padded to a bucket size), the fetches.  The rows
    stay valid until the next frame of ``ix``, which reuses their memory."""
    _, alpha, refl, _, _ = _device_db(db)
    f32 = partial(np.asarray, dtype=np.float32)  # NumPy in: a jnp conversion would dispatch a kernel per argument
    tv, tl, cs, _, uni = params_kernel(ix, f32(view), f32(lights), f32(k_threshold), n_v=len(db.theta_v),
                                       n_l=len(db.theta_l))
    if ix.reads == "track":  # the track read needs every sector's own row: no eq 6 shortcut
        uni = jnp.zeros_like(uni)
    uniform = np.asarray(uni)
    nu = np.flatnonzero(~uniform)
    slot = np.zeros(len(uniform), np.int32)
    slot[nu] = np.arange(nu.size)
    pad = np.zeros(_bucket(nu.size), np.int32)
    pad[:nu.size] = nu
    m, P = len(uniform) + pad.size, alpha.shape[-1]
    shapes = ((m, tl.shape[1], P), (m, P))
    scratch = _SCRATCH.pop(id(ix), None)
    if scratch is None or tuple(x.shape for x in scratch) != shapes:
        scratch = tuple(jnp.zeros(s, jnp.float32) for s in shapes)
    rows = fetch_kernel(ix, alpha, refl, tv, tl, uni, pad, scratch)
    if len(_SCRATCH) >= 4:
        _SCRATCH.pop(next(iter(_SCRATCH)))
    _SCRATCH[id(ix)] = rows
    return (*rows, cs, uni, slot), uniform


def frame_maps(ix: MapIndex, db, view, lights, k_threshold: float):
    """Eqs 6–7 of one frame from the index: re, α as :func:`build_maps` (device arrays) and the uniform mask."""
    args, uniform = frame_rows(ix, db, view, lights, k_threshold)
    return (*sweep_rows(ix, *args), uniform)


def geometry_index(table, fr: SectorFrames, n_layers: int, resolution, reads: str = "pair") -> MapIndex:
    """A :class:`MapIndex` of the geometry alone (no SATF neighbours): what :func:`params_kernel`
    (angles; eq 6's distance is then meaningless and unused) and :func:`sweep_sectors` read, for the map
    methods that make every sector's own row (``direct``, ``scene``); ``reads`` as :func:`map_index`'s."""
    track = _track_table(fr, reads)
    n_c, n_i, n_g, s_u = table.shape
    top = ((np.arange(n_c)[:, None] * n_i + np.arange(n_i - 1)) * n_g * s_u)[..., None] + np.arange(n_g * s_u)
    if not np.array_equal(table.hsv_sectors, np.stack([top.ravel(), top.ravel() + n_g * s_u], 1)):
        raise errors.ValidationError("table.hsv_sectors", table.shape, "need the sector table's HSV order")
    axes = np.stack([fr.ex[:, :1] * fr.reference + fr.ex[:, 1:] * fr.binormal,
                     fr.ey[:, :1] * fr.reference + fr.ey[:, 1:] * fr.binormal])
    rows, gamma, cols = _texel_cells(table.shape, resolution)
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    none = jnp.zeros((0, 1), jnp.int32)
    return MapIndex(f32(axes), none, f32(none), f32(np.zeros(len(table.hsv_sectors))), none, f32(none), f32(gamma),
                    f32(texel_offsets(table, fr, n_layers, resolution)[2]), (n_c, n_i - 1, n_g, s_u), int(n_layers),
                    tuple(rows.tolist()), tuple(cols.tolist()), track, reads)


@jax.jit
def sweep_sectors(ix: MapIndex, alpha, re, cs):
    """Eq 7 per texel from every sector's own rows, α (S, P) and re (S, Lt, P), two per HSV (its top and
    bottom sector; no eq 6 shortcut): re (C, K, Lt, n_t, n_u), α (C, K, n_t, n_u).  ``cs`` (S, 2): each
    sector's (cos θv, sin θv) from :func:`params_kernel`."""
    a1, a2 = _split(ix, alpha)
    r1, r2 = _split(ix, re)
    H = a1.shape[0]
    return sweep_rows(ix, jnp.concatenate([r1, r2]), jnp.concatenate([a1, a2]), cs, jnp.zeros(H, bool),
                      jnp.arange(H, dtype=jnp.int32))
