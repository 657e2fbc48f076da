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

from ..march import (
    GEOM,
    SHADOW_GRID,
    SIGMA_PX,
    direct_lighting,
    front_to_back,
    grid_transmittance,
    light_depth_grid,
    march,
    reflectance,
    sector_fields,
    smooth_matrix,
    to_pixels,
)

__all__ = ["GEOM", "trace_kernel"]


def _trace_one(rho, g, views, lights, phong, *, n_pix, n_steps, rays, shadow, smooth, eps):
    fields = sector_fields(rho)
    lanes = n_pix * rays
    tau, gx, gy, rs, rr, inside = march(fields, g, views, lanes, n_steps)  # (V, lanes, K)
    w, alpha = front_to_back(tau, eps)
    direct = direct_lighting(rho, gx, gy, rs, rr, inside, views, lights, phong)  # (V, L, lanes, K)
    if shadow:
        depth = light_depth_grid(fields, g, lights, n_steps, min(n_steps, SHADOW_GRID))  # (M, M, L)
        trans_l = grid_transmittance(depth, g, views, lanes, n_steps)  # (V, lanes, K, L)
        direct = direct * jnp.moveaxis(trans_l, -1, 1)
    refl = reflectance(alpha, direct, w, phong)  # (V, L, lanes); a dot, not a reduce fusion
    S = smooth_matrix(g[SIGMA_PX], n_pix) if smooth else None
    alpha, refl = to_pixels(alpha, n_pix, rays, S), to_pixels(refl, n_pix, rays, S)
    # Σ w telescopes to 1 − exp(−Σ τ) ≤ 1, but float32 rounding of the sum can overshoot by a few ulp
    return jnp.clip(alpha, 0.0, 1.0), refl


@partial(jax.jit, static_argnames=("n_pix", "n_steps", "rays", "shadow", "smooth", "eps", "chunk"))
def trace_kernel(
    rho,
    geom,
    views,
    lights,
    phong,
    *,
    n_pix: int,
    n_steps: int,
    rays: int = 1,
    shadow: bool = False,
    smooth: bool = True,
    eps: float = 1e-4,
    chunk: int = 1,
):
    """HRIRs of B sectors: alpha (B, V, P) and premultiplied reflectance (B, V, L, P).

    ``rho`` (B, n_s, n_r) densities, ``geom`` (B, len(GEOM)) sector geometry (see
    :data:`GEOM` and the module docstring), ``views`` (V,) and ``lights`` (L,) local
    angles, ``phong`` = (k_a, k_d, k_s, p).  Sectors are mapped ``chunk`` at a time.
    """
    one = partial(_trace_one, n_pix=n_pix, n_steps=n_steps, rays=rays, shadow=shadow, smooth=smooth, eps=eps)
    return jax.lax.map(lambda a: one(a[0], a[1], views, lights, phong), (rho, geom), batch_size=chunk)
