"""Direct sector maps: every sector's α and re at its own exact in-plane view and light angles.

The ``direct`` map method: instead of looking an HRIR up in a random database on
an angle grid (satf §6.2), each view traces every sector of the scene at the θv and θl it
actually sees (Params(b), satf §6.2.1), from its own density grid.  The result is the same
physical quantity the HRIR database stores (satf §5.1, eqs 4–5), computed with the planar
tracer's conventions (``hairlut.hrir``'s tracer module docstring) and its own march, normals and
Phong terms (``hairlut.hrir.march``, ``normals``, ``phong_direct``, …), so both trace the same rays:

* **Frame and pixels.**  The sector's local frame (+x the outward ellipse normal at its
  parametric centre c, +y the tangent of increasing phase); the image line through c
  perpendicular to the view direction d = (cos θv, sin θv), P pixels of width 2R/P over
  t ∈ [−R, R] along e = d rotated by +90°, R the sector's extent (the ``extent`` column of
  the geometry rows).  ``rays`` rays per pixel, box-averaged.
* **Opacity** (eq 4's α, Beer–Lambert).  Each ray marches from z = +R to z = −R in K midpoint
  steps of Δs = 2R/K through the bilinearly interpolated (cell-centre, clamped) density,
  zero outside the sector.  A step has α_k = 1 − exp(−σ_t ρ_k Δs), so the accumulated opacity
  is α = 1 − exp(−σ_t Σ ρ_k Δs): the line integral of the sector's own density projected on
  the pixel line at the exact view, to the midpoint rule's quadrature error.
* **Reflectance** re = k_a α + Σ_k w_k T_l,k (k_d max(0, n·l) + k_s max(0, r·d)^p [n·l > 0])
  (Phong, r = 2(n·l)n − l, n = −∇ρ/|∇ρ| by the chain rule through the parametric map, n = d
  where the gradient vanishes), with eq 5's front-to-back weights in closed form,
  w_k = α_k exp(−Σ_{i<k} σ_t ρ_i Δs) (0 once the transmittance falls below ``eps``), and
  T_l the in-sector transmittance toward each light (``shadow``: the optical depth traced
  from the light onto an M × M local grid, M = min(K, 128), sampled bilinearly).
* **Smoothing** (§5.1): both arrays convolved along the pixels with a Gaussian of σ_px
  pixels (the ``sigma_px`` column), normalised over the infinite line.
* **Oblique rays** (optional, ``path``/``light_path``).  The maps are in-plane (rays in the
  cross-section).  A camera ray at angle ψ_v to strands parallel to the layer's tangent ∂P/∂t
  crosses the same in-plane density over a path 1/sin ψ_v longer, ray by ray: its optical depth is
  τ_cam = σ_t (1/sin ψ_v) ∫ρ ds_in-plane (eq 4's Beer–Lambert along the camera ray, whose in-plane
  projection is the traced ray; exact where the density does not change along the tangent).  So the
  per-step depth of every ray is multiplied by the sector's factor *before* the steps are
  accumulated, the rays box-averaged to pixels and the pixels smoothed: the average of
  1 − exp(−τ/sin ψ) over the sector's actual strand positions, not a law for strands at
  independent random positions applied to the averaged α (``hairlut.render.strand_path``,
  Campbell).  ``light_path`` does the same for each light's in-sector transmittance (1/sin ψ_l).
  A factor of 1 gives the in-plane maps bit for bit.

What differs from ``hairlut.hrir.trace_sectors`` is the batching, not the quantity: one
jitted kernel takes N sectors each with its **own** view angle and its own L light angles
(``trace_sectors`` takes one set of V views and L lights shared by all sectors, so a scene's
truth had to be traced one sector at a time).  Empty sectors (all-zero density: α = re = 0
exactly) are dropped on the host and never reach the kernel.  The live sectors are padded to
a bucketed count (``block`` × 1, 2, 3, 4, 6, 8, …, or 8, 16, 32, … below one block) and mapped
``block`` at a time (vmapped inside a ``lax.map``), so a few compilations serve every view.
With ``L = 0`` lights (``theta_l`` of shape (N, 0)) only α is computed: no shading work.

Everything is float32; the one contraction (the weighted sum of the shading over the
steps) and the smoothing products state ``precision=HIGHEST`` so that a GPU (where XLA
would use TF32 otherwise) gives the CPU's answer.  Outputs are checked finite.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..validate import check_int
from ._march import (
    GEOM,
    SHADOW_GRID,
    exclusive_depth,
    front_to_back,
    grid_transmittance,
    light_depth_grid,
    march,
    normals,
    phong_direct,
    reflectance,
    sector_fields,
    smooth_matrix,
    to_pixels,
    view_points,
)

#: Sectors mapped at once inside the kernel (vmapped), by default.
BLOCK = 64

# columns of the geometry rows (hairlut.hrir.GEOM)
_PHASE, _DU, _V0, _V1, _ASPECT, _CX, _CY, _BETA, _EXTENT, _SIGMA_T, _SIGMA_PX = range(len(GEOM))


def _light_depth_at(fields, g, lights, n_steps: int, m: int, qx, qy):
    """Optical depth from each light to local points (qx, qy) (lanes, K), read straight from the light
    march's own (lane, step) lattice: (L, lanes, K).  One bilinear resampling instead of the tracer's two
    (march → Cartesian M × M grid → samples), and a third of the gathers for one view per sector."""
    tau, *_ = march(fields, g, lights, m, n_steps)
    depth = exclusive_depth(tau) + 0.5 * tau  # (L, m, K): to each step's midpoint, never negative
    L = lights.shape[0]
    R = g[_EXTENT]
    c, s = jnp.cos(lights)[:, None, None], jnp.sin(lights)[:, None, None]
    fi = jnp.clip(((-s * qx + c * qy) + R) / (2 * R) * m - 0.5, 0.0, m - 1.0)  # lane of the light march
    fj = jnp.clip((R - (c * qx + s * qy)) / (2 * R) * n_steps - 0.5, 0.0, n_steps - 1.0)  # its step
    i0 = jnp.clip(jnp.floor(fi).astype(jnp.int32), 0, m - 2)
    j0 = jnp.clip(jnp.floor(fj).astype(jnp.int32), 0, n_steps - 2)
    a, b = fi - i0, fj - j0
    quads = jnp.stack([depth[:, :-1, :-1], depth[:, 1:, :-1], depth[:, :-1, 1:], depth[:, 1:, 1:]], -1)
    quads = quads.reshape(L * (m - 1) * (n_steps - 1), 4)
    p = quads[(jnp.arange(L)[:, None, None] * (m - 1) + i0) * (n_steps - 1) + j0]  # one gather per point
    return (1 - a) * (1 - b) * p[..., 0] + a * (1 - b) * p[..., 1] + (1 - a) * b * p[..., 2] + a * b * p[..., 3]


def _direct_one(rho, g, view, lights, phong, path_v, path_l, *, n_pix, n_steps, rays, shadow, smooth, eps, shade):
    """α (P,) and premultiplied re (L, P) of one sector at view ``view`` () and lights ``lights`` (L,); the view's
    optical depth per step times ``path_v`` () and each light's times ``path_l`` (L,) (None: 1, the in-plane maps)."""
    fields = sector_fields(rho)
    lanes = n_pix * rays
    tau, gx, gy, rs, rr, inside = (x[0] for x in march(fields, g, view[None], lanes, n_steps))  # (lanes, K)
    if path_v is not None:  # per ray and step, before front_to_back and the pixel average (module docstring)
        tau = tau * path_v
    w, alpha = front_to_back(tau, eps)
    S = smooth_matrix(g[_SIGMA_PX], n_pix) if smooth else None
    alpha_px = to_pixels(alpha, n_pix, rays, S)
    if not shade:
        return alpha_px, jnp.zeros((1, n_pix), alpha_px.dtype)  # sliced to (0, P) outside the map
    vx, vy = jnp.cos(view), jnp.sin(view)
    nx, ny = normals(rho, gx, gy, rs, rr, inside, vx, vy)
    lx, ly = jnp.cos(lights)[:, None, None], jnp.sin(lights)[:, None, None]
    direct = phong_direct(nx[None], ny[None], vx, vy, lx, ly, phong)  # (L, lanes, K)
    if shadow:
        m = min(n_steps, SHADOW_GRID)
        if shadow == "grid":  # the tracer's: march → M × M Cartesian grid → samples
            depth = light_depth_grid(fields, g, lights, n_steps, m)  # (M, M, L)
            depth = depth if path_l is None else depth * path_l
            trans_l = grid_transmittance(depth, g, view[None], lanes, n_steps)[0]
            direct = direct * jnp.moveaxis(trans_l, -1, 0)
        else:  # "march": read the light march's lattice directly
            qx, qy = (q[0] for q in view_points(g, view[None], lanes, n_steps))
            depth = _light_depth_at(fields, g, lights, n_steps, m, qx, qy)  # (L, lanes, K)
            direct = direct * jnp.exp(-(depth if path_l is None else depth * path_l[:, None, None]))
    return alpha_px, to_pixels(reflectance(alpha, direct, w, phong), n_pix, rays, S)


