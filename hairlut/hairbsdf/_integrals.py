"""Converged hair tables by deterministic quadrature, each value with its estimated error (issue 28).

Three tables, on Unreal Engine's axes (its ``HairStrandsLUT`` bakes them by uniform Monte Carlo), here
computed from the BSDF of :mod:`._bsdf` (Chiang et al. 2016, "A Practical and Controllable Hair and Fur
Model for Production Path Tracing") and the dual-scattering definitions of Zinke, Yuksel, Weber and Keyser
2008, "Dual Scattering Approximation for Fast Multiple Scattering in Hair".

This module is the tables' front: :func:`tables` (whole rows of the three tables), :func:`mean_energy`,
:func:`dual_scattering` and :func:`coverage` (at scattered points) and :func:`furnace` (the white furnace test);
it re-exports what the rest of the package uses.  The parts, each in its own module:

- :mod:`._axes`: the axes (Unreal's, cell centres), the defaults and limits, the argument checks, ``peak_bytes``;
- :mod:`._quadrature`: Gauss–Legendre panels, the azimuthal crossings they are graded about, the back fraction;
- :mod:`._energy`: **mean_energy** and **dual_scattering** (definitions, row kernels) and the furnace kernel;
- :mod:`._coverage`: **coverage** (definition, closed-form q, row kernel);
- :mod:`._montecarlo`: the Unreal-style Monte Carlo baseline, :func:`montecarlo_unreal`.

Reproducibility: each *row* (one sin θ_o for the BSDF tables, one radius for coverage) is computed by one
jitted kernel of fixed shapes from the row's own inputs, both rules of the error estimate in the same program,
so a row's numbers are the same bits whichever rows are computed together (:func:`tables`' ``start``/``stop``),
and each table compiles one kernel, once per process.

Measured on the 2-core development machine, shared (load average 5–8), default axes and resolutions: all three
tables ~2 s wall, 1.6 s CPU; compiling the two row kernels takes another ~4 s wall once per process
(bsdf_row_kernel ~3.5 s, coverage_row_kernel ~0.5 s; ``hairlut`` keeps them in its XLA cache between processes).
"""

from __future__ import annotations

import numpy as np

from ..errors import ValidationError
from . import _bsdf as B
from ._axes import (
    ABSORPTION_KINDS,
    DEFAULT_AXES,
    DEFAULT_MODEL,
    DEFAULT_QUADRATURE,
    DEFAULT_RESOLUTION,
    DUAL_SCATTERING_FIELDS,
    MAX_NODES,
    MAX_RESOLUTION,
    MEAN_ENERGY_FIELDS,
    TABLES,
    _rows,
    _x64,
    absorption_sigma,
    axis_nodes,
    check_axes,
    check_model_dict,
    check_quadrature,
    check_resolution,
    peak_bytes,
)
from ._coverage import coverage_row_kernel
from ._energy import bsdf_point_kernel, bsdf_row_kernel, furnace_kernel
from ._montecarlo import UNREAL_COVERAGE_TRIALS, UNREAL_PHI, UNREAL_THETA, montecarlo_unreal, unreal_counts
from ._quadrature import back_fraction

__all__ = [
    "ABSORPTION_KINDS",
    "DEFAULT_AXES",
    "DEFAULT_MODEL",
    "DEFAULT_QUADRATURE",
    "DEFAULT_RESOLUTION",
    "DUAL_SCATTERING_FIELDS",
    "MAX_NODES",
    "MAX_RESOLUTION",
    "MEAN_ENERGY_FIELDS",
    "TABLES",
    "UNREAL_COVERAGE_TRIALS",
    "UNREAL_PHI",
    "UNREAL_THETA",
    "absorption_sigma",
    "axis_nodes",
    "back_fraction",
    "bsdf_point_kernel",
    "bsdf_row_kernel",
    "check_axes",
    "check_model_dict",
    "check_quadrature",
    "check_resolution",
    "coverage",
    "coverage_row_kernel",
    "dual_scattering",
    "furnace",
    "furnace_kernel",
    "mean_energy",
    "montecarlo_unreal",
    "peak_bytes",
    "tables",
    "unreal_counts",
]


