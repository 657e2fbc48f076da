"""Reading the ``hair_bsdf`` tables and looking them up the way a GPU's texture sampler does.

:func:`load` reads the HDF5 asset (every table, its per-entry error, the axes) or the EXR atlas (the values
only), and :meth:`HairBSDFTables.sample` interpolates a table at any coordinates exactly as a GPU's linear
sampler with clamp-to-edge addressing reads a texture whose texels are the table's nodes: along each axis of
n nodes over [lo, hi], the texture coordinate u = (x − lo)/(hi − lo) puts the sample at texel position
t = u·n − ½; the taps are ⌊t⌋ and ⌊t⌋ + 1, each clamped to [0, n − 1], weighted 1 − f and f with
f = t − ⌊t⌋ (bilinear in 2-D, trilinear in 3-D: the product of the three weights).  At a node the sample is the
stored value itself.  Hardware computes f in fixed point with a few fractional bits (8 on current GPUs, the
rounding vendor-specific); ``subtexel_bits=8`` rounds f to that grid to show its effect, the default keeps it
exact.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import errors
from ..assets import read_table, sniff
from ..assets.virtual_write import check_virtual
from ._kind import KIND
from ._recipe import QUANTITIES, resolve_recipe

GRID = ("sin_theta", "roughness", "absorption")
COVER = ("radius", "strands")
#: A texel position this close to an integer (in texels) is that node: the sample returns the stored value.
SNAP = 1e-9


def _spans(recipe: dict) -> dict[str, tuple[float, float]]:
    g, a, c = recipe["grid"], recipe["absorption"], recipe["coverage"]
    return {
        "sin_theta": tuple(g["sin_theta"]),
        "roughness": tuple(g["roughness"]),
        "absorption": tuple(a[a["axis"]]),
        "radius": tuple(c["radius"]),
        "strands": tuple(c["strands"]),
    }


def _units(recipe: dict) -> dict[str, str]:
    return {
        "sin_theta": "1",
        "roughness": "1",
        "absorption": "1" if recipe["absorption"]["axis"] == "colour" else "1/radius",
        "radius": "px",
        "strands": "1",
    }


def taps(x, span, n: int, subtexel_bits: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lower tap, upper tap, weight of the upper tap) of coordinates ``x`` on an axis of ``n`` texel-centre nodes
    over ``span``: a GPU's linear filtering with clamp-to-edge addressing (module docstring)."""
    lo, hi = span
    t = (np.asarray(x, np.float64) - lo) / (hi - lo) * n - 0.5
    near = np.round(t)
    t = np.where(np.abs(t - near) <= SNAP, near, t)
    i0 = np.floor(t)
    f = t - i0
    if subtexel_bits:
        f = np.floor(f * 2.0**subtexel_bits + 0.5) / 2.0**subtexel_bits
    i0 = i0.astype(np.int64)
    return np.clip(i0, 0, n - 1), np.clip(i0 + 1, 0, n - 1), f