@partial(jax.jit, static_argnames=("n_pix", "n_steps", "rays", "shadow", "smooth", "eps", "block", "shade"))
def direct_kernel(
    rho,
    geom,
    theta_v,
    theta_l,
    phong,
    path=None,
    light_path=None,
    *,
    n_pix: int,
    n_steps: int,
    rays: int = 1,
    shadow="march",
    smooth: bool = True,
    eps: float = 1e-4,
    block: int = BLOCK,
    shade: bool = True,
):
    """α (B, P) and premultiplied re (B, L, P) of B sectors, each at its own view and lights.

    ``rho`` (B, n_s, n_r), ``geom`` (B, 11) geometry rows (``hairlut.hrir.GEOM``), ``theta_v``
    (B,), ``theta_l`` (B, L), ``phong`` (4,) = (k_a, k_d, k_s, p); float32.  B must be a
    multiple of ``block`` (sectors vmapped together).  ``shadow``: False (no in-sector light
    transmittance), "grid" (the tracer's lookup: the light march resampled on an M × M Cartesian
    grid, then at the samples) or "march" (the light march's lattice read directly at the samples:
    one interpolation fewer, a third of the gathers).  ``shade=False``: α only (re is (B, 0, P);
    ``theta_l`` is then ignored and may be (B, 1)).  ``path`` (B,) and ``light_path`` (B, L): optional optical-path
    factors of the view's and the lights' rays (module docstring, "Oblique rays"); None: the in-plane maps.
    See the module docstring.
    """
    one = partial(_direct_one, n_pix=n_pix, n_steps=n_steps, rays=rays, shadow=shadow, smooth=smooth, eps=eps, shade=shade)
    alpha, re = jax.lax.map(
        lambda a: one(a[0], a[1], a[2], a[3], phong, a[4], a[5]),
        (rho, geom, theta_v, theta_l, path, light_path),
        batch_size=block,
    )
    return alpha, re if shade else re[:, :0]


