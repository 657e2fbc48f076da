"""The per-view path of eqs 6–7 (satf §6.2): the index once, then three jitted kernels a view.

:func:`map_index` (once per scene, in ``prepare``) keeps what does not change with the view
or the lights; :func:`view_maps` runs :func:`params_kernel` (angles, eq 6),
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


@partial(
    jax.tree_util.register_dataclass,
    data_fields=["axes", "nbr", "wgt", "dz2", "nbr_ave", "wgt_ave", "gamma", "offset", "track"],
    meta_fields=["grid", "layers", "rows", "cols", "reads"],
)
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
    cols = (
        fr.half_axes,
        fr.twist[:, None],
        fr.v_inner[:, None],
        fr.v_outer[:, None],
        fr.centre,
        fr.extent[:, None],
        fr.ex,
        fr.ey,
    )
    return jnp.asarray(np.concatenate([np.asarray(c, np.float64).reshape(len(fr.extent), -1) for c in cols], 1), jnp.float32)


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
    axes = np.stack(
        [fr.ex[:, :1] * fr.reference + fr.ex[:, 1:] * fr.binormal, fr.ey[:, :1] * fr.reference + fr.ey[:, 1:] * fr.binormal]
    )
    dz2 = np.sum(((fr.features[top] - fr.features[bot]) / std) ** 2, -1)
    dz2 = np.where(occ[top] == occ[bot], dz2, np.inf)  # a half-empty HSV is never uniform: eq 7 fades to its empty end
    rows, gamma, cols = _texel_cells(table.shape, resolution)
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    return MapIndex(
        f32(axes),
        nbr,
        wgt,
        f32(dz2),
        nbr_ave,
        wgt_ave,
        f32(gamma),
        f32(texel_offsets(table, fr, n_layers, resolution)[2]),
        (n_c, n_i - 1, n_g, s_u),
        int(n_layers),
        tuple(rows.tolist()),
        tuple(cols.tolist()),
        track,
        reads,
    )


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
    x = jnp.swapaxes(x.reshape(n_c, s_t, n_g, s_u, *x.shape[1:])[:, :, : ix.layers], 1, 2)
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
    """The SATF rows of a view from the index's neighbours (``hairlut.hrir.interpolate``):
    re (M, Lt, P), α (M, P).  Row h < H is HSV h's first HRIR (at Params_ave if it is uniform,
    else its top sector's); row H + i the bottom sector's HRIR of HSV ``nonuniform[i]``.
    ``scratch``: two arrays of those shapes, donated, so that the rows reuse their memory."""
    u = uniform[:, None]
    (n1, n2), (w1, w2), (v1, v2), (l1, l2) = (_split(ix, x) for x in (ix.nbr, ix.wgt, tv, tl))
    q = (
        jnp.where(u, ix.nbr_ave, n1),
        jnp.where(u, ix.wgt_ave, w1),
        jnp.where(uniform, v1 + 0.5 * _wrap(v2 - v1), v1),
        jnp.where(u, l1 + 0.5 * _wrap(l2 - l1), l1),
    )
    return interpolate(*(jnp.concatenate([a, b[nonuniform]]) for a, b in zip(q, (n2, w2, v2, l2))), alpha, refl)


def _fenced(fn, *args):
    """fn(*args), materialised: both branches of a ``lax.cond`` are fn, so the result is the same whichever runs,
    and XLA cannot fuse fn's work into the consumers.  XLA:CPU drops ``optimization_barrier`` and fuses a producer
    into each of its consumers, recomputing it (cos, sin, atan2, the gathers' index arithmetic) once per
    consumer (the paper-scale track window computed cos and sin in 12 fusions: 72 → 20–24 CPU-ms fenced)."""
    lead = jnp.ravel(jax.tree_util.tree_leaves(args)[0])[0]
    return jax.lax.cond(lead == lead, fn, fn, *args)


def _track_layout(ix: MapIndex):
    """The track read's static layout: the sector rows ``used`` (sorted, of 0 … s_t) that the texels' two
    cross-sections read, and per cross-section e (0: the HSV's top, 1: its bottom) the position in ``used`` of
    each texel row's sector row ``rows[i] + e``.  A cross-section's window and composite depend only on the
    sector row, the track and the texel column (the layer-surface point p lies in the cross-section), so they
    are made once per (C, R, K, n_u) *entry* and shared by the texel rows that read that sector row."""
    rows = np.asarray(ix.rows)
    used = np.unique(np.concatenate([rows, rows + 1]))
    return tuple(used.tolist()), tuple(tuple(np.searchsorted(used, rows + e).tolist()) for e in (0, 1))


def _entries(ix: MapIndex, x, used: tuple):
    """Per-sector values (S, …) → per entry (C, R, K, n_u, …): sector row ``used[r]``, track k, the phase column
    of texel column j (broadcasts, no gather, where the texel columns are the regular repeat)."""
    n_c, s_t, n_g, s_u = ix.grid
    x = x.reshape(n_c, s_t + 1, n_g, s_u, *x.shape[1:])[:, :, : ix.layers]
    if used != tuple(range(s_t + 1)):
        x = jnp.take(x, np.asarray(used), axis=1)
    return _take(x, ix.cols, 3)


def track_window(ix: MapIndex, cs, used: tuple, by_sector: bool = False):
    """The sectors each entry's in-plane ray crosses in its track, on its side of the chord (an entry: a sector
    row ``used[r]``, a track k, a texel column j; :func:`_track_layout`), flattened to (E,): for m < M =
    min(s_u, ⌊s_u/4⌋ + 2), the m-th sector from the texel's point p inward along the ray is phase column
    k_m = (``j0`` + ``sig`` m) mod s_u, with weight ``w[:, m]`` (1; ½ when the chord's other fragment crosses it
    too; 0 past the segment's end); ``last`` is one past the last m of nonzero weight (slots from ``last`` on
    are no-ops); ``front`` (the ray enters the track at p: m runs front to back; else back to front); and what
    the image-line coordinate x_m = (p − c_s)·e / R_s of sector s = ``base`` + k_m needs (e the in-plane view
    turned +90°): p (``Px``, ``Py``) and the in-plane view (``dx``, ``dy``); ``row0``: the entry's track's first
    row in :func:`sweep_track`'s rows (``by_sector``: rows in sector order, (S, …); else its HSV layout).

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
    S, H = n_c * (s_t + 1) * n_g * s_u, n_c * s_t * n_g * s_u
    n_u = ix.offset.shape[-1]
    du = TWO_PI / s_u
    u = (TWO_PI * (jnp.arange(n_u) + 0.5) / n_u).astype(jnp.float32)
    sid = _entries(ix, jnp.arange(S, dtype=jnp.int32), used)
    g = _entries(ix, ix.track, used)
    A, B, q, v0, v1, _, _, _, exx, exy, eyx, eyy = (g[..., i] for i in range(12))
    c = _entries(ix, cs, used)
    dx, dy = c[..., 0] * exx + c[..., 1] * eyx, c[..., 0] * exy + c[..., 1] * eyy  # in-plane view (toward the eye)
    px, py = _fenced(lambda v1, qu: (v1 * jnp.cos(qu), v1 * jnp.sin(qu)), v1, q + u)  # p in (x/A, y/B)
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

    own_end, other = _fenced(lambda *a: (phase(s_end), (phase(2 * s_mid - s_end), phase(2 * s_mid))), s_end)
    own = (u, own_end)

    turns = (-s_u, 0, s_u) if s_u == 1 else (0,)  # from s_u = 2 on, the chord's columns never wrap onto each other

    def crossed(j, ends):  # phase length of column j (any turn of the circle) inside the interval between ends
        lo, hi = jnp.minimum(*ends), jnp.maximum(*ends)
        over = [jnp.minimum(hi, (j + n + 1) * du) - jnp.maximum(lo, (j + n) * du) for n in turns]
        return over[0] if len(over) == 1 else jnp.max(jnp.stack(over), axis=0)

    j0 = jnp.floor(u / du).astype(jnp.int32) + jnp.zeros_like(sig)  # unwrapped column of p
    ws = [
        jnp.where(crossed(j0 + sig * m, own) > EPS_PHASE, jnp.where(crossed(j0 + sig * m, other) > EPS_PHASE, 0.5, 1.0), 0.0)
        for m in range(min(s_u, s_u // 4 + 2))
    ]
    last = jnp.max(jnp.stack([jnp.where(w > 0, m + 1, 0) for m, w in enumerate(ws)]), axis=0)
    base = sid - jnp.mod(sid, s_u)
    cell = sid // (n_g * s_u)  # c (s_t + 1) + r
    hs = base - (cell // (s_t + 1)) * (n_g * s_u)  # the HSV of which the sector is the top (r < s_t) …
    row0 = base if by_sector else jnp.where(jnp.mod(cell, s_t + 1) < s_t, hs, H + hs - n_g * s_u)  # … else the
    # bottom of the HSV before it
    geo = {
        "j0": j0,
        "sig": sig,
        "front": front,
        "w": jnp.stack(ws, -1),
        "last": last,
        "Px": A * px,
        "Py": B * py,
        "dx": dx,
        "dy": dy,
        "base": base,
        "row0": row0,
    }
    return {k: v.reshape(-1, *v.shape[4:]) for k, v in geo.items()}


def _track_slot(m: int, geo: dict, acc, trans, flat_a, flat_re, section, s_u: int, P: int):
    """Slot m of :func:`sweep_track`'s front-to-back composite, for the entries of ``geo`` (all, or a subset)."""
    Lt = acc.shape[-1]
    k = jnp.mod(geo["j0"] + geo["sig"] * m, s_u)
    w = geo["w"][:, m]
    h = section[geo["base"] + k]
    x = ((geo["Px"] - h[..., 0]) * -geo["dy"] + (geo["Py"] - h[..., 1]) * geo["dx"]) / h[..., 2]
    row, p = geo["row0"] + k, (x + 1.0) * P / 2.0 - 0.5
    f = jnp.clip(p, 0.0, P - 1.0)  # _maps._sample's pixel, materialised before the gathers that use it
    i0 = jnp.clip(jnp.floor(f).astype(jnp.int32), 0, max(P - 2, 0))
    row, i0, t = _fenced(lambda *a: a, row, i0, f - i0)
    i1 = jnp.minimum(i0 + 1, P - 1)

    def sample(flat, r):  # linear in the pixel, clamped: _maps._sample's arithmetic
        g0 = flat[r * P + i0]
        return g0 + t * (flat[r * P + i1] - g0)

    a = jnp.clip(sample(flat_a, row), 0.0, 1.0)
    a_w = jnp.where(w == 1.0, a, jnp.where(w == 0.0, 0.0, 1.0 - jnp.sqrt(1.0 - a)))  # 1 − (1 − α)^w
    scale = jnp.where(a > 0, a_w / jnp.where(a > 0, a, 1.0), 0.0)
    re = jnp.stack([sample(flat_re, row * Lt + j) for j in range(Lt)], -1) * scale[..., None]
    front = geo["front"][..., None]
    return _fenced(
        lambda *a: (jnp.where(front, acc + trans[..., None] * re, re + (1.0 - a_w[..., None]) * acc), trans * (1.0 - a_w)), acc
    )


def sweep_track(ix: MapIndex, rows_re, rows_a, cs, by_sector: bool = False):
    """``layer_reads = "track"``: each texel's α and re from every sector its in-plane ray crosses in its track
    (:func:`track_window`), in both of its HSV's cross-sections, then eq 7's γ interpolation between them.  Rows:
    HSV h's top sector's at row h, its bottom sector's at row H + h (``fetch_kernel``'s with every HSV
    non-uniform), or with ``by_sector`` every sector's own row, (S, …) (``sweep_sectors``: no concatenation).
    Per cross-section, with weight w a sector's pixel gives α' = 1 − (1 − α)^w (its optical depth times w) and
    re' = re α'/α (re is α-premultiplied), composited along the ray front to back: α = 1 − Π(1 − α'),
    re = Σ re' Π_{before}(1 − α').

    Cost: the window and the composite are made once per entry (:func:`_track_layout`: a sector row's, shared
    by the texel rows on either side of it), each materialised (:func:`_fenced`), and a slot only when some
    entry's window reaches it (the paper-scale model's reach 4 of M = 6; compacting the entries that reach a
    slot, 21 % at slot 2, cost more than the slot itself: 10.7 against 4.7 CPU-ms).  Paper-scale model (53,040
    sectors, 208,896 texels, s_u = 16), loaded 2-core CPU, same run: 40–43 CPU-ms against eq 7's 7.6–8.5 (was
    246–401; ``benchmarks/track_cost.py``), of which the window's three atan2 are ~14; the vendored grooms'
    scenes: Sintel 1.3 against 1.25, Ratboy 4.2 against 5.1."""
    n_c, s_t, n_g, s_u = ix.grid
    Lt, P = rows_re.shape[1:]
    used, pos = _track_layout(ix)
    geo = _fenced(lambda ix, cs: track_window(ix, cs, used, by_sector), ix, cs)  # materialised before the gathers
    flat_re, flat_a, section = rows_re.reshape(-1), rows_a.reshape(-1), ix.track[:, 5:8]  # centre, extent
    n = geo["j0"].shape[0]
    acc, trans = jnp.zeros((n, Lt), jnp.float32), jnp.ones(n, jnp.float32)
    for m in range(geo["w"].shape[1]):

        def slot(state, m=m):
            return _track_slot(m, geo, *state, flat_a, flat_re, section, s_u, P)

        # a slot no window reaches is skipped (a weight-0 slot is an exact no-op: the same numbers either way)
        acc, trans = slot((acc, trans)) if m == 0 else jax.lax.cond(jnp.any(geo["last"] > m), slot, lambda s: s, (acc, trans))
    shape = (n_c, len(used), ix.layers, -1)
    ent = (acc.reshape(*shape, Lt), (1.0 - trans).reshape(shape))
    out = [[jnp.swapaxes(_take(x, pos[e], 1), 1, 2) for x in ent] for e in (0, 1)]
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


def view_rows(ix: MapIndex, db, view, lights, k_threshold: float):
    """Eq 6 and the SATF fetches of one view: :func:`sweep_rows`'s arguments after ``ix`` (device
    arrays) and the uniform mask (H,) on the host.  Two kernels: the uniformity test, then, with the
    few non-uniform HSVs compacted on the host (padded to a bucket size), the fetches.  The rows
    stay valid until the next view of ``ix``, which reuses their memory."""
    _, alpha, refl, _, _ = _device_db(db)
    f32 = partial(np.asarray, dtype=np.float32)  # NumPy in: a jnp conversion would dispatch a kernel per argument
    tv, tl, cs, _, uni = params_kernel(ix, f32(view), f32(lights), f32(k_threshold), n_v=len(db.theta_v), n_l=len(db.theta_l))
    if ix.reads == "track":  # the track read needs every sector's own row: no eq 6 shortcut
        uni = jnp.zeros_like(uni)
    uniform = np.asarray(uni)
    nu = np.flatnonzero(~uniform)
    slot = np.zeros(len(uniform), np.int32)
    slot[nu] = np.arange(nu.size)
    pad = np.zeros(_bucket(nu.size), np.int32)
    pad[: nu.size] = nu
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


def view_maps(ix: MapIndex, db, view, lights, k_threshold: float):
    """Eqs 6–7 of one view from the index: re, α as :func:`build_maps` (device arrays) and the uniform mask."""
    args, uniform = view_rows(ix, db, view, lights, k_threshold)
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
    axes = np.stack(
        [fr.ex[:, :1] * fr.reference + fr.ex[:, 1:] * fr.binormal, fr.ey[:, :1] * fr.reference + fr.ey[:, 1:] * fr.binormal]
    )
    rows, gamma, cols = _texel_cells(table.shape, resolution)
    f32 = partial(jnp.asarray, dtype=jnp.float32)
    none = jnp.zeros((0, 1), jnp.int32)
    return MapIndex(
        f32(axes),
        none,
        f32(none),
        f32(np.zeros(len(table.hsv_sectors))),
        none,
        f32(none),
        f32(gamma),
        f32(texel_offsets(table, fr, n_layers, resolution)[2]),
        (n_c, n_i - 1, n_g, s_u),
        int(n_layers),
        tuple(rows.tolist()),
        tuple(cols.tolist()),
        track,
        reads,
    )


@jax.jit
def sweep_sectors(ix: MapIndex, alpha, re, cs):
    """Eq 7 per texel from every sector's own rows, α (S, P) and re (S, Lt, P), two per HSV (its top and
    bottom sector; no eq 6 shortcut): re (C, K, Lt, n_t, n_u), α (C, K, n_t, n_u).  ``cs`` (S, 2): each
    sector's (cos θv, sin θv) from :func:`params_kernel`."""
    if ix.reads == "track":
        return sweep_track(ix, re, alpha, cs, by_sector=True)
    a1, a2 = _split(ix, alpha)
    r1, r2 = _split(ix, re)
    H = a1.shape[0]
    return sweep_rows(
        ix, jnp.concatenate([r1, r2]), jnp.concatenate([a1, a2]), cs, jnp.zeros(H, bool), jnp.arange(H, dtype=jnp.int32)
    )
