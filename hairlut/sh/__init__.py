"""Real spherical harmonics for the SH convolution tables (xing §4).

Convention (DESIGN.md): real, orthonormal on the unit sphere, flat index
``i = l*l + l + m``, no Condon–Shortley phase, m > 0 ↔ cos(mφ), m < 0 ↔ sin(|m|φ):

    Y₀₀ = 0.282095;  Y₁₋₁, Y₁₀, Y₁₁ = 0.488603·(y, z, x);
    Y₂₋₂ = 1.092548·xy, Y₂₋₁ = 1.092548·yz, Y₂₀ = 0.315392·(3z²−1),
    Y₂₁ = 1.092548·xz, Y₂₂ = 0.546274·(x²−y²).

Public API:

* :func:`real_sh` — the basis at directions (one jitted kernel per lmax; float32/float64).
* :func:`n_coeffs`, :func:`lm_index`, :func:`index_lm` — index helpers.
* :func:`sphere_grid` / :class:`GaussLegendreGrid` — product quadrature exact to degree 2L.
* :func:`project`, :func:`project_function`, :func:`evaluate` — coefficients ↔ values.
* :func:`gaunt`, :func:`gaunt_sparse` — real Gaunt coefficients ∫ Y_i Y_j Y_k dω.
* :func:`real_sh_reference` — a slow float64 reference (tests, benchmarks).

Wiring for other kernels and for tests, importable by name but not listed: ``real_sh_kernel`` (the unchecked
jitted kernel behind :func:`real_sh`), ``real_sh_soa`` (its unrolled form, for use inside other kernels),
``check_dirs`` (the directions check it applies), ``normalize_dirs``, ``lm_arrays``, ``selection_mask``,
``gaunt_quadrature`` (the Gaunt coefficients before the selection rules, uncached) and ``real_sh_scipy``
(a second reference, through SciPy).
"""

from ._basis import (
    MAX_LMAX,
    check_dirs,
    index_lm,
    lm_arrays,
    lm_index,
    n_coeffs,
    normalize_dirs,
    real_sh,
    real_sh_kernel,
    real_sh_soa,
)
from ._gaunt import gaunt, gaunt_quadrature, gaunt_sparse, selection_mask
from ._quadrature import GaussLegendreGrid, evaluate, project, project_function, sphere_grid
from ._reference import real_sh_reference, real_sh_scipy

__all__ = [
    "GaussLegendreGrid",
    "evaluate",
    "gaunt",
    "gaunt_sparse",
    "index_lm",
    "lm_index",
    "n_coeffs",
    "project",
    "project_function",
    "real_sh",
    "real_sh_reference",
    "sphere_grid",
]