@dataclass(frozen=True, eq=False)
class HairBSDFTables:
    """The ``hair_bsdf`` tables as :func:`load` returns them.

    ``values`` and ``errors`` map each quantity (``A_f``, …, ``beta_b``, ``R``, ``TT``, ``TRT``, ``coverage``) to
    its table as stored (``errors`` is None for an EXR atlas, which holds values only); ``dims`` names each
    table's axes, ``axes`` their nodes and ``spans`` the intervals [lo, hi] the nodes are the texel centres of;
    ``sigma_a`` is σ_a at each (roughness, absorption) node (None for an atlas)."""

    values: dict
    errors: dict | None
    dims: dict
    axes: dict
    spans: dict
    units: dict
    sigma_a: np.ndarray | None
    recipe: dict
    path: Path | None = None
    attrs: dict | None = None

    @property
    def names(self) -> list[str]:
        """The quantities the tables hold."""
        return list(self.values)

    def _table(self, name: str) -> np.ndarray:
        if name not in self.values:
            raise errors.ValidationError("name", name, f"not a table of this file; it holds {', '.join(self.values)}")
        return self.values[name]

    def sample(self, name: str, *coords, subtexel_bits: int | None = None) -> np.ndarray:
        """The table ``name`` at ``coords`` (broadcast arrays: sin θ, roughness, absorption for a grid table;
        strand count, radius in pixels for ``coverage``), interpolated as a GPU's linear sampler with
        clamp-to-edge addressing does (module docstring), in float64 from the stored values."""
        table = self._table(name)
        dims = self.dims[name]
        if len(coords) != len(dims):
            raise errors.ValidationError("coords", len(coords), f"{name} takes {len(dims)} coordinates: {', '.join(dims)}")
        pts = np.broadcast_arrays(*(np.asarray(c, np.float64) for c in coords))
        for d, p in zip(dims, pts):
            if not np.isfinite(p).all():
                raise errors.ValidationError(d, "NaN or infinity", "coordinates are finite numbers")
        v = np.asarray(table, np.float64)
        per_axis = [taps(p, self.spans[d], table.shape[i], subtexel_bits) for i, (d, p) in enumerate(zip(dims, pts))]
        out = np.zeros(pts[0].shape, np.float64)
        for corner in np.ndindex(*(2,) * len(dims)):
            w = np.ones(pts[0].shape, np.float64)
            idx = []
            for bit, (a, b, f) in zip(corner, per_axis):
                idx.append(b if bit else a)
                w = w * (f if bit else 1.0 - f)
            out = out + w * v[tuple(idx)]
        return out

    def absorption_of(self, *, colour=None, sigma_a=None, melanin=None, roughness=None) -> np.ndarray:
        """The absorption-axis coordinates of a hair, one per channel (on a last axis), from its linear ``colour``
        (each channel in (0, 1]), its ``sigma_a`` (each ≥ 0, per unit fibre radius) or its ``melanin``
        concentrations (eumelanin, pheomelanin; each ≥ 0; pbrt-v4's absorption per unit concentration): exactly one
        of the three.  Where the conversion runs through Chiang et al.'s eq. 9 (σ_a or melanin onto a colour axis,
        a colour onto a σ_a axis) it needs the ``roughness`` β_n."""
        given = [(k, v) for k, v in (("colour", colour), ("sigma_a", sigma_a), ("melanin", melanin)) if v is not None]
        if len(given) != 1:
            raise errors.ValidationError("absorption", [k for k, _ in given], "give exactly one of colour, sigma_a, melanin")
        key, value = given[0]
        arr = np.asarray(value, np.float64)
        if not np.isfinite(arr).all():
            raise errors.ValidationError(key, value, "must be finite (NaN or infinity given)")
        if key == "colour" and ((arr <= 0) | (arr > 1)).any():
            raise errors.ValidationError("colour", value, "each channel lies in (0, 1]")
        if key != "colour" and (arr < 0).any():
            raise errors.ValidationError(key, value, "must be ≥ 0")
        if key == "melanin" and arr.shape[-1:] != (2,):
            raise errors.ValidationError("melanin", value, "give (eumelanin, pheomelanin) concentrations")
        axis = self.recipe["absorption"]["axis"]
        if key == "colour" and axis == "colour":
            return np.sqrt(arr)  # Unreal's perceptual axis: the linear colour is c²
        if key == "sigma_a" and axis == "sigma_a":
            return arr
        needs_beta = axis == "colour" or key == "colour"  # σ_a or melanin onto colour, colour onto σ_a
        if needs_beta and roughness is None:
            raise errors.ValidationError("roughness", None, f"a {key} maps onto the {axis} axis through β_n: give the roughness")
        beta = np.asarray(1.0 if roughness is None else roughness, np.float64)
        if not (np.isfinite(beta).all() and ((beta > 0) & (beta <= 1)).all()):
            raise errors.ValidationError("roughness", roughness, "β_n lies in (0, 1]")
        beta = beta[..., None] if beta.ndim else beta
        from . import _bsdf  # Chiang et al.'s eq. 9 and pbrt's melanin (loads JAX)

        if key == "colour":
            return _bsdf.colour_to_sigma_a(arr, beta)
        sig = arr if key == "sigma_a" else _bsdf.sigma_a_from_concentration(arr[..., 0], arr[..., 1])
        return np.sqrt(_bsdf.sigma_a_to_colour(sig, beta)) if axis == "colour" else sig

    def sample_hair(self, name: str, sin_theta, roughness, *, colour=None, sigma_a=None, melanin=None) -> np.ndarray:
        """A grid table at (sin θ, roughness) for a hair given by its linear colour, σ_a or melanin
        (:meth:`absorption_of`): one value per channel, on a last axis (what a shader gets from one sample per
        colour channel)."""
        absorption = self.absorption_of(colour=colour, sigma_a=sigma_a, melanin=melanin, roughness=roughness)
        return self.sample(name, np.asarray(sin_theta)[..., None], np.asarray(roughness)[..., None], absorption)


def _dims(name: str) -> tuple[str, ...]:
    return COVER if name == "coverage" else GRID


def from_atlas(path) -> HairBSDFTables:
    """The tables of an EXR atlas (values only; float32 or half as stored)."""
    from ._atlas import read_atlas

    recipe, _, values = read_atlas(path)
    r = resolve_recipe(recipe, budget=False)
    return _tables(r, values, None, Path(path), None)


def _tables(r: dict, values: dict, errs: dict | None, path, attrs, sigma=None) -> HairBSDFTables:
    from ._recipe import grid_axes

    ax = grid_axes(r)
    names = [q for qs in QUANTITIES.values() for q in qs if q in values]
    dims = {q: _dims(q) for q in names}
    return HairBSDFTables(
        {q: values[q] for q in names},
        None if errs is None else {q: errs[q] for q in names},
        dims,
        {d: ax[d] for q in names for d in dims[q]},
        _spans(r),
        _units(r),
        sigma,
        r,
        path,
        attrs,
    )


def load(path) -> HairBSDFTables:
    """The ``hair_bsdf`` tables at ``path``: the validated HDF5 asset (a virtual one with its parts), or its EXR
    atlas (the values alone).  Raises a :mod:`hairlut.errors` exception naming the file and the fault."""
    if sniff(path) == "openexr":
        return from_atlas(path)
    check_virtual(path)
    t = read_table(path, kind=KIND)
    r = resolve_recipe(t.recipe, budget=False)
    want = [q for table, qs in QUANTITIES.items() if r[table]["bake"] for q in qs]
    missing = [n for q in want for n in (q, f"{q}_error") if n not in t.variables]
    if missing:
        raise errors.MissingDatasetError(path, f"the recipe's tables {missing} are missing")
    sigma = t["sigma_a"] if "sigma_a" in t.variables else None
    out = _tables(r, {q: t[q] for q in want}, {q: t[f"{q}_error"] for q in want}, Path(path), dict(t.attrs), sigma)
    for q in want:
        shape = tuple(len(out.axes[d]) for d in out.dims[q])
        if out.values[q].shape != shape or out.errors[q].shape != shape:
            raise errors.CorruptAssetError(path, f"table {q} is {out.values[q].shape}, its recipe's axes make {shape}")
    return out
