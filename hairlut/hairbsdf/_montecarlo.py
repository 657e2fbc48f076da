"""The Monte Carlo baseline: Unreal Engine's estimator of the same hair tables, for comparison with the quadrature.

:func:`montecarlo_unreal` is the baseline: Unreal's estimator (stratified uniform sampling of the sphere
with jitter, 128…64 × 128…32 strata per entry falling with roughness, the sums clamped to [0, 1]) for the
same tables, with a fixed PRNG key.  The BSDF is :mod:`._bsdf`'s (Chiang et al. 2016, "A Practical and
Controllable Hair and Fur Model for Production Path Tracing"), the dual-scattering quantities Zinke et al.
2008's (as :mod:`._energy`), the coverage measure :mod:`._coverage`'s.

Measured on the 2-core development machine, shared (load average 5–8), default axes and resolutions:

- the Unreal-style baseline against 24-node quadrature: at Unreal's counts 46.5 s wall (25.7 s CPU), max |error|
  0.94 (mean energy, TT), 0.90 (A_f), 0.83 (A_b), RMS 0.068 (mean energy) and 0.086 (A_f, A_b); at 4× the
  samples (``sample_scale`` = 2) 145 s, max 0.86 / 0.90 / 0.62, RMS 0.051 / 0.060; at 16× (``sample_scale`` = 4,
  16 rows of 64 measured, ~690 s for all) max 0.66 / 0.70 / 0.17, RMS 0.027 / 0.032.  The worst entries sit at
  the smallest roughness (0.0078), in the TT lobe, whose spike uniform sampling misses.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ValidationError
from . import _bsdf as B
from ._axes import TABLES, _rows, _x64, absorption_sigma, axis_nodes, check_axes, check_model_dict

#: Unreal's strata per entry: θ from 128 (smooth) to 64 (rough), φ from 128 to 32 (``HairStrandsLUT.usf``).
UNREAL_THETA = (128, 64)
UNREAL_PHI = (128, 32)
#: Coverage trials per entry of the Monte Carlo baseline (Unreal's coverage sampling is not public; our choice).
UNREAL_COVERAGE_TRIALS = 1024
_TWO_PI = 2.0 * math.pi


# ----------------------------------------------------------------------------- the Monte Carlo baseline


def _mc_row(sin_o, rough, sigma, n_theta, n_phi, jitter, hs, eta, alpha, block: int):
    """Unreal's estimator for one sin θ_o: per roughness, n_θ × n_φ jittered strata of the sphere (row-major in
    the strata, jitter and h from shared tables indexed by stratum), summed in blocks."""
    cos_o = B._sqrt1m(sin_o)
    theta_o = jnp.arctan2(sin_o, cos_o)
    sin_p, cos_p = B.tilt(sin_o, cos_o, alpha)
    k_count = sigma.shape[-1]

    def per_rough(args):
        r, sg, nt, npf = args
        total = nt * npf
        nblocks = (total + block - 1) // block
        sa = sg[None, :]
        v, s = B.longitudinal_variance(r), B.azimuthal_scale(r)

        def body(b, acc):
            j = b * block + jnp.arange(block)
            ok = j < total
            jj = jnp.where(ok, j, 0)
            ia, ib = jj % nt, jj // nt
            idx = ia * _MC_PHI_STRIDE + ib
            jt = jitter[idx]
            sin_i = 1.0 - 2.0 * (ia + jt[:, 0]) / nt
            cos_i = B._sqrt1m(sin_i)
            phi_i = _TWO_PI * (ib + jt[:, 1]) / npf
            h = hs[idx]
            gamma_o, cos_go, gamma_t, cos_gt, cos_t = B._fibre(sin_o, cos_o, h, eta)
            m_, n_ = B._mn(sin_i, cos_i, phi_i, sin_p, cos_p, v, s, gamma_o, gamma_t)
            t = jnp.exp(-sa * (2.0 * cos_gt / cos_t)[:, None])  # (block, K)
            a = B.attenuation(B.fresnel(cos_o * cos_go, eta)[:, None], t)  # (block, K, 4)
            mn = jnp.where(ok[:, None], m_ * n_, 0.0)  # (block, 4)
            g = mn[:, None, :] * a * (4.0 * math.pi)  # f / pdf, pdf = 1/(4π)
            is_back = jnp.cos(phi_i) > 0.0
            okb, okf = ok & is_back, ok & ~is_back
            theta_h = 0.5 * (jnp.arcsin(sin_i) + theta_o)
            s_all, s_f, s_b, c_f, c_b, m0, m1, m2 = acc
            return (
                s_all + jnp.sum(g, axis=0),
                s_f + jnp.sum(jnp.where(okf[:, None, None], g, 0.0), axis=0),
                s_b + jnp.sum(jnp.where(okb[:, None, None], g, 0.0), axis=0),
                c_f + jnp.sum(okf),
                c_b + jnp.sum(okb),
                m0 + jnp.sum(mn, axis=0),
                m1 + jnp.sum(mn * theta_h[:, None], axis=0),
                m2 + jnp.sum(mn * theta_h[:, None] ** 2, axis=0),
            )

        z = jnp.zeros((k_count, 4))
        z4 = jnp.zeros(4)
        zero = jnp.zeros((), total.dtype)
        s_all, s_f, s_b, c_f, c_b, m0, m1, m2 = jax.lax.fori_loop(0, nblocks, body, (z, z, z, zero, zero, z4, z4, z4))
        energy = jnp.clip(s_all / total, 0.0, 1.0)
        fr = 0.5 * s_f / jnp.maximum(c_f, 1)
        bk = 0.5 * s_b / jnp.maximum(c_b, 1)
        mean_a = m1 / jnp.where(m0 > 0, m0, 1.0)
        var_b = jnp.maximum(m2 / jnp.where(m0 > 0, m0, 1.0) - mean_a**2, 0.0)
        a_f, a_b = jnp.sum(fr, axis=-1), jnp.sum(bk, axis=-1)

        def weighted(wt, tot, x):
            ok = tot > 0.0
            return jnp.where(ok, jnp.sum(wt * x[None, :], axis=-1) / jnp.where(ok, tot, 1.0), 0.0)

        dual = jnp.stack(
            [
                jnp.clip(a_f, 0.0, 1.0),
                jnp.clip(a_b, 0.0, 1.0),
                weighted(fr, a_f, mean_a),
                weighted(bk, a_b, mean_a),
                jnp.sqrt(weighted(fr, a_f, var_b)),
                jnp.sqrt(weighted(bk, a_b, var_b)),
            ],
            axis=-1,
        )
        return energy, dual

    return jax.lax.map(per_rough, (rough, sigma, n_theta, n_phi))


#: Stride of the φ stratum in the shared jitter tables (the largest φ count the tables allow).
_MC_PHI_STRIDE = 128 * 16


@functools.partial(jax.jit, static_argnames=("block",))
def montecarlo_row_kernel(sin_o, rough, sigma, n_theta, n_phi, jitter, hs, eta, alpha, *, block):
    """Unreal's uniform Monte Carlo for one sin θ_o row → (mean energy (R, K, 4), dual scattering (R, K, 6))."""
    return _mc_row(sin_o, rough, sigma, n_theta, n_phi, jitter, hs, eta, alpha, block)


