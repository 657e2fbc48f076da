"""re-maps and α-maps of every layer from the SATF (satf §6.2, eqs 6–7).

**Parameters** (§6.2.1).  Each boundary sector b of an HSV gets Params(b) =
(ρ_feature, θv, θl): its density features (the database's feature set, grid and density
scale) and the view and light directions projected into the cross-section's normal plane,
as azimuths from the sector's local +x axis (the outward ellipse normal at its parametric
centre; +y the tangent of increasing phase — the tracer's frame, ``hairlut.hrir._tracer``).

**Uniformity** (eq 6) is tested in a normalised parameter space: features as
z = (x − mean)/std with the database's statistics, angles as the wrapped difference over
the database's grid step (2π/V for θv, 2π/L for θl), so one unit is one standard
deviation of a feature or one cell of the angle grid:
‖Params(b⊤) − Params(b⊥)‖ = √(Σ Δz² + (Δθv/δv)² + Σ_lights (Δθl/δl)²) < k_threshold.

**Fetches.**  A uniform HSV fetches one HRIR at Params_ave (features averaged, angles by
their wrapped mid-point); a non-uniform one uses its two boundary sectors' HRIRs (each
sector is fetched once, however many HSVs share it).  Only what is needed is fetched.

**Patching** (§6.2.2).  Texel (i, j) of layer k's (u, t) texture (u = 2π(j + ½)/n_u,
t = (i + ½)/n_t; the layer meshes' uv) lies in HSV (⌊t s_t⌋, k, ⌊u s_u/2π⌋) at
γ = t s_t − ⌊t s_t⌋ along it.  Its point on the layer surface, projected on a sector's
image line (perpendicular to the in-plane view), gives the pixel it reads in that
sector's HRIR: x = (p − c)·e / R ∈ [−1, 1], pixel (x + 1) P/2 − ½, sampled linearly.
Non-uniform: l = (1 − γ)·HRIR⊤[x⊤] + γ·HRIR⊥[x⊥] (eq 7); uniform: HRIR_ave swept along
the HSV at x̄ = (x⊤ + x⊥)/2.

**Two implementations.**  :func:`sector_angles`, :func:`texels`, :func:`fetch` and
:func:`build_maps` are the reference: NumPy, a k-NN search per fetch.  The per-view path
splits the work as the paper's index does: :func:`map_index` (once per scene) keeps what
does not change with the view or the lights (the SATF neighbours and weights of every
sector and of every HSV's averaged features, eq 6's feature term, each texel's offsets in
its sectors' frames), and :func:`view_maps` runs a view in three jitted kernels:
:func:`params_kernel` (angles, eq 6), :func:`fetch_kernel` (one HRIR row per HSV, a second
for the non-uniform ones, compacted on the host) and :func:`sweep_rows` (eq 7).  They stay
separate kernels because XLA:CPU otherwise fuses each row's gathers into every consumer
and recomputes them per texel (measured 3–8× slower).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..geometry.density import sector_density, sector_mean_density
from ..geometry.features import PROJECTION, sector_features
from ..geometry.inplane import TWO_PI, azimuths, sector_axes
from ..hrir import projection_features, query_kernel
from ..march import scene_sector_inputs, sector_extent


def wrap(x):
    """Angle differences wrapped to [−π, π)."""
    return np.mod(np.asarray(x) + np.pi, TWO_PI) - np.pi


@dataclass(frozen=True, eq=False)
class SectorFrames:
    """What does not change with the view or the lights, per sector (N): ``features`` (N, F),
    the 2-D normal-plane frame ``centre``, ``ex``, ``ey`` (N, 2) in (reference, binormal)
    coordinates, ``extent`` R (N,), ``half_axes`` (N, 2), ``twist`` (N,), outer radius
    ``v_outer`` (N,), the 3-D ``reference`` and ``binormal`` (N, 3) of its cross-section, and
    ``occupied`` (N,): whether any strand crosses it (an empty sector holds no hair: α = re = 0), and its
    track's inner radius ``v_inner`` (N,) (the track read, ``_view.sweep_track``)."""

    features: np.ndarray
    centre: np.ndarray
    ex: np.ndarray
    ey: np.ndarray
    extent: np.ndarray
    half_axes: np.ndarray
    twist: np.ndarray
    v_outer: np.ndarray
    reference: np.ndarray
    binormal: np.ndarray
    occupied: np.ndarray
    v_inner: np.ndarray


@dataclass(frozen=True, eq=False)
class SectorParams:
    """Params(b) of every sector: its :class:`SectorFrames` plus ``theta_v`` (N,) and ``theta_l`` (N, Lt)."""

    frames: SectorFrames
    theta_v: np.ndarray
    theta_l: np.ndarray

    def __getattr__(self, name):  # the frame's fields read through
        if name == "frames":
            raise AttributeError(name)
        return getattr(self.frames, name)