# ---------------------------------------------------------------------------------------------
# host side: validation, empty-sector skipping, bucketing


def bucket(n: int, block: int) -> int:
    """Padded sector count for ``n`` live sectors: 8, 16, 32, … up to ``block``, then ``block`` × 1, 2, 3, 4, 6, 8, 12, …
    (at most a third more than needed, and few distinct shapes, so compilations are reused)."""
    if n <= 0:
        return 0
    if n <= block:
        return min(block, 1 << max(int(n) - 1, 7).bit_length())
    k = -(-int(n) // block)
    p = 1 << (k - 1).bit_length()  # the power of two ≥ k
    return (3 * p // 4 if 3 * p // 4 >= k else p) * block


SHADOW_LOOKUPS = ("march", "grid")


def _settings(recipe, n_pix, overrides, shadow_lookup="march") -> tuple[dict, np.ndarray]:
    if not isinstance(recipe, dict) or not isinstance(recipe.get("trace"), dict) or not isinstance(recipe.get("phong"), dict):
        raise errors.ValidationError("recipe", type(recipe).__name__, "need an HRIR recipe with 'trace' and 'phong' sections")
    tr, ph = recipe["trace"], recipe["phong"]
    try:
        cfg = {
            "n_pix": tr["pixels"],
            "n_steps": tr["steps"],
            "rays": tr["rays_per_pixel"],
            "shadow": tr["self_shadow"],
            "smooth": tr["smooth"],
            "eps": float(tr["termination"]),
        }
        phong = np.array([ph["ambient"], ph["diffuse"], ph["specular"], ph["shininess"]], np.float64)
    except KeyError as e:
        raise errors.ValidationError(f"recipe.{e.args[0]}", None, "missing from the recipe's trace/phong sections") from None
    if n_pix is not None:
        cfg["n_pix"] = n_pix
    unknown = set(overrides) - {"n_steps", "rays", "shadow", "smooth", "eps"}
    if unknown:
        raise errors.ValidationError(sorted(unknown)[0], overrides[sorted(unknown)[0]], "not a trace setting")
    cfg.update(overrides)
    for key, least in (("n_pix", 1), ("n_steps", 2), ("rays", 1)):
        cfg[key] = check_int(cfg[key], key, least)
    if shadow_lookup not in SHADOW_LOOKUPS:
        raise errors.ValidationError("shadow_lookup", shadow_lookup, f"one of {SHADOW_LOOKUPS}")
    cfg["shadow"], cfg["smooth"] = (shadow_lookup if cfg["shadow"] else False), bool(cfg["smooth"])
    if not (np.isfinite(cfg["eps"]) and 0 <= cfg["eps"] < 1):
        raise errors.ValidationError("eps", cfg["eps"], "the termination threshold is in [0, 1)")
    if not np.all(np.isfinite(phong)):
        raise errors.ValidationError("recipe.phong", phong.tolist(), "must be finite")
    return cfg, phong


def _check_paths(path, light_path, n: int, n_l: int):
    """``path`` (N,) and ``light_path`` (N, L) as float64 arrays (or None), finite and > 0."""
    out = []
    for name, x, shape in (("path", path, (n,)), ("light_path", light_path, (n, n_l))):
        if x is None:
            out.append(None)
            continue
        a = np.asarray(x, np.float64)
        if a.shape != shape:
            raise errors.ValidationError(
                name,
                a.shape,
                f"need shape {shape}: one optical-path factor per sector" + (" and light" if name == "light_path" else ""),
            )
        if not (np.all(np.isfinite(a)) and (a > 0).all()):
            raise errors.ValidationError(name, "non-finite or ≤ 0", "optical-path factors (1/sin ψ) are finite and > 0")
        out.append(a)
    return out


def _check_inputs(density, geometry, theta_v, theta_l):
    rho = np.asarray(density)
    if rho.ndim != 3:
        raise errors.ValidationError("density", rho.shape, "need shape (N, n_s, n_r)")
    if rho.dtype.kind not in "fiu" or not np.all(np.isfinite(rho)) or (rho < 0).any():
        raise errors.ValidationError("density", "non-finite or < 0", "densities must be finite and ≥ 0")
    n = rho.shape[0]
    g = np.asarray(geometry, np.float64)
    n_geom = len(GEOM)
    if g.shape != (n, n_geom):
        raise errors.ValidationError("geometry", g.shape, f"need shape ({n}, {n_geom}): one hrir.GEOM row per sector")
    if not np.all(np.isfinite(g)):
        raise errors.ValidationError("geometry", "non-finite", "geometry rows must be finite")
    if not (
        (g[:, _EXTENT] > 0).all()
        and (g[:, _SIGMA_T] >= 0).all()
        and (g[:, _SIGMA_PX] >= 0).all()
        and (g[:, _ASPECT] > 0).all()
        and (g[:, _V1] > g[:, _V0]).all()
        and (g[:, _DU] > 0).all()
    ):
        raise errors.ValidationError("geometry", "bad row", "need extent > 0, σ_t ≥ 0, σ_px ≥ 0, aspect > 0, v1 > v0, Δu > 0")
    tv = np.asarray(theta_v, np.float64)
    if tv.shape != (n,):
        raise errors.ValidationError("theta_v", tv.shape, f"need shape ({n},): one view angle per sector")
    if not np.all(np.isfinite(tv)):
        raise errors.ValidationError("theta_v", "non-finite", "angles must be finite")
    tl = np.asarray(theta_l, np.float64)
    if tl.ndim != 2 or tl.shape[0] != n:
        raise errors.ValidationError("theta_l", tl.shape, f"need shape ({n}, L): the light angles of each sector")
    if not np.all(np.isfinite(tl)):
        raise errors.ValidationError("theta_l", "non-finite", "angles must be finite")
    return rho, g, tv, tl


def direct_sector_maps(
    density,
    geometry,
    theta_v,
    theta_l,
    recipe: dict,
    *,
    n_pix: int | None = None,
    block: int = BLOCK,
    shadow_lookup: str = "march",
    path=None,
    light_path=None,
    **overrides,
) -> tuple[np.ndarray, np.ndarray]:
    """α (N, P) and premultiplied re (N, L, P) of N sectors, each at its own exact angles (one jitted kernel).

    ``density`` (N, n_s, n_r) sector density grids (``hairlut.geometry.sector_density``);
    ``geometry`` (N, 11) rows of ``hairlut.hrir.GEOM`` (``hairlut.hrir.sector_geometry``, or
    :func:`scene_sector_inputs` for a scene), built for the same pixel count (σ_px is in
    pixels); ``theta_v`` (N,) and ``theta_l`` (N, L) in-plane azimuths of the view and the
    lights in each sector's local frame (Params(b), ``hairlut.geometry.azimuths``), reduced
    mod 2π in float64 first; ``recipe`` an HRIR recipe (its ``trace`` and ``phong`` sections:
    pixels, steps, rays_per_pixel, self_shadow, smooth, termination, and the Phong k_a, k_d,
    k_s, p).  ``overrides`` replace trace settings (n_steps, rays, shadow, smooth, eps), as in
    ``hairlut.hrir.trace_sectors``; with the same settings (and ``shadow_lookup="grid"``, the
    tracer's resampling of the light depth) the two agree to float32 rounding.  The default
    ``shadow_lookup="march"`` reads each light's march directly at the view samples (one
    bilinear resampling instead of two; cheaper, and differs from the tracer only by that).
    ``block``: sectors vmapped together (larger for a GPU).  ``path`` (N,) and ``light_path`` (N, L): the
    optical-path factors of the view's and each light's rays through each sector (1/sin ψ, ψ the ray's angle to
    the strands: module docstring, "Oblique rays"), applied per ray and step; None (the default): in-plane maps.

    Satf eq 4 (α, here Beer–Lambert of the line integral of ρ) and eq 5 (front-to-back
    accumulation of re); the conventions are the tracer's (module docstring).  Sectors whose
    density is all zero get α = re = 0 exactly and cost nothing.  Raises
    :class:`hairlut.errors.ValidationError` naming the argument for bad shapes or values, and
    :class:`hairlut.errors.HairlutError` if the kernel's output is not finite.
    """
    cfg, phong = _settings(recipe, n_pix, overrides, shadow_lookup)
    block = check_int(block, "block", 1)
    rho, g, tv, tl = _check_inputs(density, geometry, theta_v, theta_l)
    n, n_l, P = rho.shape[0], tl.shape[1], cfg["n_pix"]
    pv, pl = _check_paths(path, light_path, n, n_l)
    alpha = np.zeros((n, P), np.float32)
    re = np.zeros((n, n_l, P), np.float32)
    live = np.flatnonzero(rho.reshape(n, -1).max(axis=1, initial=0.0) > 0) if n else np.zeros(0, np.int64)
    if live.size == 0:
        return alpha, re
    size = bucket(live.size, block)
    rows = np.concatenate([live, np.full(size - live.size, live[0])])  # pad with a copy of a live sector
    two_pi = 2.0 * np.pi
    a, r = direct_kernel(
        jnp.asarray(rho[rows], jnp.float32),
        jnp.asarray(g[rows], jnp.float32),
        jnp.asarray(np.mod(tv[rows], two_pi), jnp.float32),
        jnp.asarray(np.mod(tl[rows] if n_l else np.zeros((size, 1)), two_pi), jnp.float32),
        jnp.asarray(phong, jnp.float32),
        None if pv is None else jnp.asarray(pv[rows], jnp.float32),
        None if pl is None or not n_l else jnp.asarray(pl[rows], jnp.float32),
        block=min(block, size),
        shade=n_l > 0,
        **cfg,
    )
    a, r = np.asarray(a)[: live.size], np.asarray(r)[: live.size]
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(r))):
        raise errors.HairlutError("direct_sector_maps: the kernel produced non-finite maps (check the density scale)")
    alpha[live], re[live] = a, r
    return alpha, re