@functools.partial(jax.jit, static_argnames=("trials", "strands"))
def montecarlo_coverage_kernel(key, r, counts, *, trials, strands):
    """Random strands (a uniform point of the pixel and a uniform orientation each) over one random point of the
    pixel per trial: the covered share for the first N strands, N = counts (C,) (rounded), over ``trials``."""
    k1, k2, k3 = jax.random.split(key, 3)
    pts = jax.random.uniform(k1, (trials, strands, 2), jnp.float64)
    ang = jax.random.uniform(k2, (trials, strands), jnp.float64) * math.pi
    x = jax.random.uniform(k3, (trials, 1, 2), jnp.float64)
    dist = jnp.abs((x[..., 0] - pts[..., 0]) * jnp.sin(ang) - (x[..., 1] - pts[..., 1]) * jnp.cos(ang))
    hit = jnp.cumsum(dist <= r, axis=-1) > 0  # (trials, strands): covered by the first j+1 strands
    hit = jnp.concatenate([jnp.zeros((trials, 1), bool), hit], axis=-1)
    n = jnp.clip(jnp.round(counts).astype(jnp.int32), 0, strands)
    return jnp.mean(hit[:, n].astype(jnp.float64), axis=0)


# ----------------------------------------------------------------------------- the baseline's tables