# ----------------------------------------------------------------------------- public functions


def _bsdf_points(sin_theta_o, roughness, absorption, absorption_kind, model, quadrature):
    if absorption_kind not in ABSORPTION_KINDS:
        raise ValidationError("absorption_kind", absorption_kind, f"must be one of {', '.join(ABSORPTION_KINDS)}")
    so = B.check_values(sin_theta_o, "sin_theta_o", -1.0, 1.0)
    r = B.check_roughness(roughness)
    ab = B.check_colour(absorption, "absorption") if absorption_kind == "colour" else B.check_sigma_a(absorption, "absorption")
    so, r, ab = np.broadcast_arrays(so, r, ab)
    sigma = B.colour_to_sigma_a(ab * ab, r) if absorption_kind == "colour" else ab
    eta, alpha = check_model_dict(model)
    q = check_quadrature(quadrature)
    flat = [np.ascontiguousarray(x.reshape(-1)) for x in (so, r, sigma)]
    e, ee, d, de = _x64(bsdf_point_kernel, *flat, eta, alpha, m=q["nodes"], levels=q["levels"])
    shape = so.shape
    return [(a.reshape(*shape, -1), b.reshape(*shape, -1)) for a, b in ((e, ee), (d, de))]


def mean_energy(sin_theta_o, roughness, absorption, *, absorption_kind="colour", model=None, quadrature=None):
    """(values (..., 4), errors (..., 4)): the mean energies (R, TT, TRT, residual) at broadcast points.

    ``absorption`` is a perceptual colour c ∈ (0, 1] (C = c², σ_a by [Chiang eq. 9] with β_n = roughness) or,
    with ``absorption_kind="sigma_a"``, σ_a ≥ 0; ``model`` = {"eta", "alpha"}; ``quadrature`` as in
    :func:`tables`.  :mod:`._energy` defines them."""
    return _bsdf_points(sin_theta_o, roughness, absorption, absorption_kind, model, quadrature)[0]


def dual_scattering(sin_theta_o, roughness, absorption, *, absorption_kind="colour", model=None, quadrature=None):
    """(values (..., 6), errors (..., 6)): A_f, A_b, ᾱ_f, ᾱ_b, β̄_f, β̄_b (:data:`DUAL_SCATTERING_FIELDS`) at
    broadcast points (arguments as :func:`mean_energy`)."""
    return _bsdf_points(sin_theta_o, roughness, absorption, absorption_kind, model, quadrature)[1]


def coverage(strand_count, radius_px, *, quadrature=None):
    """(values, errors) of the expected covered fraction of a pixel (:mod:`._coverage`'s measure) for broadcast
    strand counts N ≥ 0 and radii r ≥ 0 (pixels)."""
    n = B.check_values(strand_count, "strand_count", 0.0)
    r = B.check_values(radius_px, "radius_px", 0.0)
    q = check_quadrature(quadrature)
    n, r = np.broadcast_arrays(n, r)
    vals, errs = np.zeros(n.shape), np.zeros(n.shape)
    for rv in np.unique(r):
        sel = r == rv
        vals[sel], errs[sel] = _x64(coverage_row_kernel, np.float64(rv), np.ascontiguousarray(n[sel]), m=q["coverage_nodes"])
    return vals, errs