def _ellipse(ab, v, phi):
    return np.stack([ab[..., 0] * v * np.cos(phi), ab[..., 1] * v * np.sin(phi)], axis=-1)


def sector_frames(geometry, table, db) -> SectorFrames:
    """Features (in the database's feature set, grid and density scale) and frames of every sector.

    A ``projection``-indexed database's features are each sector's own density grid projected with
    the tracer's march in its own geometry rows (``scene_sector_inputs``, at the extent the texels
    use), scored on the database's stored basis (``hairlut.hrir.projection_features``).  A ``db`` marked
    ``geometry_only`` (the map methods that read no database: ``hairlut.synth``'s ``_geometry_db``) keeps its one
    feature, ``rho_st``, from the splats without a density grid (``hairlut.geometry.density.sector_mean_density``:
    the same value to float32 rounding, at a fraction of the cost on a large groom)."""
    names = tuple(db.stats.names)
    if any(n.startswith("pc") for n in names):
        raise errors.ValidationError("db.features", names, "principal-component features need the bake's PCA basis")
    rec = db.recipe.get("sectors", {})
    grid = tuple(rec.get("grid", (32, 32)))
    extent = sector_extent(table)
    occupied = np.diff(table.splat_offsets) > 0  # a sector any splat reaches
    if getattr(db, "geometry_only", False) and names == ("rho_st",):  # no database: its one feature, without a grid
        feats = sector_mean_density(table, density_scale=float(rec.get("density_scale", 1.0)))[:, None]
    elif names == PROJECTION:
        feats = projection_features(db, *scene_sector_inputs(table, db.recipe, extent=extent))
    else:
        splats = table.splats()
        dens = sector_density(splats, grid, density_scale=float(rec.get("density_scale", 1.0)))
        feats = sector_features(dens, splats, names)
    reference, binormal, ex, ey = sector_axes(geometry, table)
    ab, q = table.half_axes, table.twist
    centre = _ellipse(ab, table.v_range.mean(axis=1), q + table.u_range.mean(axis=1))
    return SectorFrames(
        feats,
        centre,
        ex,
        ey,
        extent,
        ab,
        q,
        table.v_range[:, 1].copy(),
        reference,
        binormal,
        occupied,
        table.v_range[:, 0].copy(),
    )


def sector_angles(fr: SectorFrames, view, lights) -> SectorParams:
    """Params(b) angles (:func:`azimuths`) of every sector with its frames."""
    return SectorParams(fr, *azimuths(fr.reference, fr.binormal, fr.ex, fr.ey, view, lights))


def sector_params(geometry, table, view, lights, db) -> SectorParams:
    """Params(b) of every sector of ``table`` (a :class:`~hairlut.geometry.SectorTable`)."""
    return sector_angles(sector_frames(geometry, table, db), view, lights)


def param_distance(db, features_a, tv_a, tl_a, features_b, tv_b, tl_b) -> np.ndarray:
    """Eq 6's ‖Params(a) − Params(b)‖ in the normalised space (module docstring)."""
    std = np.where(db.stats.std > 0, db.stats.std, 1.0)
    dz = (np.asarray(features_a) - np.asarray(features_b)) / std
    dv = wrap(np.asarray(tv_a) - tv_b) / (TWO_PI / len(db.theta_v))
    dl = wrap(np.asarray(tl_a) - tl_b) / (TWO_PI / len(db.theta_l))
    return np.sqrt(np.sum(dz**2, -1) + dv**2 + np.sum(dl**2, -1))


@dataclass(frozen=True, eq=False)
class Texels:
    """Per texel (C, K, n_t, n_u): its HSV ``hsv``, ``gamma`` along it, and the float pixel
    index it reads in the top, bottom and averaged HRIR (``pix_top``, ``pix_bot``, ``pix_ave``)."""

    hsv: np.ndarray
    gamma: np.ndarray
    pix_top: np.ndarray
    pix_bot: np.ndarray
    pix_ave: np.ndarray
    u: np.ndarray
    t: np.ndarray


def texel_grid(resolution) -> tuple[np.ndarray, np.ndarray]:
    """Texel centres of an (n_u, n_t) layer texture: u = 2π(j + ½)/n_u (n_u,), t = (i + ½)/n_t (n_t,)."""
    n_u, n_t = resolution
    return TWO_PI * (np.arange(n_u) + 0.5) / n_u, (np.arange(n_t) + 0.5) / n_t


def _texel_cells(shape, resolution):
    """HSV row and γ along it of each texel row i (n_t,), HSV column of each texel column j (n_u,)."""
    s_t, s_u = shape[1] - 1, shape[3]
    u, t = texel_grid(resolution)
    row = np.minimum(np.floor(t * s_t).astype(np.int64), s_t - 1)
    return row, t * s_t - row, np.minimum(np.floor(u / (TWO_PI / s_u)).astype(np.int64), s_u - 1)