def unreal_counts(roughness, sample_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Unreal's strata per entry (n_θ, n_φ), each ``max(1, round(sample_scale · lerp(hi, lo, roughness)))``.

    ``sample_scale`` multiplies each axis (Unreal's ``SampleCountScale``), so the sample count grows as its
    square: 2 gives 4× the samples, 4 gives 16×."""
    r = np.asarray(roughness, np.float64)
    nt = np.maximum(1, np.rint(sample_scale * (UNREAL_THETA[0] + (UNREAL_THETA[1] - UNREAL_THETA[0]) * r))).astype(np.int64)
    npf = np.maximum(1, np.rint(sample_scale * (UNREAL_PHI[0] + (UNREAL_PHI[1] - UNREAL_PHI[0]) * r))).astype(np.int64)
    return nt, npf


def montecarlo_unreal(
    axes=None,
    resolution=None,
    *,
    sample_scale: float = 1.0,
    coverage_trials: int = UNREAL_COVERAGE_TRIALS,
    seed: int = 0,
    model=None,
    which=TABLES,
    start=None,
    stop=None,
    block: int = 4096,
) -> dict[str, np.ndarray]:
    """The Unreal-style baseline for the same tables (values only, no error), deterministic for a ``seed``.

    BSDF tables: for each entry, n_θ × n_φ strata of the sphere (:func:`unreal_counts`), one direction per
    stratum jittered (sin θ_i = 1 − 2u, φ_i = 2πu′, pdf 1/(4π)) and one offset h uniform in [−1, 1]; the jitter
    and h of stratum (a, b) are shared by every entry (Unreal shares its R2 jitter likewise).  mean energy =
    the mean of f·cos/pdf per lobe; A_f, A_b = ½ × the mean over the front (back) samples, as Unreal's
    ``HemisphereFactor``; all clamped to [0, 1] (Unreal's ``saturate``).  ᾱ, β̄ combine the per-lobe front/back
    energies with the lobes' sample moments of θ_h (Unreal does not tabulate them).  Coverage: per entry
    ``coverage_trials`` trials of one uniform point of the pixel and N random strands (the measure of
    :mod:`._coverage`).  Returns {name: values} shaped as :func:`tables`."""
    which = (which,) if isinstance(which, str) else tuple(which)
    bad = [w for w in which if w not in TABLES]
    if bad:
        raise ValidationError("which", bad[0], f"must be among {', '.join(TABLES)}")
    scale = B.check_values(sample_scale, "sample_scale", 0.0, 16.0, lo_open=True)
    for name, v in (("coverage_trials", coverage_trials), ("seed", seed), ("block", block)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < (0 if name == "seed" else 1):
            raise ValidationError(name, v, "must be a non-negative integer" if name == "seed" else "must be a positive integer")
    ax = check_axes(axes)
    nodes = axis_nodes(ax, resolution)
    eta, alpha = check_model_dict(model)
    key = jax.random.PRNGKey(int(seed))
    out = {}
    if "mean_energy" in which or "dual_scattering" in which:
        i0, i1 = _rows(start, stop, nodes["sin_theta_o"].size, "rows")
        sigma = absorption_sigma(nodes["absorption"], nodes["roughness"], ax["absorption_kind"])
        nt, npf = unreal_counts(nodes["roughness"], float(scale))
        if int(npf.max()) > _MC_PHI_STRIDE or int(nt.max()) > _MC_PHI_STRIDE:
            raise ValidationError("sample_scale", float(scale), f"at most {_MC_PHI_STRIDE} strata per axis")
        with jax.enable_x64(True):
            kj, kh = jax.random.split(key)
            size = int(nt.max()) * _MC_PHI_STRIDE
            jitter = np.asarray(jax.random.uniform(kj, (size, 2), jnp.float64))
            hs = np.asarray(jax.random.uniform(kh, (size,), jnp.float64, -1.0, 1.0))
        energy, dual = [], []
        for i in range(i0, i1):
            so = np.float64(nodes["sin_theta_o"][i])
            e, d = _x64(montecarlo_row_kernel, so, nodes["roughness"], sigma, nt, npf, jitter, hs, eta, alpha, block=block)
            energy.append(e)
            dual.append(d)
        shape = (0, nodes["roughness"].size, nodes["absorption"].size)
        if "mean_energy" in which:
            out["mean_energy"] = np.stack(energy) if energy else np.zeros((*shape, 4))
        if "dual_scattering" in which:
            out["dual_scattering"] = np.stack(dual) if dual else np.zeros((*shape, 6))
    if "coverage" in which:
        i0, i1 = _rows(start, stop, nodes["radius_px"].size, "rows")
        counts = nodes["strand_count"]
        strands = max(1, int(np.ceil(counts.max())))
        rows = []
        for i in range(i0, i1):
            with jax.enable_x64(True):
                k = jax.random.fold_in(jax.random.fold_in(key, 1), i)
                rows.append(
                    np.asarray(
                        montecarlo_coverage_kernel(
                            k,
                            jnp.float64(nodes["radius_px"][i]),
                            jnp.asarray(counts),
                            trials=int(coverage_trials),
                            strands=strands,
                        )
                    )
                )
        out["coverage"] = np.stack(rows) if rows else np.zeros((0, counts.size))
    return out
