"""Stress cases for the shadow methods (xing §5, bertails, kim ch. 6, satf eq 12): empty,
single-voxel and one-strand grooms, and transmittances that underflow exp().

Every method is run through its public entry point: ``light_oriented`` and ``opacity_maps``
through :func:`hairlut.shadows.light_transmittance`, the voxel SH transmittance through
:func:`hairlut.shadows.voxelize` + :func:`hairlut.shadows.transmittance` (T toward the light is
Σ_j b_j Y_j(light) at the strands' own vertices, where the method defines it; its SH ringing is
counted, and the bound checked is the mean transmittance b_0/√(4π) ∈ [0, 1]), and the s-map
through :func:`hairlut.synth.shadow_map`.  The float64 reference is :func:`hairlut.shadows.ray_march` (a world-aligned density marched
toward the light) and, for the s-map, exp(−k Σ α) in NumPy.
"""

from __future__ import annotations

import math

import numpy as np

from .. import errors
from ._tally import Case

LIGHT = np.array([0.0, 0.0, 1.0])
#: Grid resolution of every shadow method here (cells along the groom's longest side).
RESOLUTION = 12
#: Extinction scales of the underflow case: exp(−κ τ) underflows float32 from κ τ ≈ 104, float64 from ≈ 745.
UNDERFLOW_KAPPAS = (1e3, 1e6, 1e30)

#: light-space maps vs the world-aligned ray march, max |ΔT|: the two grids differ by up to half a cell, and a
#: lone strand's shadow is one cell wide (trilinear blur); tests/test_light_oriented.py allows 0.06 on a tuft.
SHADOW_TOL = 0.25
#: the same at underflow, where both must give T = 0 (or 1 in front) to rounding.
UNDERFLOW_TOL = 1e-6


def _strands(points, counts, thickness=0.01):
    from ..geometry import Strands

    points = np.asarray(points, np.float64).reshape(-1, 3)
    return Strands(points, np.asarray(counts, np.int64), thickness=np.full(len(points), thickness))


def one_strand():
    """One straight strand along x, 8 points over [−0.5, 0.5]."""
    x = np.linspace(-0.5, 0.5, 8)
    return _strands(np.stack([x, np.zeros(8), np.zeros(8)], 1), [8])


def single_voxel():
    """One short strand (length 1e-3): the whole groom inside one cell."""
    return _strands([[0.0, 0.0, 0.0], [1e-3, 0.0, 0.0], [1e-3, 1e-3, 0.0]], [3])


def tuft(n: int = 40, seed: int = 0):
    """``n`` parallel strands along x through a 0.2 × 0.2 cross-section: a dense groom."""
    rng = np.random.default_rng(seed)
    yz = rng.uniform(-0.1, 0.1, (n, 2))
    x = np.linspace(-0.5, 0.5, 6)
    pts = np.stack([np.broadcast_to(x, (n, 6)), np.repeat(yz[:, :1], 6, 1), np.repeat(yz[:, 1:], 6, 1)], -1)
    return _strands(pts, np.full(n, 6))


def probes(strands, vertices: bool = True) -> np.ndarray:
    """Points 1.5 cells below and above every vertex (with ``vertices``), below and above the groom's
    footprint shrunk by 1.5 cells (away from the shadow's blurred edge), and 6 cells beside it (lit):
    inside every method's grid."""
    pts = strands.points
    lo, hi = pts.min(0), pts.max(0)
    cell = max(float((hi - lo).max()), 1e-9) / RESOLUTION

    def axis(k, n):
        a, b = lo[k] + 1.5 * cell, hi[k] - 1.5 * cell
        return np.linspace(a, b, n) if b > a else np.array([0.5 * (lo[k] + hi[k])])

    uu, vv = np.meshgrid(axis(0, 7), axis(1, 5), indexing="ij")
    out = [np.stack([uu, vv, np.full_like(uu, z)], -1).reshape(-1, 3) for z in (lo[2] - 1.5 * cell, hi[2] + 1.5 * cell)]
    mid = 0.5 * (lo + hi)
    out.append(np.array([[mid[0], hi[1] + 6 * cell, mid[2]], [mid[0], lo[1] - 6 * cell, mid[2]]]))
    if vertices:
        out += [pts + [0.0, 0.0, -1.5 * cell], pts + [0.0, 0.0, 1.5 * cell]]
    return np.concatenate(out)


def _ray_march(points, light, kappa, strands):
    from ..shadows import ray_march

    return ray_march(points, light, kappa, strands, RESOLUTION)


def _voxel_sh(strands, kappa, points):
    """(mean transmittance b_0/√(4π), T toward LIGHT = Σ b_j Y_j(LIGHT)) from the voxel SH transmittance."""
    from ..sh import real_sh
    from ..shadows import transmittance, voxelize

    tr = transmittance(voxelize(strands, RESOLUTION), kappa, lmax=2, stride=1)
    b = tr.at(points)
    return b[:, 0] / math.sqrt(4 * np.pi), b @ np.asarray(real_sh(2, LIGHT[None]))[0]