def texel_offsets(table, fr: SectorFrames, n_layers: int, resolution):
    """The view-independent part of :func:`texels`: per texel (C, K, n_t, n_u) its ``hsv`` and
    ``gamma``, and for its top and bottom sector b (axis 0) the offset of its layer-surface point
    p from the sector's centre in the sector's frame, ((p − c)·ex, (p − c)·ey) / R (axis 1), so
    that x = −sin θv · dx + cos θv · dy on the image line of the view's azimuth θv."""
    n_u, n_t = resolution
    n_c, n_i, n_g, s_u = table.shape
    s_t = n_i - 1
    u, _ = texel_grid(resolution)
    row, gamma_t, col = _texel_cells(table.shape, resolution)
    c, k, i, j = np.meshgrid(np.arange(n_c), np.arange(n_layers), np.arange(n_t), np.arange(n_u), indexing="ij")
    hsv = ((c * s_t + row[i]) * n_g + k) * s_u + col[j]

    def offset(b):
        d = _ellipse(fr.half_axes[b], fr.v_outer[b], fr.twist[b] + u[j]) - fr.centre[b]
        return np.stack([np.sum(d * fr.ex[b], -1), np.sum(d * fr.ey[b], -1)]) / fr.extent[b]

    return hsv, gamma_t[i], np.stack([offset(table.hsv_sectors[hsv, e]) for e in (0, 1)])


def texels(table, sp: SectorParams, n_layers: int, resolution, n_pixels: int) -> Texels:
    """Texel → HSV, γ and pixel coordinates (module docstring) for every layer of every cluster."""
    hsv, gamma, off = texel_offsets(table, sp.frames, n_layers, resolution)

    def pix(e):
        th = sp.theta_v[table.hsv_sectors[hsv, e]]
        x = -np.sin(th) * off[e, 0] + np.cos(th) * off[e, 1]
        return (x + 1.0) * n_pixels / 2.0 - 0.5

    top, bot = pix(0), pix(1)
    u, t = texel_grid(resolution)
    return Texels(hsv, gamma, top, bot, 0.5 * (top + bot), u, t)


def _bucket(n: int) -> int:
    return max(64, 1 << (max(n, 1) - 1).bit_length())


_DEVICE: dict[int, tuple] = {}


def _device_db(db):
    """The database's normalised features and tables as device arrays, converted once per database
    (``satf_query`` converts them on every call; a default database's reflectance is ~130 MB)."""
    hit = _DEVICE.get(id(db))
    if hit is not None and hit[0] is db:
        return hit[1]
    std = np.where(db.stats.std > 0, db.stats.std, 1.0)  # as satf_query: a constant feature carries no distance
    arrays = ((db.features - db.stats.mean) / std, db.alpha, db.reflectance)
    dev = tuple(jnp.asarray(a, jnp.float32) for a in arrays) + (db.stats.mean, std)
    if len(_DEVICE) >= 4:
        _DEVICE.pop(next(iter(_DEVICE)))
    _DEVICE[id(db)] = (db, dev)
    return dev


def _check_k(db, k):
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= len(db.features):
        raise errors.ValidationError("k", k, f"need 1 ≤ k ≤ {len(db.features)} (database size)")


def fetch(db, features, theta_v, theta_l, k: int):
    """SATF at (M,) parameter rows × Lt lights → re (M, Lt, P), α (M, P): ``satf_query``'s kernel
    and normalisation on cached device arrays, padded to a bucket size so it compiles for few shapes."""
    m, n_l = len(features), theta_l.shape[1]
    P = db.alpha.shape[-1]
    if m == 0:
        return np.zeros((0, n_l, P), np.float32), np.zeros((0, P), np.float32)
    _check_k(db, k)
    zdb, alpha, refl, mean, std = _device_db(db)
    pad = _bucket(m) - m
    idx = np.concatenate([np.arange(m), np.zeros(pad, np.int64)])
    z = np.repeat((features[idx] - mean) / std, n_l, axis=0)
    tv = np.repeat(theta_v[idx], n_l)
    re, a, _, _ = query_kernel(
        jnp.asarray(z, jnp.float32),
        jnp.asarray(tv, jnp.float32),
        jnp.asarray(theta_l[idx].ravel(), jnp.float32),
        zdb,
        alpha,
        refl,
        int(k),
    )
    re = np.asarray(re).reshape(len(idx), n_l, P)
    return re[:m], np.asarray(a).reshape(len(idx), n_l, P)[:m, 0]


def _sample(flat, row, p, P: int):
    """Rows of P pixels, flattened, sampled at float pixel p of row ``row``: linear in the pixel, clamped."""
    f = jnp.clip(p, 0.0, P - 1.0)
    i0 = jnp.clip(jnp.floor(f).astype(jnp.int32), 0, max(P - 2, 0))
    g0 = flat[row * P + i0]
    return g0 + (f - i0) * (flat[row * P + jnp.minimum(i0 + 1, P - 1)] - g0)