# ---------------------------------------------------------------------------------------------
# a scene's sectors as kernel inputs


def sector_extent(table, n_edge: int = 9) -> np.ndarray:
    """(N,) extent R of every sector of a :class:`~hairlut.geometry.SectorTable` in metric units:
    the largest distance from its parametric centre to ``n_edge`` points on each of its four
    edges — the extent the online texels' pixel coordinates use (``SectorFrames.extent``)."""
    ab, q = np.asarray(table.half_axes, np.float64), np.asarray(table.twist, np.float64)
    vr, ur = np.asarray(table.v_range, np.float64), np.asarray(table.u_range, np.float64)

    def ellipse(v, phi):
        return np.stack([ab[:, None, 0] * v * np.cos(phi), ab[:, None, 1] * v * np.sin(phi)], axis=-1)

    centre = ellipse(vr.mean(axis=1)[:, None], (q + ur.mean(axis=1))[:, None])[:, 0]
    w = np.linspace(0.0, 1.0, n_edge)
    v0, v1 = vr[:, :1], vr[:, 1:]
    u0, u1 = ur[:, :1] + q[:, None], ur[:, 1:] + q[:, None]
    ua, va = u0 + (u1 - u0) * w, v0 + (v1 - v0) * w
    edges = np.concatenate([ellipse(v0, ua), ellipse(v1, ua), ellipse(va, u0), ellipse(va, u1)], axis=1)
    return np.linalg.norm(edges - centre[:, None], axis=-1).max(axis=1)