def _methods(tally, ctx, label, strands, kappa, vertices: bool = True):
    """Every strand-based method on ``strands`` at the probes: finite, T ∈ [0, 1], error vs the ray march."""
    from ..shadows import light_transmittance

    pts = probes(strands, vertices)
    ref = np.asarray(ctx.reference(pts, LIGHT, kappa, strands), np.float64)
    tally.within(f"{label} reference T", ref, 0.0, 1.0)
    errs = []
    for method in ("light_oriented", "opacity_maps"):
        T = light_transmittance(strands, LIGHT, pts, method=method, resolution=RESOLUTION, kappa=kappa)[:, 0]
        tally.within(f"{label} {method} T", T, 0.0, 1.0)
        errs.append(f"{method} {tally.compare(f'{label} {method}', T, ref, scale=1.0):.3f}")
    tally.note(f"{label}: max |ΔT| vs the ray march: {', '.join(errs)}")
    mean, toward = _voxel_sh(strands, kappa, strands.points)  # defined at the hair's own vertices (xing §5)
    tally.within(f"{label} voxel SH mean T", mean, 0.0, 1.0, slack=1e-12)
    toward = tally.finite(f"{label} voxel SH T(light)", toward)
    ringing = int(((toward < 0) | (toward > 1)).sum())
    tally.count("voxel SH T(light) outside [0, 1] (SH ringing)", ringing)
    return ref


def _empty(tally, ctx):
    from ..shadows import light_transmittance, transmittance, voxelize
    from ..synth import shadow_map

    empty = _strands(np.zeros((0, 3)), [])
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, -3.0]])
    for method in ("light_oriented", "opacity_maps"):
        try:
            T = light_transmittance(empty, LIGHT, pts, method=method, resolution=RESOLUTION, kappa=1.0)
        except errors.HairlutError as exc:
            tally.count("rejected", 1)
            tally.note(f"{method}: {type(exc).__name__}")
        else:
            tally.compare(f"empty {method} T = 1", T[:, 0], np.ones(len(pts)), scale=1.0)
    tally.rejects("voxelize(empty)", lambda: transmittance(voxelize(empty, RESOLUTION), 1.0))
    tally.rejects("ray_march(empty)", lambda: ctx.reference(pts, LIGHT, 1.0, empty))
    tau = tally.finite("s-map of empty α-maps", shadow_map(np.zeros((3, 4, 5), np.float32), 2.0))
    tally.compare("s-map of empty α-maps = 1", tau, np.ones_like(tau), scale=1.0)
    tally.note("an empty groom: T = 1 or a ValidationError, never NaN")


def _one_strand(tally, ctx):
    ref = _methods(tally, ctx, "one strand", one_strand(), kappa=0.05)
    if ref.min() >= 1.0:
        tally.fault("one strand: the reference sees no shadow (the case is vacuous)")
    tally.note(
        f"one straight strand, κ = 0.05, {RESOLUTION} cells; reference T min {ref.min():.3f} (a one-cell "
        "shadow: each method's grid places it differently)"
    )


def _single_voxel(tally, ctx):
    from ..shadows import light_transmittance

    ref = _methods(tally, ctx, "single voxel", single_voxel(), kappa=1e-3)

    zero = _strands(np.zeros((2, 3)), [2])  # a zero-length strand: a point of hair in a single voxel
    tally.rejects("voxel SH of a zero-length strand", lambda: _voxel_sh(zero, 1.0, np.zeros((1, 3))))
    pts = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    for method in ("light_oriented", "opacity_maps"):
        try:
            T = light_transmittance(zero, LIGHT, pts, method=method, resolution=RESOLUTION, kappa=1.0)
        except errors.HairlutError:
            tally.count("rejected", 1)
        else:
            tally.within(f"zero-length strand {method}", T, 0.0, 1.0)
    tally.note(f"a 1e-3 groom of three points (reference T min {ref.min():.3g}), and a zero-length strand (one voxel, no length)")


def _underflow(tally, ctx):
    import jax.numpy as jnp

    from ..synth import shadow_map

    kappas = UNDERFLOW_KAPPAS[:2] if ctx.quick else UNDERFLOW_KAPPAS
    g = tuft()
    for kappa in kappas:
        ref = _methods(tally, ctx, f"κ={kappa:g}", g, kappa, vertices=False)  # in the tuft, any blur is 0 or 1
        if ref.min() > 0.0 or ref.max() < 1.0:
            tally.fault(f"κ={kappa:g}: the reference does not reach both T = 0 and T = 1 (the case is vacuous)")
    alpha = jnp.ones((4, 3, 3), jnp.float32)  # four opaque layers: Σ_{m>k} α_m = 3 − k
    outer = np.arange(3, -1, -1, dtype=np.float64)[:, None, None] * np.ones((4, 3, 3))
    for k in (1e3, 1e6, 1e30):
        tau = tally.finite(f"s-map k={k:g}", shadow_map(alpha, k))
        tally.within(f"s-map k={k:g}", tau, 0.0, 1.0)
        tally.compare(f"s-map k={k:g}", tau, np.exp(-k * outer), scale=1.0)
    tally.note(f"a 40-strand tuft with κ ∈ {{{', '.join(f'{k:g}' for k in kappas)}}}; s-map with k_shadow up to 1e30")


CASES = (
    Case(
        "shadow.empty_groom",
        "no strands: T = 1 or rejected, never NaN (every method, s-map)",
        0.0,
        "exact: nothing blocks the light",
        _ray_march,
        _empty,
    ),
    Case(
        "shadow.one_strand",
        "one strand: light-oriented, opacity maps, voxel SH vs the ray march",
        SHADOW_TOL,
        "half-cell grid offsets on a one-cell-wide shadow",
        _ray_march,
        _one_strand,
    ),
    Case(
        "shadow.single_voxel",
        "a 1e-3 groom, and a zero-length strand (one voxel)",
        SHADOW_TOL,
        "half-cell grid offsets on a one-cell-wide shadow",
        _ray_march,
        _single_voxel,
    ),
    Case(
        "shadow.underflow",
        "exp(−κτ) underflows (κ up to 1e30): T = 0 behind, 1 in front, no NaN",
        UNDERFLOW_TOL,
        "both sides saturate to 0 or 1; only rounding differs",
        _ray_march,
        _underflow,
    ),
)
