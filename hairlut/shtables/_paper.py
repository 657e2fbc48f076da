"""The paper's way, kept as a baseline: brute-force quadrature over cube-map directions.

xing §4 samples both ω and t on cube-map texel centres (7×7×6 in the paper) and
sums K(ω, t) Y_i(ω) Y_j(ω) ΔΩ per entry; θ′ is sampled in steps of π/8.  The
error of this quadrature falls only as 1/N (the kernels have kinks), which is
what the exact Legendre–Gaunt form removes.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from .. import kernels as kk
from ..envlight import cube_dirs
from ..sh import real_sh_kernel

HIGHEST = jax.lax.Precision.HIGHEST  # stated, not inherited: XLA would use TF32 on NVIDIA GPUs


@functools.partial(jax.jit, static_argnames=("lmax_i", "lmax_j", "specular"))
def _quadrature(t, theta_v, omega, weight, p, lmax_i, lmax_j, specular):
    y = real_sh_kernel(omega, lmax=max(lmax_i, lmax_j))
    prod = jnp.einsum("wi,wj,w->wij", y[:, : (lmax_i + 1) ** 2], y[:, : (lmax_j + 1) ** 2], weight, precision=HIGHEST)
    cos_theta = jnp.clip(jnp.matmul(t, omega.T, precision=HIGHEST), -1.0, 1.0)  # (T, W)
    theta = jnp.arccos(cos_theta)
    if specular:
        lobe = kk.specular(theta[:, None, :], theta_v[None, :, None], p)  # (T, Θ, W)
        return jnp.einsum("tvw,wij->tvij", lobe, prod, precision=HIGHEST)
    return jnp.einsum("tw,wij->tij", kk.diffuse(theta), prod, precision=HIGHEST)


def paper_tables(n_omega: int, t_dirs, theta_v, p: float, lmax_light_d: int, lmax_light_s: int, lmax_trans: int):
    """Rd (T, I_d, J) and Rs (T, Θ, I_s, J) by the paper's cube-map quadrature (float64)."""
    omega, weight = cube_dirs(n_omega)
    with jax.enable_x64(True):
        args = (
            jnp.asarray(t_dirs, jnp.float64),
            jnp.asarray(theta_v, jnp.float64),
            jnp.asarray(omega),
            jnp.asarray(weight),
            jnp.float64(p),
        )
        rd = _quadrature(*args, lmax_i=lmax_light_d, lmax_j=lmax_trans, specular=False)
        rs = _quadrature(*args, lmax_i=lmax_light_s, lmax_j=lmax_trans, specular=True)
        return np.asarray(rd), np.asarray(rs)
