"""Per-light transmittance at arbitrary 3-D points from the strands: the light-space shadow methods.

The online module's shadow seam (satf eq 13 with one τ per light): shading multiplies each
light's contribution at a texel by that light's transmittance T toward it.  This module
builds T for the methods that work in light space, one map per (distant) light:

``light_oriented``  the light-oriented density map (bertails §2–3): a light-aligned grid
                    of hair length per unit volume, Trans = exp(−κ ∫ ρ dl) (eqs 1–3),
                    trilinear between cell centres (§3.3);
``opacity_maps``    opacity shadow maps (kim ch. 6, eqs 6-1, 6-2): slices perpendicular to
                    the light, Ω accumulated from the light, τ = exp(−κ Ω).

Both are evaluated with one κ meaning: the light-blocking width of a fibre, a length in
the scene's units (opacity maps are built with unit width, so Ω is hair length per unit
area, as the density map's ∫ ρ dl).  ``kappa=None`` takes the strands' mean diameter
(``Strands.thickness``): fibres that block what they cover.  The eq 12 s-map is not here:
it needs the α-maps of a view and lives with the online shading kernel.
"""

from __future__ import annotations

import numpy as np

from .. import errors
from ._light import check_kappa
from ._light_oriented import light_oriented_map
from ._opacity import opacity_shadow_maps

LIGHT_METHODS = ("light_oriented", "opacity_maps")


def fibre_width(strands) -> float:
    """The mean strand diameter (``Strands.thickness``): the default κ of :func:`light_transmittance`."""
    if strands.thickness is None or not len(strands.thickness):
        raise errors.ValidationError("kappa", None, "the strands carry no thickness: give κ (the fibre width)")
    return float(np.mean(strands.thickness))


def light_transmittance(
    strands, lights, points, *, method: str, resolution: int = 32, kappa: float | None = None, slices: int = 16, padding: int = 2
) -> np.ndarray:
    """T (..., L) in [0, 1] toward each light (L, 3) at ``points`` (..., 3), from ``strands``.

    ``method``: ``light_oriented`` (``resolution`` cells along the hair's longest extent in
    the light frame, ``padding`` empty cells around) or ``opacity_maps`` (``resolution``
    texels over the footprint's longer side, ``slices`` slices in depth); ``kappa`` as in
    the module docstring.  One map per light; points in front of the hair (nearer the light)
    or beside it get T = 1."""
    if method not in LIGHT_METHODS:
        raise errors.ValidationError("method", method, f"one of {', '.join(LIGHT_METHODS)}")
    lights = np.atleast_2d(np.asarray(lights, np.float64))
    pts = np.asarray(points, np.float64)
    flat = pts.reshape(-1, 3)
    k = fibre_width(strands) if kappa is None else check_kappa(kappa)
    out = np.empty((len(flat), len(lights)))
    for j, light in enumerate(lights):
        if method == "light_oriented":
            m = light_oriented_map(strands, light, resolution=resolution, kappa=k, padding=padding)
        else:
            m = opacity_shadow_maps(strands, light, n_slices=slices, resolution=resolution, kappa=k, width=1.0)
        out[:, j] = m.at(flat)
    return out.reshape(pts.shape[:-1] + (len(lights),))