@jax.jit
def sweep_kernel(re1, re2, a1, a2, hsv, gamma, pix1, pix2):
    """Eq 7 per texel: (1 − γ)·HRIR1[pix1] + γ·HRIR2[pix2] (linear in the pixel, clamped);
    re (T, Lt) and α (T,) from per-HSV arrays re (H, Lt, P), α (H, P)."""
    (Lt, P), g = re1.shape[1:], gamma[:, None]
    rows = hsv[:, None] * Lt + jnp.arange(Lt)
    re = (1 - g) * _sample(re1.reshape(-1), rows, pix1[:, None], P) + g * _sample(re2.reshape(-1), rows, pix2[:, None], P)
    a = (1 - gamma) * _sample(a1.reshape(-1), hsv, pix1, P) + gamma * _sample(a2.reshape(-1), hsv, pix2, P)
    return re, jnp.clip(a, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class Maps:
    """``re`` (C, K, Lt, n_t, n_u) per light, ``alpha`` (C, K, n_t, n_u), ``uniform`` (H,) per HSV,
    ``distance`` (H,) of eq 6, and ``fetches``: HRIRs fetched (averaged + sector records)."""

    re: np.ndarray
    alpha: np.ndarray
    uniform: np.ndarray
    distance: np.ndarray
    fetches: int


def build_maps(db, table, sp: SectorParams, tx: Texels, k_threshold: float, k: int = 4) -> Maps:
    """Eqs 6–7 for every HSV, then patch the re- and α-maps (module docstring)."""
    top, bot = table.hsv_sectors[:, 0], table.hsv_sectors[:, 1]
    dist = param_distance(
        db, sp.features[top], sp.theta_v[top], sp.theta_l[top], sp.features[bot], sp.theta_v[bot], sp.theta_l[bot]
    )
    occ = np.asarray(sp.occupied, bool)
    uniform = (dist < k_threshold) & (occ[top] == occ[bot])  # a half-empty HSV sweeps its two ends (one of them 0)
    uh = np.flatnonzero(uniform)
    ave_f = 0.5 * (sp.features[top[uh]] + sp.features[bot[uh]])
    ave_v = sp.theta_v[top[uh]] + 0.5 * wrap(sp.theta_v[bot[uh]] - sp.theta_v[top[uh]])
    ave_l = sp.theta_l[top[uh]] + 0.5 * wrap(sp.theta_l[bot[uh]] - sp.theta_l[top[uh]])
    re_u, a_u = fetch(db, ave_f, ave_v, ave_l, k)
    need = np.unique(np.concatenate([top[~uniform], bot[~uniform]]))
    re_s, a_s = fetch(db, sp.features[need], sp.theta_v[need], sp.theta_l[need], k)
    slot = np.full(len(sp.features), -1)
    slot[need] = np.arange(need.size)
    H, Lt, P = len(top), sp.theta_l.shape[1], db.alpha.shape[-1]
    re1, re2 = np.zeros((H, Lt, P), np.float32), np.zeros((H, Lt, P), np.float32)
    a1, a2 = np.zeros((H, P), np.float32), np.zeros((H, P), np.float32)
    nu = np.flatnonzero(~uniform)
    re_u, a_u = re_u * occ[top[uh], None, None], a_u * occ[top[uh], None]  # empty sectors hold no hair: 0
    re_s, a_s = re_s * occ[need, None, None], a_s * occ[need, None]
    re1[uh], re2[uh], a1[uh], a2[uh] = re_u, re_u, a_u, a_u
    re1[nu], a1[nu] = re_s[slot[top[nu]]], a_s[slot[top[nu]]]
    re2[nu], a2[nu] = re_s[slot[bot[nu]]], a_s[slot[bot[nu]]]
    hsv = tx.hsv.ravel()
    uni = uniform[hsv]
    pix1 = np.where(uni, tx.pix_ave.ravel(), tx.pix_top.ravel())
    pix2 = np.where(uni, tx.pix_ave.ravel(), tx.pix_bot.ravel())
    re, a = sweep_kernel(
        *(jnp.asarray(x) for x in (re1, re2, a1, a2)),
        jnp.asarray(hsv, jnp.int32),
        jnp.asarray(tx.gamma.ravel(), jnp.float32),
        jnp.asarray(pix1, jnp.float32),
        jnp.asarray(pix2, jnp.float32),
    )
    shape = tx.hsv.shape
    re = np.moveaxis(np.asarray(re).reshape(shape + (Lt,)), -1, 2)
    return Maps(re, np.asarray(a).reshape(shape), uniform, dist, int(uh.size + need.size))