def furnace(sin_theta_o, h, beta_m, beta_n, sigma_a=0.0, *, model=None, nodes=8):
    """(values, errors): ∫_{S²} Σ_p M_p A_p N_p dω_i at broadcast (sin θ_o, h, β_m, β_n, σ_a), by a tensor
    Gauss–Legendre rule in (θ_i, φ_i) graded about every lobe (not using the factorisation); exactly
    Σ_p A_p(θ_o, h), which is 1 when σ_a = 0 (the white furnace)."""
    so = B.check_values(sin_theta_o, "sin_theta_o", -1.0, 1.0)
    hh = B.check_values(h, "h", -1.0, 1.0)
    bm, bn = B.check_roughness(beta_m, "beta_m"), B.check_roughness(beta_n, "beta_n")
    sa = B.check_sigma_a(sigma_a)
    eta, alpha = check_model_dict(model)
    q = check_quadrature({"nodes": nodes})
    arrs = np.broadcast_arrays(so, hh, bm, bn, sa)
    flat = [np.ascontiguousarray(x.reshape(-1)) for x in arrs]
    hi = _x64(furnace_kernel, *flat, eta, alpha, m=q["nodes"])
    lo = _x64(furnace_kernel, *flat, eta, alpha, m=q["nodes"] // 2)
    return hi.reshape(arrs[0].shape), np.abs(hi - lo).reshape(arrs[0].shape)


def tables(axes=None, resolution=None, *, quadrature=None, model=None, which=TABLES, start=None, stop=None):
    """Compute the tables ``which`` (a subset of :data:`TABLES`) for rows [start, stop) of their first axis.

    Returns {name: (values, errors)}, float64: ``mean_energy`` (S, n_roughness, n_absorption, 4) and
    ``dual_scattering`` (S, n_roughness, n_absorption, 6), S rows of ``sin_theta_o``; ``coverage``
    (S, n_strand_count), S rows of ``radius_px``.  ``start``/``stop`` index the first axis of each table
    asked for (so ask for the BSDF tables and coverage separately when their row counts differ); a row's
    numbers do not depend on the range.  ``axes``, ``resolution``, ``quadrature`` and ``model`` update
    :data:`DEFAULT_AXES`, :data:`DEFAULT_RESOLUTION`, :data:`DEFAULT_QUADRATURE` and :data:`DEFAULT_MODEL`
    (ValidationError naming the key otherwise)."""
    which = (which,) if isinstance(which, str) else tuple(which)
    bad = [w for w in which if w not in TABLES]
    if bad:
        raise ValidationError("which", bad[0], f"must be among {', '.join(TABLES)}")
    ax = check_axes(axes)
    nodes = axis_nodes(ax, resolution)
    q = check_quadrature(quadrature)
    eta, alpha = check_model_dict(model)
    out = {}
    if "mean_energy" in which or "dual_scattering" in which:
        i0, i1 = _rows(start, stop, nodes["sin_theta_o"].size, "rows")
        sigma = absorption_sigma(nodes["absorption"], nodes["roughness"], ax["absorption_kind"])
        res = [[], [], [], []]
        for i in range(i0, i1):
            so = np.float64(nodes["sin_theta_o"][i])
            got = _x64(bsdf_row_kernel, so, nodes["roughness"], sigma, eta, alpha, m=q["nodes"], levels=q["levels"])
            for lst, x in zip(res, got):
                lst.append(x)
        shape_e = (0, nodes["roughness"].size, nodes["absorption"].size)
        stacked = [np.stack(x) if x else np.zeros((*shape_e, n)) for x, n in zip(res, (4, 4, 6, 6))]
        if "mean_energy" in which:
            out["mean_energy"] = (stacked[0], stacked[1])
        if "dual_scattering" in which:
            out["dual_scattering"] = (stacked[2], stacked[3])
    if "coverage" in which:
        i0, i1 = _rows(start, stop, nodes["radius_px"].size, "rows")
        counts = nodes["strand_count"]
        vals, errs = [], []
        for i in range(i0, i1):
            r = np.float64(nodes["radius_px"][i])
            v, e = _x64(coverage_row_kernel, r, counts, m=q["coverage_nodes"])
            vals.append(v)
            errs.append(e)
        empty = np.zeros((0, counts.size))
        out["coverage"] = (np.stack(vals) if vals else empty, np.stack(errs) if errs else empty)
    return out
