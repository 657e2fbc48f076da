"""Voxel-based SH transmittance (xing §5): b_j and ∇b_j at sample voxels, eq (7) elsewhere.

At sample voxels y_i (non-empty voxels on a lattice of the given ``stride``)
rays are cast toward the directions ω of an SH quadrature grid:

    τ(y, ω) = Σ ρ(y + tω) Δt,   ∇τ(y, ω) = Σ ∇ρ(y + tω) Δt        (trilinear samples)
    T = exp(−κτ),  ∇T = −κ T ∇τ                                     (Beer–Lambert)
    b_j(y) = Σ_ω w_ω T Y_j(ω),  ∇b_j(y) = Σ_ω w_ω ∇T Y_j(ω)

so the opacity does not depend on the step size (the step only sets the
quadrature of τ).  Every non-empty voxel x (and its one-voxel ring, so that
trilinear lookups at vertices see no empty neighbours) then gets eq (7):

    b_j(x) = Σ_i w_i (b_j(y_i) + (x − y_i)·∇b_j(y_i)) / Σ_i w_i,   w_i = exp(−σ‖x − y_i‖)

over its ``neighbours`` nearest sample voxels; ``use_gradient=False`` gives the
plain weighted average.  Vertices take b_j by trilinear interpolation.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

from .. import errors
from .._blocks import map_blocks
from ..sh import real_sh, sphere_grid
from ._volume import Volume, gradient, trilinear

CHUNK = 256


@functools.partial(jax.jit, static_argnames=("n_steps",))
def _cast_kernel(points, dirs, weights, ylm, density, grad, step, size, kappa, n_steps):
    """(b, ∇b) at sample points (S, 3) in voxel coordinates: (S, n), (S, 3, n)."""

    def one_block(p):
        t = (jnp.arange(n_steps) + 0.5) * step  # voxel units
        pos = p[:, None, None, :] + t[None, None, :, None] * dirs[None, :, None, :]  # (B, M, K, 3)
        dt = step * size  # world length per step
        tau = trilinear(density, pos).sum(-1) * dt  # (B, M)
        dtau = trilinear(grad, pos).sum(-2) * dt / size  # (B, M, 3): ∇ρ per world unit
        T = jnp.exp(-kappa * tau)
        dT = -kappa * T[..., None] * dtau
        b = jnp.einsum("bm,m,mj->bj", T, weights, ylm, precision=jax.lax.Precision.HIGHEST)
        db = jnp.einsum("bmc,m,mj->bcj", dT, weights, ylm, precision=jax.lax.Precision.HIGHEST)
        return b, db

    return map_blocks(one_block, (points,), CHUNK)


@dataclass(frozen=True)
class Transmittance:
    """SH transmittance on a voxel grid: ``coeffs`` (nx, ny, nz, n) and where they are valid."""

    volume: Volume
    coeffs: np.ndarray
    valid: np.ndarray  # (nx, ny, nz) bool
    lmax: int
    kappa: float
    samples: np.ndarray  # (S, 3) voxel indices of the sample voxels

    def at(self, points) -> np.ndarray:
        """b_j at world points by trilinear interpolation of the voxel coefficients (xing §5, end)."""
        g = self.volume.to_grid(points)
        with jax.enable_x64(True):
            return np.asarray(trilinear(jnp.asarray(self.coeffs), jnp.asarray(g)))


def transmittance(
    volume: Volume,
    kappa: float,
    *,
    lmax: int = 2,
    stride: int = 2,
    order: int = 8,
    step: float = 0.5,
    neighbours: int = 8,
    use_gradient: bool = True,
) -> Transmittance:
    """Compute SH transmittance coefficients for every non-empty voxel (see module doc)."""
    for name, v, lo in (("lmax", lmax, 0), ("stride", stride, 1), ("order", order, 1), ("neighbours", neighbours, 1)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise errors.ValidationError(name, v, f"need an integer ≥ {lo}")
    if not (np.isfinite(kappa) and kappa >= 0):
        raise errors.ValidationError("kappa", kappa, "the extinction scale κ must be finite and ≥ 0")
    if not (np.isfinite(step) and 0 < step <= 2):
        raise errors.ValidationError("step", step, "the ray step (in voxels) must be in (0, 2]")
    if order < lmax:
        raise errors.ValidationError("order", order, f"the quadrature order must be ≥ lmax = {lmax}")
    rho = np.asarray(volume.density, np.float64)
    filled = np.argwhere(rho > 0)
    if len(filled) == 0:
        raise errors.ValidationError("volume", volume.shape, "the volume holds no hair")
    samples = filled[np.all(filled % stride == 0, axis=1)]
    if len(samples) == 0:
        samples = filled[:: stride**3]
    grid = sphere_grid(order)
    ylm = np.asarray(real_sh(lmax, grid.dirs))
    n_steps = int(np.ceil(np.linalg.norm(volume.shape) / step))
    with jax.enable_x64(True):
        dens = jnp.asarray(rho)
        b, db = _cast_kernel(
            jnp.asarray(samples, jnp.float64),
            jnp.asarray(grid.dirs),
            jnp.asarray(grid.weights),
            jnp.asarray(ylm),
            dens,
            gradient(dens),
            step,
            float(volume.size),
            float(kappa),
            n_steps,
        )
        b, db = np.asarray(b), np.asarray(db)
    # eq (7) at every non-empty voxel and its one-voxel ring
    valid = np.zeros(rho.shape, bool)
    for d in np.ndindex(3, 3, 3):
        sl = tuple(slice(max(0, o - 1), n + min(0, o - 1)) for o, n in zip(d, rho.shape))
        dst = tuple(slice(max(0, 1 - o), n + min(0, 1 - o)) for o, n in zip(d, rho.shape))
        valid[dst] |= rho[sl] > 0
    targets = np.argwhere(valid)
    k = min(neighbours, len(samples))
    dist, nn = cKDTree(samples).query(targets, k=k)
    dist, nn = dist.reshape(len(targets), k), nn.reshape(len(targets), k)
    sigma = 3.0 / max(float(dist[:, -1].max()), 1.0)  # weights fall to ~e^-3 at the farthest neighbour used
    w = np.exp(-sigma * dist)
    est = b[nn]  # (X, k, n)
    if use_gradient:
        offset = (targets[:, None, :] - samples[nn]) * volume.size  # world units
        est = est + np.einsum("xkc,xkcn->xkn", offset, db[nn])
    coeffs = np.zeros(rho.shape + (b.shape[1],))
    coeffs[tuple(targets.T)] = np.einsum("xk,xkn->xn", w, est) / w.sum(1, keepdims=True)
    return Transmittance(volume, coeffs, valid, lmax, float(kappa), samples)
