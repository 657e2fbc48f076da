"""The hair tables' axes, defaults and limits, the checks of their arguments, and how a row kernel is run.

The tables (:data:`TABLES`) are Unreal Engine's (its ``HairStrandsLUT`` bakes them by uniform Monte Carlo),
computed from the BSDF of Chiang et al. 2016, "A Practical and Controllable Hair and Fur Model for Production
Path Tracing" (:mod:`._energy`, :mod:`._coverage`).

**Axes** (Unreal's, :data:`DEFAULT_AXES`).  Every axis has ``n`` nodes at the *cell centres* of its range
[lo, hi], x_i = lo + (i + ½)(hi − lo)/n, which is where a GPU's bilinear sampler reads texel i:

- ``sin_theta_o`` ∈ [0, 1]: sin θ_o of the outgoing (view) direction against the fibre.  [0, 1] suffices
  for the energies (they depend on cos θ_o only); the longitudinal shifts ᾱ are not symmetric in θ_o when
  the cuticle tilt α ≠ 0, so a range reaching −1 may be asked for.
- ``roughness`` ∈ (0, 1]: one roughness for both of Chiang's: β_m = β_n = roughness.
- ``absorption``: with ``absorption_kind = "colour"`` (the default) Unreal's perceptual absorption axis
  c ∈ [0, 1]: the linear hair colour is C = c² (Unreal's ``ToLinearAbsorption``) and σ_a follows from C
  through [Chiang eq. 9] with β_n = roughness; with ``"sigma_a"`` the axis is σ_a itself (per unit radius).
- coverage: ``radius_px`` ∈ [0, 0.5] (the strand radius in pixels, Unreal's range) and ``strand_count``
  over [−0.5, 63.5], whose cell centres are the counts 0, 1, …, 63 (Unreal's texel i holds i strands).

:func:`peak_bytes` bounds a row kernel's working memory before anything is allocated; :func:`_rows` checks a
range of rows and :func:`_x64` runs a kernel in float64 on NumPy inputs and returns NumPy outputs.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ValidationError
from . import _bsdf as B

TABLES = ("mean_energy", "dual_scattering", "coverage")
MEAN_ENERGY_FIELDS = ("R", "TT", "TRT", "residual")
DUAL_SCATTERING_FIELDS = ("A_f", "A_b", "alpha_f", "alpha_b", "beta_f", "beta_b")
ABSORPTION_KINDS = ("colour", "sigma_a")
#: Unreal's axes (module docstring).
DEFAULT_AXES = {
    "sin_theta_o": (0.0, 1.0),
    "roughness": (0.0, 1.0),
    "absorption": (0.0, 1.0),
    "absorption_kind": "colour",
    "radius_px": (0.0, 0.5),
    "strand_count": (-0.5, 63.5),
}
#: Unreal's resolutions: 64 × 64 × 16 for the BSDF tables, 64 × 64 for coverage.
DEFAULT_RESOLUTION = {"sin_theta_o": 64, "roughness": 64, "absorption": 16, "radius_px": 64, "strand_count": 64}
#: Gauss–Legendre nodes per panel (``nodes``, even: the error estimate uses half of them), the grading levels
#: about each sharp feature (``levels``) and the nodes per panel of the coverage integrals.
DEFAULT_QUADRATURE = {"nodes": 12, "levels": 4, "coverage_nodes": 16}
#: The BSDF's constants (η, the cuticle tilt α in degrees): pbrt-v4's defaults.
DEFAULT_MODEL = {"eta": B.ETA, "alpha": B.ALPHA}
MAX_NODES = 64
MAX_RESOLUTION = 4096


# ----------------------------------------------------------------------------- axes and validation


def _range(value, field: str, lo=None, hi=None) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ValidationError(field, value, "need a range (lo, hi) of two numbers") from None
    if not (math.isfinite(a) and math.isfinite(b)) or not a < b:
        raise ValidationError(field, value, "need finite lo < hi")
    if (lo is not None and a < lo) or (hi is not None and b > hi):
        raise ValidationError(field, value, f"must lie within [{lo:g}, {hi:g}]" if hi is not None else f"must be ≥ {lo:g}")
    return a, b


def check_axes(axes: dict | None) -> dict:
    """:data:`DEFAULT_AXES` updated by ``axes``, each range checked (ValidationError naming ``axes.KEY``)."""
    axes = dict(axes or {})
    unknown = sorted(set(axes) - set(DEFAULT_AXES))
    if unknown:
        raise ValidationError(f"axes.{unknown[0]}", axes[unknown[0]], f"unknown axis; known: {', '.join(DEFAULT_AXES)}")
    out = {**DEFAULT_AXES, **axes}
    kind = out["absorption_kind"]
    if kind not in ABSORPTION_KINDS:
        raise ValidationError("axes.absorption_kind", kind, f"must be one of {', '.join(ABSORPTION_KINDS)}")
    out["sin_theta_o"] = _range(out["sin_theta_o"], "axes.sin_theta_o", -1.0, 1.0)
    out["roughness"] = _range(out["roughness"], "axes.roughness", 0.0, 1.0)
    out["absorption"] = _range(out["absorption"], "axes.absorption", 0.0, 1.0 if kind == "colour" else None)
    out["radius_px"] = _range(out["radius_px"], "axes.radius_px", 0.0, None)
    out["strand_count"] = _range(out["strand_count"], "axes.strand_count", -1.0, None)
    return out


def check_resolution(resolution: dict | None) -> dict:
    """:data:`DEFAULT_RESOLUTION` updated by ``resolution`` (integers in [1, MAX_RESOLUTION])."""
    resolution = dict(resolution or {})
    unknown = sorted(set(resolution) - set(DEFAULT_RESOLUTION))
    if unknown:
        raise ValidationError(f"resolution.{unknown[0]}", resolution[unknown[0]], "unknown axis")
    out = {**DEFAULT_RESOLUTION, **resolution}
    for name, n in out.items():
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_RESOLUTION:
            raise ValidationError(f"resolution.{name}", n, f"must be an integer in [1, {MAX_RESOLUTION}]")
        out[name] = int(n)
    return out


def check_quadrature(quadrature: dict | None) -> dict:
    """:data:`DEFAULT_QUADRATURE` updated by ``quadrature``: ``nodes`` and ``coverage_nodes`` even integers in
    [2, MAX_NODES], ``levels`` an integer in [1, 8]."""
    quadrature = dict(quadrature or {})
    unknown = sorted(set(quadrature) - set(DEFAULT_QUADRATURE))
    if unknown:
        raise ValidationError(f"quadrature.{unknown[0]}", quadrature[unknown[0]], "unknown key")
    out = {**DEFAULT_QUADRATURE, **quadrature}
    for name in ("nodes", "coverage_nodes"):
        n = out[name]
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 2 <= n <= MAX_NODES or n % 2:
            raise ValidationError(f"quadrature.{name}", n, f"must be an even integer in [2, {MAX_NODES}]")
    n = out["levels"]
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 8:
        raise ValidationError("quadrature.levels", n, "must be an integer in [1, 8]")
    return {k: int(v) for k, v in out.items()}


def check_model_dict(model: dict | None) -> tuple[float, float]:
    """(η, α in radians) from ``model`` ({"eta", "alpha" (degrees)}, defaults :data:`DEFAULT_MODEL`)."""
    model = dict(model or {})
    unknown = sorted(set(model) - set(DEFAULT_MODEL))
    if unknown:
        raise ValidationError(f"model.{unknown[0]}", model[unknown[0]], "unknown key; known: eta, alpha")
    out = {**DEFAULT_MODEL, **model}
    try:
        alpha, eta = B.check_model(out["alpha"], out["eta"])
    except ValidationError as exc:
        raise ValidationError(f"model.{exc.field}", exc.value, exc.reason) from None
    return eta, alpha


def axis_nodes(axes: dict | None = None, resolution: dict | None = None) -> dict[str, np.ndarray]:
    """The cell-centre nodes of every axis (float64): lo + (i + ½)(hi − lo)/n."""
    axes, resolution = check_axes(axes), check_resolution(resolution)
    out = {}
    for name, n in resolution.items():
        lo, hi = axes[name]
        out[name] = lo + (np.arange(n, dtype=np.float64) + 0.5) * ((hi - lo) / n)
    return out


def absorption_sigma(absorption, roughness, kind: str) -> np.ndarray:
    """σ_a (R, K) for the absorption nodes (K,) at each roughness (R,): the colour axis maps c → C = c² →
    [Chiang eq. 9] with β_n = roughness; the σ_a axis is used as is."""
    a = np.asarray(absorption, np.float64)[None, :]
    r = np.asarray(roughness, np.float64)[:, None]
    if kind == "sigma_a":
        return np.broadcast_to(a, (r.shape[0], a.shape[1])).copy()
    return B.colour_to_sigma_a(a * a, r)


def peak_bytes(resolution=None, quadrature=None, *, block: int = 4096) -> dict[str, int]:
    """An upper estimate of the working memory (bytes) of one row kernel, before anything is allocated:
    ``bsdf_row`` (both BSDF tables), ``coverage_row`` and ``montecarlo_row`` (``block`` samples at a time).
    Each counts its float64 temporaries live at once: for ``bsdf_row`` 16 arrays over (roughness, every lobe's
    and both rules' γ nodes) (the per-node geometry and one absorption column's terms; measured 9.0 MB of XLA
    temporaries at the defaults against this 18.5 MB), 8 over the θ nodes and the (R, K) results; the tables
    themselves (rows × … × 8 bytes, twice with the errors) are the caller's."""
    res, q = check_resolution(resolution), check_quadrature(quadrature)
    r, k, m, lv = res["roughness"], res["absorption"], q["nodes"], q["levels"]
    both = m + m // 2  # nodes per panel of the two rules together
    n_h = both * (2 * (4 * lv + 6) + 12 * lv + 10)  # panels: 4L + 6 for lobes 0 and 1 each, 12L + 10 for TRT
    n_th = 4 * (2 * lv + 2) * both
    bsdf = 8 * (16 * r * n_h + 8 * r * n_th + 64 * r * k)
    mc = q["coverage_nodes"]
    n_x = (3 * mc) ** 2 + (3 * mc // 2) ** 2  # both rules' points
    cov = 8 * (4 * 8 * n_x + 3 * res["strand_count"] * n_x)  # per point: its 8 edge ends; per (count, point): 3
    return {"bsdf_row": int(bsdf), "coverage_row": int(cov), "montecarlo_row": int(8 * 8 * block * k * 4)}


def _rows(start, stop, total: int, field: str) -> tuple[int, int]:
    start = 0 if start is None else start
    stop = total if stop is None else stop
    for name, v in (("start", start), ("stop", stop)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise ValidationError(f"{field}.{name}", v, "must be an integer")
    if not 0 <= start <= stop <= total:
        raise ValidationError(field, (start, stop), f"need 0 ≤ start ≤ stop ≤ {total}")
    return int(start), int(stop)


# ----------------------------------------------------------------------------- running a row kernel


def _f64(a):
    if isinstance(a, float) or (isinstance(a, np.ndarray) and np.issubdtype(a.dtype, np.floating)):
        return jnp.asarray(a, jnp.float64)
    return jnp.asarray(a) if isinstance(a, np.ndarray) else a


def _x64(fn, *args, **kwargs):
    with jax.enable_x64(True):
        out = fn(*(_f64(a) for a in args), **kwargs)
        return jax.tree_util.tree_map(np.asarray, out)
