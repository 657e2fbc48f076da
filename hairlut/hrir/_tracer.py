"""Planar ray tracing of generalized sectors into HRIRs (satf §5.1, eqs 4–5), one jitted kernel.

**Sector geometry** (see ``hairlut.geometry.sampler``).  A sector is the patch
v ∈ [v0, v1], φ ∈ [φ0, φ0 + Δu] of eq 1's ellipse x = A v cos φ, y = B v sin φ (A = 1,
B = aspect).  Its density ρ is given on a parametric (n_s, n_r) grid of cell averages
(s along φ, r along v); it is interpolated bilinearly between cell centres (clamped at
the edges) and is zero outside the sector.

**Local frame** (in which the angles of eq 4 are measured).  Origin c = P(v_mid, φ_mid),
the parametric centre; +x is the ellipse's outward normal there (the radial direction,
increasing r), +y the tangent (increasing s, i.e. increasing phase); the frame is
right-handed.  A view angle θv ∈ [0, 2π) from +x gives the unit vector d toward the
viewer; a light angle θl gives l toward the light.  θv = 0 looks at the shell from outside.

**Pixels.**  The HRIR is the image on the line through c perpendicular to d:
P pixels of width 2R/P covering t ∈ [−R, R] along e = d rotated by +90°, where R (the
sector's *extent*) is the largest distance from c to the sector.  Pixel j's rays
(``rays`` per pixel, box-averaged) start at z = +R on the viewer's side and march to
z = −R in K steps of Δs = 2R/K (midpoint samples).

**Opacity.**  A step of length Δs at density ρ has α = 1 − exp(−σ_t ρ Δs).  The paper's
"α proportional to ρ" is the first-order term, α ≈ c ρ with c = σ_t Δs, valid when
σ_t ρ Δs ≪ 1.  The exponential form makes the product of step transmittances telescope,
Π(1 − α_k) = exp(−σ_t Σ ρ_k Δs), so the accumulated opacity is 1 − exp(−optical depth):
exact for piecewise-constant ρ at any step, and converging as Δs → 0 to the exact line
integral with only the quadrature error of Σ ρ_k Δs.  A fixed constant c (the paper's
reading) makes α_acc depend on how many samples a ray takes, and a linear α exceeds 1
once σ_t ρ Δs > 1.
σ_t = κ / r_strand: for opaque strands of radius r covering an area fraction ρ, a ray
meets 2ρ/(π r) strands per unit length, so κ = 2/π is the physical value.

**Reflectance** re(h) = k_a + T_l(h)·(k_d max(0, n·l) + k_s max(0, r·d)^p [n·l > 0]) (Phong,
r = 2(n·l)n − l) with n = −∇ρ/|∇ρ| (the density gradient by the chain rule through the
parametric map; where |∇ρ| vanishes, e.g. inside a uniform region, n = d).  T_l is the
in-plane transmittance toward the light (self-shadowing, optional; 1 otherwise).

**Accumulation** is eq 5, re_acc += α re (1 − α_acc), α_acc += α (1 − α_acc), written in
closed form: 1 − α_acc before step k is T_k = exp(−Σ_{i<k} σ_t ρ_i Δs), so each sample
weighs w_k = α_k T_k.  Early termination: samples with T_k < ``eps`` (α_acc ≈ 1) get
w_k = 0 (a mask: with fixed shapes every step is still evaluated, vectorised).  The stored reflectance is the accumulated (alpha-premultiplied) re_acc.
The α array and the weights depend only on the view, so they are computed once per
(sector, view) and shared by all lights.

**Self-shadowing**: the optical depth from the light to every point is traced once per
(sector, light) by the same march (rays from the light), resampled onto an M × M
Cartesian grid of the local frame (M = min(K, 128)) holding all lights per node, and
sampled bilinearly at each view sample.  On by default (``trace.self_shadow``): it
costs 2–4× the trace and changes re by more than the discretisation error
(benchmarks/hrir_bake.py).  It is the shadowing *within* a sector; the online s-map
(eq 12) adds the shadows that outer layers cast on inner ones.

**Smoothing** (§5.1): both arrays are convolved along the pixel axis with a Gaussian of
σ_px = 1.5 σ_strand / (2R/P) pixels (zero outside the image; the sampled kernel is
normalised over the infinite line, so a delta input gives a discrete Gaussian of
standard deviation σ_px).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

HIGHEST = jax.lax.Precision.HIGHEST  # stated, not inherited: XLA would use TF32 on NVIDIA GPUs

#: Largest side M of the Cartesian shadow grid (M = min(steps, SHADOW_GRID)).
SHADOW_GRID = 128

#: Columns of the per-sector geometry array passed to :func:`trace_kernel`.
GEOM = ("phase", "du", "v0", "v1", "aspect", "cx", "cy", "beta", "extent", "sigma_t", "sigma_px")


def _bilerp(grid, fi, fj):
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
    return ((1 - a) * (1 - b) * grid[i0, j0] + a * (1 - b) * grid[i1, j0]
            + (1 - a) * b * grid[i0, j1] + a * b * grid[i1, j1])


def _patches(grid):
    """(n−1, m−1, 4·c) corner values of every cell-centre quad, so bilinear lookups gather once."""
    g = grid if grid.shape[0] > 1 else jnp.concatenate([grid, grid], axis=0)
    g = g if g.shape[1] > 1 else jnp.concatenate([g, g], axis=1)
    return jnp.concatenate([g[:-1, :-1], g[1:, :-1], g[:-1, 1:], g[1:, 1:]], axis=-1)


def _bilerp_patch(patches, fi, fj):
    """Bilinear interpolation from :func:`_patches` at fractional cell-centre indices (clamped)."""
    n, m, c4 = patches.shape
    c = c4 // 4
    fi = jnp.clip(fi, 0.0, float(n))
    fj = jnp.clip(fj, 0.0, float(m))
    i0 = jnp.clip(jnp.floor(fi).astype(jnp.int32), 0, n - 1)
    j0 = jnp.clip(jnp.floor(fj).astype(jnp.int32), 0, m - 1)
    a = (fi - i0)[..., None]
    b = (fj - j0)[..., None]
    p = patches[i0, j0]
    return ((1 - a) * (1 - b) * p[..., :c] + a * (1 - b) * p[..., c:2 * c]
            + (1 - a) * b * p[..., 2 * c:3 * c] + a * b * p[..., 3 * c:])


def _sample(fields, g, qx, qy):
    """Density, inside mask and local-frame ∇ρ direction at local points (qx, qy).

    ``fields`` is (n_s, n_r, 3): ρ, ∂ρ/∂s, ∂ρ/∂r on cell centres.
    """
    n_s, n_r = fields.shape[0] + 1, fields.shape[1] + 1  # fields are patches
    cb, sb = jnp.cos(g[7]), jnp.sin(g[7])
    ex = g[5] + cb * qx - sb * qy  # ellipse coordinates
    ey = g[6] + sb * qx + cb * qy
    ux, uy = ex, ey / g[4]
    v = jnp.sqrt(ux * ux + uy * uy)
    phi = jnp.arctan2(uy, ux)
    s = jnp.mod(phi - g[0], 2 * jnp.pi) / g[1]
    r = (v - g[2]) / (g[3] - g[2])
    inside = (s < 1.0) & (r >= 0.0) & (r <= 1.0)
    f = _bilerp_patch(fields, s * n_s - 0.5, r * n_r - 0.5)
    rho = jnp.where(inside, f[..., 0], 0.0)
    # ∇ρ = J^{-T} (ρ_s, ρ_r), J = [∂P/∂s ∂P/∂r]; det J = −Δu Δv A B v < 0, so up to the positive
    # factor 1/|det J|, ∇ρ = −(d ρ_s − c ρ_r, −b ρ_s + a ρ_r)
    cp, sp = ux / jnp.maximum(v, 1e-30), uy / jnp.maximum(v, 1e-30)
    dv = g[3] - g[2]
    a, c = -g[1] * v * sp, g[1] * v * g[4] * cp
    b, d = dv * cp, dv * g[4] * sp
    gx = -(d * f[..., 1] - c * f[..., 2])
    gy = -(-b * f[..., 1] + a * f[..., 2])
    lx, ly = cb * gx + sb * gy, -sb * gx + cb * gy  # into the local frame
    return rho, inside, lx, ly, f[..., 1], f[..., 2]


def _march(fields, g, ang, n_lanes: int, n_steps: int):
    """Optical depth per step (A, lanes, K) and ∇ρ (local) of rays entering along −d(ang)."""
    R = g[8]
    dx, dy = jnp.cos(ang)[:, None, None], jnp.sin(ang)[:, None, None]
    t = (-R + (jnp.arange(n_lanes) + 0.5) * (2 * R / n_lanes))[None, :, None]
    ds = 2 * R / n_steps
    z = (R - (jnp.arange(n_steps) + 0.5) * ds)[None, None, :]
    qx = -dy * t + dx * z
    qy = dx * t + dy * z
    rho, inside, gx, gy, rs, rr = _sample(fields, g, qx, qy)
    tau = g[9] * rho * ds
    return tau, gx, gy, rs, rr, inside


def _fields(rho):
    n_s, n_r = rho.shape
    rs = jnp.gradient(rho, axis=0) * n_s if n_s > 1 else jnp.zeros_like(rho)
    rr = jnp.gradient(rho, axis=1) * n_r if n_r > 1 else jnp.zeros_like(rho)
    return _patches(jnp.stack([rho, rs, rr], axis=-1))


def _shadow_field(fields, g, light, n_steps: int, m: int):
    """Optical depth from each light to the nodes of an m × m local grid: (m, m, L), lights minor.

    Light rays: m lanes of ``n_steps`` steps from the light's side, like the view march.
    """
    tau, *_ = _march(fields, g, light, m, n_steps)
    depth = jnp.cumsum(tau, axis=-1) - 0.5 * tau  # (L, m, K): to each step's midpoint
    R = g[8]
    x = -R + (jnp.arange(m) + 0.5) * (2 * R / m)
    qx, qy = x[:, None, None], x[None, :, None]
    c, s = jnp.cos(light), jnp.sin(light)
    fi = jnp.clip(((-s * qx + c * qy) + R) / (2 * R) * m - 0.5, 0.0, m - 1.0)  # (m, m, L)
    fj = jnp.clip((R - (c * qx + s * qy)) / (2 * R) * n_steps - 0.5, 0.0, n_steps - 1.0)
    i0 = jnp.clip(jnp.floor(fi).astype(jnp.int32), 0, m - 2)
    j0 = jnp.clip(jnp.floor(fj).astype(jnp.int32), 0, n_steps - 2)
    a, b = fi - i0, fj - j0
    li = jnp.arange(light.shape[0])[None, None, :]
    out = ((1 - a) * (1 - b) * depth[li, i0, j0] + a * (1 - b) * depth[li, i0 + 1, j0]
           + (1 - a) * b * depth[li, i0, j0 + 1] + a * b * depth[li, i0 + 1, j0 + 1])
    return out


def _smooth_matrix(sigma_px, n_pix: int):
    """(P, P) Gaussian convolution along pixels (column j: the kernel centred on pixel j)."""
    off = jnp.arange(n_pix)[:, None] - jnp.arange(n_pix)[None, :]
    s = jnp.maximum(sigma_px, 1e-6)
    k = jnp.exp(-0.5 * (off / s) ** 2)
    m = jnp.arange(-16, 17)
    # Σ over all integers of exp(−m²/2σ²): the direct sum for σ ≤ 2, √(2π)σ beyond (Poisson summation)
    total = jnp.where(s <= 2.0, jnp.sum(jnp.exp(-0.5 * (m / s) ** 2)), jnp.sqrt(2 * jnp.pi) * s)
    return k / total


def _trace_one(rho, g, views, lights, phong, *, n_pix, n_steps, rays, shadow, smooth, eps):
    fields = _fields(rho)
    lanes = n_pix * rays
    tau, gx, gy, rs, rr, inside = _march(fields, g, views, lanes, n_steps)  # (V, lanes, K)
    before = jnp.cumsum(tau, axis=-1) - tau
    trans = jnp.exp(-before)
    w = jnp.where(trans >= eps, -jnp.expm1(-tau) * trans, 0.0)
    alpha = jnp.sum(w, axis=-1)
    # normal n = −∇ρ/|∇ρ|, falling back to d where the gradient vanishes
    mag2 = gx * gx + gy * gy
    scale = jnp.max(jnp.abs(rho))
    ok = (rs * rs + rr * rr > (1e-5 * scale) ** 2) & (mag2 > 0) & inside
    inv = jnp.where(ok, jax.lax.rsqrt(jnp.where(ok, mag2, 1.0)), 0.0)
    vx, vy = jnp.cos(views)[:, None, None], jnp.sin(views)[:, None, None]
    nx = jnp.where(ok, -gx * inv, vx)
    ny = jnp.where(ok, -gy * inv, vy)
    lx, ly = jnp.cos(lights), jnp.sin(lights)
    nl = nx[:, None] * lx[None, :, None, None] + ny[:, None] * ly[None, :, None, None]  # (V, L, lanes, K)
    nv = (nx * vx + ny * vy)[:, None]
    lv = (lx[None, :] * jnp.cos(views)[:, None] + ly[None, :] * jnp.sin(views)[:, None])[:, :, None, None]
    rv = 2 * nl * nv - lv
    spec = jnp.where((nl > 0) & (rv > 0), jnp.exp(phong[3] * jnp.log(jnp.where(rv > 0, rv, 1.0))), 0.0)
    direct = phong[1] * jnp.maximum(nl, 0.0) + phong[2] * spec
    if shadow:
        m = min(n_steps, SHADOW_GRID)
        field = _shadow_field(fields, g, lights, n_steps, m)  # (M, M, L)
        R = g[8]
        t = (-R + (jnp.arange(lanes) + 0.5) * (2 * R / lanes))[None, :, None]
        z = (R - (jnp.arange(n_steps) + 0.5) * (2 * R / n_steps))[None, None, :]
        qx, qy = -vy * t + vx * z, vx * t + vy * z
        fi, fj = (qx + R) / (2 * R) * m - 0.5, (qy + R) / (2 * R) * m - 0.5
        # one view at a time: the loop boundary stops XLA fusing the field into the gather (10x slower)
        trans_l = jax.lax.map(lambda a: jnp.exp(-_bilerp(field, a[0], a[1])), (fi, fj))  # (V, lanes, K, L)
        direct = direct * jnp.moveaxis(trans_l, -1, 1)
    # (V, L, lanes); a dot, not a reduce fusion
    refl = phong[0] * alpha[:, None] + jnp.einsum("vlnk,vnk->vln", direct, w, precision=HIGHEST)
    alpha = alpha.reshape(alpha.shape[0], n_pix, rays).mean(-1)
    refl = refl.reshape(*refl.shape[:2], n_pix, rays).mean(-1)
    if smooth:
        S = _smooth_matrix(g[10], n_pix)
        alpha = jnp.matmul(alpha, S, precision=HIGHEST)
        refl = jnp.matmul(refl, S, precision=HIGHEST)
    # Σ w telescopes to 1 − exp(−Σ τ) ≤ 1, but float32 rounding of the sum can overshoot by a few ulp
    return jnp.clip(alpha, 0.0, 1.0), refl


@partial(jax.jit, static_argnames=("n_pix", "n_steps", "rays", "shadow", "smooth", "eps", "chunk"))
def trace_kernel(rho, geom, views, lights, phong, *, n_pix: int, n_steps: int, rays: int = 1,
                 shadow: bool = False, smooth: bool = True, eps: float = 1e-4, chunk: int = 1):
    """HRIRs of B sectors: alpha (B, V, P) and premultiplied reflectance (B, V, L, P).

    ``rho`` (B, n_s, n_r) densities, ``geom`` (B, len(GEOM)) sector geometry (see
    :data:`GEOM` and the module docstring), ``views`` (V,) and ``lights`` (L,) local
    angles, ``phong`` = (k_a, k_d, k_s, p).  Sectors are mapped ``chunk`` at a time.
    """
    one = partial(_trace_one, n_pix=n_pix, n_steps=n_steps, rays=rays, shadow=shadow, smooth=smooth, eps=eps)
    return jax.lax.map(lambda a: one(a[0], a[1], views, lights, phong), (rho, geom), batch_size=chunk)