def scene_sector_inputs(table, recipe: dict, *, extent=None, n_pix: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``density`` (N, n_s, n_r) and ``geometry`` (N, 11) of a scene's sectors for :func:`direct_sector_maps`.

    ``table``: a :class:`~hairlut.geometry.SectorTable` (one cluster's, as ``prepare`` builds);
    ``recipe``: an HRIR recipe (its ``sectors.grid``, ``sectors.density_scale``,
    ``trace.extinction``, ``trace.pixels``, ``trace.smooth_ratio``); ``extent`` (N,) the
    metric extent the texels use (``SectorFrames.extent``; :func:`sector_extent` by default).

    The density is the sector's own strands splatted on its parametric grid
    (``hairlut.geometry.sector_density``).  The geometry rows describe the metric sector
    (A x, B y) scaled by 1/A — the tracer's (1, B/A) ellipse, with the same angles — with
    phase = twist + u0, Δu, (v0, v1), aspect B/A, the strand radius (the mean of the sector's
    splat radii, or the table's median crossing radius for an empty sector) relative to
    √area, and the extent R/A, so pixel p of the image line is the same point the texels of
    ``texels`` read; σ_px is rescaled with the extent, keeping its metric width.
    """
    from ..geometry.density import sector_density
    from ._geometry import sector_geometry
    from ._march import GEOM

    try:
        grid = tuple(recipe["sectors"]["grid"])
        scale = float(recipe["sectors"]["density_scale"])
        tr = recipe["trace"]
        kappa, pixels, ratio = tr["extinction"], tr["pixels"] if n_pix is None else n_pix, tr["smooth_ratio"]
    except (KeyError, TypeError) as e:
        raise errors.ValidationError(
            "recipe", type(recipe).__name__, f"need an HRIR recipe with sectors.grid, sectors.density_scale and trace ({e})"
        ) from None
    pixels = check_int(pixels, "n_pix", 1)
    splats = table.splats()
    density = sector_density(splats, grid, density_scale=scale)
    (a, b), du = np.asarray(table.half_axes, np.float64).T, table.u_range[:, 1] - table.u_range[:, 0]
    # the strands' own radius (σ_t = κ / r; the splats' discs are widened for tilt): an empty sector takes the
    # median crossing radius; with no crossing at all any radius will do (no density)
    r = table.sector_radius(None if table.crossing_radius.size else np.sqrt(splats.sector_areas()) / 20)
    params = {
        "phase": table.twist + table.u_range[:, 0],
        "s_u": 2 * np.pi / du,
        "v_range": table.v_range,
        "aspect": b / a,
        "radius_rel": r / np.sqrt(splats.sector_areas()),
    }
    geometry = sector_geometry(params, kappa=kappa, n_pix=pixels, smooth_ratio=ratio)
    ext = sector_extent(table) if extent is None else np.asarray(getattr(extent, "extent", extent), np.float64)
    if ext.shape != (len(geometry),) or not (np.isfinite(ext).all() and (ext > 0).all()):
        raise errors.ValidationError("extent", ext.shape, f"need ({len(geometry)},) finite extents > 0")
    ext = ext / a
    col_e, col_s = GEOM.index("extent"), GEOM.index("sigma_px")
    geometry[:, col_s] *= geometry[:, col_e] / ext
    geometry[:, col_e] = ext
    return density, geometry
