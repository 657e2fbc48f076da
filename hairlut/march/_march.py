"""The planar march through one sector's density (satf §5.1): the pieces that the HRIR tracer, the
direct map method and the scene table's view-grid bake share, so that all three trace the same rays.

Conventions (local frame, pixels, opacity, reflectance, accumulation, self-shadowing, smoothing)
are the tracer's: ``hairlut.hrir._tracer``'s module docstring.  Per-sector geometry rows hold the
columns :data:`GEOM`.  Everything here is float32 JAX meant to run inside one of the callers'
jitted kernels; contractions state ``precision=HIGHEST``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

HIGHEST = jax.lax.Precision.HIGHEST  # stated, not inherited: XLA would use TF32 on NVIDIA GPUs

#: Largest side M of the Cartesian shadow grid (M = min(steps, SHADOW_GRID)).
SHADOW_GRID = 128

#: Columns of the per-sector geometry rows.
GEOM = ("phase", "du", "v0", "v1", "aspect", "cx", "cy", "beta", "extent", "sigma_t", "sigma_px")
PHASE, DU, V0, V1, ASPECT, CX, CY, BETA, EXTENT, SIGMA_T, SIGMA_PX = range(len(GEOM))


def fence(fn, *args):
    """fn(*args), materialised once: both branches of a ``lax.cond`` are fn, so the result is the same whichever
    runs, and XLA cannot fuse fn's work into its consumers.  XLA:CPU drops ``optimization_barrier`` and fuses a
    producer into each consumer, recomputing it there: a gather fused with its index arithmetic (atan2, sqrt)
    recomputes that arithmetic per gathered value (``hairlut.synth._view._fenced`` does the same for a view's maps)."""
    lead = jnp.ravel(jax.tree_util.tree_leaves(args)[0])[0]
    return jax.lax.cond(lead == lead, fn, fn, *args)


def atan2(y, x):
    """arctan2(y, x) in float32 arithmetic that vectorises: XLA:CPU calls the scalar libm atan2f per element (30 ns;
    it was 8 of the scene bake's 39 CPU-ms per paper-model sector), this is ~4 ns.  Octant reduction to
    t = min/max(|x|, |y|) ≤ 1, then t > tan(π/8) → (t − 1)/(t + 1) + π/4, and Cephes' atanf polynomial (S. L. Moshier,
    |error| ≈ 1e-7 on [−tan(π/8), tan(π/8)]); measured against float64 arctan2 on 8.4 M normal pairs: 2.7e-7 rad at
    most (jnp.arctan2: 2.5e-7).  Signed zeros as arctan2's (atan2(±0, −0) = ±π)."""
    ax, ay = jnp.abs(x), jnp.abs(y)
    steep = ay > ax
    num, den = jnp.where(steep, ax, ay), jnp.where(steep, ay, ax)
    t = num / jnp.where(den > 0, den, 1.0)
    hi = t > 0.41421356237309503  # tan(π/8)
    u = jnp.where(hi, (t - 1) / (t + 1), t)
    z = u * u
    a = (((8.05374449538e-2 * z - 1.38776856032e-1) * z + 1.99777106478e-1) * z - 3.33329491539e-1) * z * u + u
    a = jnp.where(hi, a + jnp.pi / 4, a)
    a = jnp.where(steep, jnp.pi / 2 - a, a)
    a = jnp.where(jnp.signbit(x), jnp.pi - a, a)
    return jnp.where(jnp.signbit(y), -a, a)


def bilerp_nodes(grid, fi, fj):
    """Bilinear interpolation of ``grid`` (n, m, ...) at fractional cell-centre indices (clamped)."""
    n, m = grid.shape[:2]
    fi = jnp.clip(fi, 0.0, n - 1.0)
    fj = jnp.clip(fj, 0.0, m - 1.0)
    i0 = jnp.clip(jnp.floor(fi).astype(jnp.int32), 0, max(n - 2, 0))
    j0 = jnp.clip(jnp.floor(fj).astype(jnp.int32), 0, max(m - 2, 0))
    i1 = jnp.minimum(i0 + 1, n - 1)
    j1 = jnp.minimum(j0 + 1, m - 1)
    a = fi - i0
    b = fj - j0
    if grid.ndim > 2:
        a = a[..., None]
        b = b[..., None]
    return (1 - a) * (1 - b) * grid[i0, j0] + a * (1 - b) * grid[i1, j0] + (1 - a) * b * grid[i0, j1] + a * b * grid[i1, j1]


def patches(grid):
    """(n−1, m−1, 4·c) corner values of every cell-centre quad, so bilinear lookups gather once."""
    g = grid if grid.shape[0] > 1 else jnp.concatenate([grid, grid], axis=0)
    g = g if g.shape[1] > 1 else jnp.concatenate([g, g], axis=1)
    return jnp.concatenate([g[:-1, :-1], g[1:, :-1], g[:-1, 1:], g[1:, 1:]], axis=-1)


def bilerp_patch(patches, fi, fj):
    """Bilinear interpolation from :func:`patches` at fractional cell-centre indices (clamped)."""
    n, m, c4 = patches.shape
    c = c4 // 4
    fi = jnp.clip(fi, 0.0, float(n))
    fj = jnp.clip(fj, 0.0, float(m))
    i0 = jnp.clip(jnp.floor(fi).astype(jnp.int32), 0, n - 1)
    j0 = jnp.clip(jnp.floor(fj).astype(jnp.int32), 0, m - 1)
    a = (fi - i0)[..., None]
    b = (fj - j0)[..., None]
    p = patches[i0, j0]
    return (
        (1 - a) * (1 - b) * p[..., :c]
        + a * (1 - b) * p[..., c : 2 * c]
        + (1 - a) * b * p[..., 2 * c : 3 * c]
        + a * b * p[..., 3 * c :]
    )


def sector_fields(rho):
    """Patches of (ρ, ∂ρ/∂s, ∂ρ/∂r) on cell centres (central differences, one-sided at the edges)."""
    n_s, n_r = rho.shape
    rs = jnp.gradient(rho, axis=0) * n_s if n_s > 1 else jnp.zeros_like(rho)
    rr = jnp.gradient(rho, axis=1) * n_r if n_r > 1 else jnp.zeros_like(rho)
    return patches(jnp.stack([rho, rs, rr], axis=-1))


def sample(fields, g, qx, qy, fenced: bool = False, density_only: bool = False):
    """Density, inside mask and local-frame ∇ρ direction at local points (qx, qy).

    ``fields`` is (n_s, n_r, 3): ρ, ∂ρ/∂s, ∂ρ/∂r on cell centres.  ``fenced``: the bilinear gather runs behind a
    :func:`fence` (its indices materialised first), for callers that do not vmap it (a ``lax.cond`` under
    ``vmap`` with a batched predicate becomes a select of both branches).  ``density_only``: (ρ, inside) alone,
    gathering the ρ corners only (the same ρ).
    """
    n_s, n_r = fields.shape[0] + 1, fields.shape[1] + 1  # fields are patches
    cb, sb = jnp.cos(g[BETA]), jnp.sin(g[BETA])
    ex = g[CX] + cb * qx - sb * qy  # ellipse coordinates
    ey = g[CY] + sb * qx + cb * qy
    ux, uy = ex, ey / g[ASPECT]
    v = jnp.sqrt(ux * ux + uy * uy)
    if fenced:  # vectorising forms; unfenced, XLA fuses them into the gather, once per gathered value (slower)
        turn = atan2(uy, ux) - g[PHASE]
        s = (turn - 2 * jnp.pi * jnp.floor(turn / (2 * jnp.pi))) / g[DU]  # mod 2π (XLA:CPU's rem: a scalar fmod)
    else:
        s = jnp.mod(jnp.arctan2(uy, ux) - g[PHASE], 2 * jnp.pi) / g[DU]
    r = (v - g[V0]) / (g[V1] - g[V0])
    inside = (s < 1.0) & (r >= 0.0) & (r <= 1.0)
    fi, fj = s * n_s - 0.5, r * n_r - 0.5
    if density_only:
        fields = fields[..., ::3]  # the corners' ρ (patches: corner-major, (ρ, ρ_s, ρ_r) each)
    f = fence(lambda fi, fj: bilerp_patch(fields, fi, fj), fi, fj) if fenced else bilerp_patch(fields, fi, fj)
    rho = jnp.where(inside, f[..., 0], 0.0)
    if density_only:
        return rho, inside
    # ∇ρ = J^{-T} (ρ_s, ρ_r), J = [∂P/∂s ∂P/∂r]; det J = −Δu Δv A B v < 0, so up to the positive
    # factor 1/|det J|, ∇ρ = −(d ρ_s − c ρ_r, −b ρ_s + a ρ_r)
    cp, sp = ux / jnp.maximum(v, 1e-30), uy / jnp.maximum(v, 1e-30)
    dv = g[V1] - g[V0]
    a, c = -g[DU] * v * sp, g[DU] * v * g[ASPECT] * cp
    b, d = dv * cp, dv * g[ASPECT] * sp
    gx = -(d * f[..., 1] - c * f[..., 2])
    gy = -(-b * f[..., 1] + a * f[..., 2])
    lx, ly = cb * gx + sb * gy, -sb * gx + cb * gy  # into the local frame
    return rho, inside, lx, ly, f[..., 1], f[..., 2]


def march(fields, g, ang, n_lanes: int, n_steps: int, fenced: bool = False, depth_only: bool = False):
    """Optical depth per step (A, lanes, K) and ∇ρ (local) of rays entering along −d(ang); with ``depth_only`` the
    optical depth alone (:func:`sample`'s ``density_only``).

    ``fenced`` (for callers that do not vmap it, :func:`sample`): the gather and the whole march run behind
    :func:`fence` calls, so that XLA:CPU computes each sample once instead of once per consumer (the scene bake:
    39 → 29 CPU-ms per paper-model sector, the same bits)."""

    def run(fields, g, ang):
        rho, inside, *grad = sample(fields, g, *view_points(g, ang, n_lanes, n_steps), fenced, depth_only)
        tau = g[SIGMA_T] * rho * (2 * g[EXTENT] / n_steps)
        return tau if depth_only else (tau, *grad, inside)

    return fence(run, fields, g, ang) if fenced else run(fields, g, ang)


def light_depth_grid(fields, g, light, n_steps: int, m: int, fenced: bool = False):
    """Optical depth from each light to the nodes of an m × m local grid: (m, m, L), lights minor.

    Light rays: m lanes of ``n_steps`` steps from the light's side, like the view march.  ``fenced``: as
    :func:`march`'s (the depths and the lookup's indices materialised before the gathers).
    """
    tau = march(fields, g, light, m, n_steps, fenced=fenced, depth_only=True)
    depth = exclusive_depth(tau) + 0.5 * tau  # (L, m, K): to each step's midpoint, never negative

    def corners(g, light):
        R = g[EXTENT]
        x = -R + (jnp.arange(m) + 0.5) * (2 * R / m)
        qx, qy = x[:, None, None], x[None, :, None]
        c, s = jnp.cos(light), jnp.sin(light)
        fi = jnp.clip(((-s * qx + c * qy) + R) / (2 * R) * m - 0.5, 0.0, m - 1.0)  # (m, m, L)
        fj = jnp.clip((R - (c * qx + s * qy)) / (2 * R) * n_steps - 0.5, 0.0, n_steps - 1.0)
        i0 = jnp.clip(jnp.floor(fi).astype(jnp.int32), 0, m - 2)
        j0 = jnp.clip(jnp.floor(fj).astype(jnp.int32), 0, n_steps - 2)
        return i0, j0, fi - i0, fj - j0

    def lookup(depth, i0, j0, a, b):
        li = jnp.arange(light.shape[0])[None, None, :]
        return (
            (1 - a) * (1 - b) * depth[li, i0, j0]
            + a * (1 - b) * depth[li, i0 + 1, j0]
            + (1 - a) * b * depth[li, i0, j0 + 1]
            + a * b * depth[li, i0 + 1, j0 + 1]
        )

    if not fenced:
        return lookup(depth, *corners(g, light))
    return lookup(fence(lambda d: d, depth), *fence(corners, g, light))


def smooth_matrix(sigma_px, n_pix: int):
    """(P, P) Gaussian convolution along pixels (column j: the kernel centred on pixel j)."""
    off = jnp.arange(n_pix)[:, None] - jnp.arange(n_pix)[None, :]
    s = jnp.maximum(sigma_px, 1e-6)
    k = jnp.exp(-0.5 * (off / s) ** 2)
    m = jnp.arange(-16, 17)
    # Σ over all integers of exp(−m²/2σ²): the direct sum for σ ≤ 2, √(2π)σ beyond (Poisson summation)
    total = jnp.where(s <= 2.0, jnp.sum(jnp.exp(-0.5 * (m / s) ** 2)), jnp.sqrt(2 * jnp.pi) * s)
    return k / total


def direct_lighting(rho, gx, gy, rs, rr, inside, views, lights, phong):
    """:func:`phong_direct` at every (view, light, lane, step) sample of a march on the views ``views`` (V,),
    lit from ``lights`` (L,), with the :func:`normals` of that march's gradients: (V, L, lanes, K)."""
    vx, vy = jnp.cos(views)[:, None, None], jnp.sin(views)[:, None, None]
    nx, ny = normals(rho, gx, gy, rs, rr, inside, vx, vy)
    lx, ly = jnp.cos(lights)[None, :, None, None], jnp.sin(lights)[None, :, None, None]
    return phong_direct(nx[:, None], ny[:, None], vx[:, None], vy[:, None], lx, ly, phong)


def reflectance(alpha, direct, w, phong):
    """Eq 5's premultiplied reflectance per lane, k_a α + Σ_k w_k · direct_k: ``alpha`` (..., lanes),
    ``direct`` (..., L, lanes, K), ``w`` (..., lanes, K) → (..., L, lanes)."""
    return phong[0] * alpha[..., None, :] + jnp.einsum("...lnk,...nk->...ln", direct, w, precision=HIGHEST)


def to_pixels(x, n_pix: int, rays: int, smooth=None):
    """Lanes (..., P · rays) to pixels (..., P): a pixel's rays averaged, then convolved with ``smooth``
    (a :func:`smooth_matrix`) when given."""
    x = x.reshape(*x.shape[:-1], n_pix, rays).mean(-1)
    return x if smooth is None else jnp.matmul(x, smooth, precision=HIGHEST)


def exclusive_depth(tau):
    """Σ_{i<k} τ_i (..., K): the optical depth in front of each step, summed directly.

    Never as the inclusive sum less τ_k: at large optical depths (σ_t ρ Δs ≫ 1, trace.extinction or
    sectors.density_scale of 1e8 and more) that difference cancels catastrophically, and XLA:CPU, which
    recomputes a fused producer (the march) in each consumer, may round the two τ differently, so the
    difference went negative and exp(−depth) reached 1e27 (issue 29, N9).  A sum of non-negative terms
    is never negative, so T = exp(−depth) ≤ 1 whatever the rounding."""
    front = jnp.cumsum(tau[..., :-1], axis=-1)
    return jnp.concatenate([jnp.zeros_like(tau[..., :1]), front], axis=-1)


def front_to_back(tau, eps):
    """Eq 5 in closed form: per-step weights w_k = α_k T_k (zero once T_k < ``eps``) and α = Σ_k w_k,
    from the optical depth per step ``tau`` (..., K); T_k from :func:`exclusive_depth`."""
    trans = jnp.exp(-exclusive_depth(tau))
    w = jnp.where(trans >= eps, -jnp.expm1(-tau) * trans, 0.0)
    return w, jnp.sum(w, axis=-1)


def normals(rho, gx, gy, rs, rr, inside, vx, vy):
    """n = −∇ρ/|∇ρ| at the march's samples, falling back to the view direction d = (vx, vy) where the
    gradient is unresolved (:func:`resolved`, with the sector's peak density |ρ|max)."""
    ok, inv = resolved(jnp.max(jnp.abs(rho)), gx, gy, rs, rr, inside)
    return jnp.where(ok, -gx * inv, vx), jnp.where(ok, -gy * inv, vy)


def resolved(scale, gx, gy, rs, rr, inside):
    """(ok, 1/|∇ρ|): where the gradient (local ``gx``, ``gy``; parametric ``rs``, ``rr``) is resolved, at least
    1e-5 of ``scale`` (the sector's peak density) and inside the sector; 1/|∇ρ| there, 0 elsewhere."""
    mag2 = gx * gx + gy * gy
    ok = (rs * rs + rr * rr > (1e-5 * scale) ** 2) & (mag2 > 0) & inside
    return ok, jnp.where(ok, jax.lax.rsqrt(jnp.where(ok, mag2, 1.0)), 0.0)


def phong_direct(nx, ny, vx, vy, lx, ly, phong):
    """The direct part of the tracer's reflectance, k_d max(0, n·l) + k_s max(0, r·d)^p [n·l > 0] with
    r = 2(n·l)n − l; all arguments broadcast (the caller lays out the view and light axes).  r·d, a cosine of unit
    vectors, is clamped to 1: float32 rounding can put it a few ulp above, which the power p amplifies to
    (1 + 1e-7)^p, infinite for p ≳ 1e9 (phong.shininess is bounded by float32's range, not by physics)."""
    nl = nx * lx + ny * ly
    rv = jnp.minimum(2 * nl * (nx * vx + ny * vy) - (lx * vx + ly * vy), 1.0)
    spec = jnp.where((nl > 0) & (rv > 0), jnp.exp(phong[3] * jnp.log(jnp.where(rv > 0, rv, 1.0))), 0.0)
    return phong[1] * jnp.maximum(nl, 0.0) + phong[2] * spec


def view_points(g, views, n_lanes: int, n_steps: int):
    """Local (qx, qy) of every (view, lane, step) sample: (V, lanes, K) each, as :func:`march` places them."""
    return sample_points(
        g,
        jnp.cos(views)[:, None, None],
        jnp.sin(views)[:, None, None],
        jnp.arange(n_lanes)[None, :, None],
        jnp.arange(n_steps)[None, None, :],
        n_lanes,
        n_steps,
    )


def sample_points(g, dx, dy, lane, step, n_lanes: int, n_steps: int):
    """Local (qx, qy) of the samples at integer ``lane`` and ``step`` of the rays entering along −d, d = (``dx``,
    ``dy``) (all broadcast): lane centres t ∈ (−R, R) along d rotated by +90°, step midpoints z from +R to −R."""
    R = g[EXTENT]
    t = -R + (lane + 0.5) * (2 * R / n_lanes)
    z = R - (step + 0.5) * (2 * R / n_steps)
    return -dy * t + dx * z, dx * t + dy * z


def grid_transmittance(depth, g, views, n_lanes: int, n_steps: int):
    """exp(−optical depth toward each light) at every view sample, from :func:`light_depth_grid`'s
    (M, M, L) nodes: (V, lanes, K, L)."""
    qx, qy = view_points(g, views, n_lanes, n_steps)
    # one view at a time: the loop boundary stops XLA fusing the field into the gather (10x slower)
    return jax.lax.map(lambda q: transmittance_at(depth, g, q[0], q[1]), (qx, qy))


def transmittance_at(depth, g, qx, qy):
    """exp(−optical depth toward each light) at local points (qx, qy) (any shape S), bilinear in
    :func:`light_depth_grid`'s (M, M, L) nodes on the sector's [−R, R]² box: (*S, L)."""
    m = depth.shape[0]
    R = g[EXTENT]
    return jnp.exp(-bilerp_nodes(depth, (qx + R) / (2 * R) * m - 0.5, (qy + R) / (2 * R) * m - 0.5))
