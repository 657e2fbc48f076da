"""The EXR atlas of the ``hair_bsdf`` tables: what an engine samples, the layout in the header.

One part per table (``dual_scattering``, ``mean_energy``, ``coverage``), one channel per quantity
(``dual_scattering.A_f``, …, ``mean_energy.TRT``, ``coverage.Y``), float32 (or half).  A 3-D table of
n_x sin θ × n_y roughness × n_z absorption nodes is stored as its n_z absorption slices, each an n_x × n_y
tile (x: sin θ, left to right; y: roughness, top to bottom: the first scanline is roughness node 0, where
Direct3D, Vulkan and Metal put v = 0), tiled row-major: slice k at tile column k mod C and row k div C,
C = ⌈√n_z⌉ columns; tiles past the last slice are zero.  The 2-D coverage table is one tile (x: radius in
pixels, y: strand count).

A shader samples the atlas trilinearly as two bilinear taps in the neighbouring slices, each with its texture
coordinate clamped to the tile's texel centres [½, n − ½] (so no tap reads the next tile), blended by the
slice coordinate: the interpolation of :meth:`hairlut.hairbsdf.HairBSDFTables.sample`.

The header attribute ``hairlut:atlas`` (JSON) says all of this per table: its part, channels, tile size,
tile columns and rows, and each axis's name, span, node count and units, so that a reader rebuilds the 3-D
tables from the pixels alone (:func:`read_atlas`; ``hairlut inspect`` shows it).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .. import errors
from ..assets import ExrPart, read_exr, write_exr
from ._recipe import QUANTITIES

ATTRIBUTE = "hairlut:atlas"
ATLAS_KIND = "hair_bsdf_atlas"
LAYOUT_VERSION = 1


def tiling(slices: int) -> tuple[int, int]:
    """(columns, rows) of the tiles of ``slices`` slices: ⌈√n⌉ columns, as many rows as needed."""
    cols = math.ceil(math.sqrt(slices))
    return cols, math.ceil(slices / cols)


def tile(values: np.ndarray) -> np.ndarray:
    """A (n_x, n_y, n_z) table as its atlas image (rows · n_y, cols · n_x): slice k at tile (k mod C, k div C)."""
    n_x, n_y, n_z = values.shape
    cols, rows = tiling(n_z)
    image = np.zeros((rows * n_y, cols * n_x), values.dtype)
    for k in range(n_z):
        r, c = divmod(k, cols)
        image[r * n_y : (r + 1) * n_y, c * n_x : (c + 1) * n_x] = values[:, :, k].T
    return image


def untile(image: np.ndarray, n_x: int, n_y: int, n_z: int) -> np.ndarray:
    """The inverse of :func:`tile`: the (n_x, n_y, n_z) table of an atlas image."""
    cols, rows = tiling(n_z)
    if image.shape != (rows * n_y, cols * n_x):
        raise ValueError(f"an atlas of {n_z} slices of {n_x} × {n_y} is {cols * n_x} × {rows * n_y}, not {image.shape[::-1]}")
    out = np.empty((n_x, n_y, n_z), image.dtype)
    for k in range(n_z):
        r, c = divmod(k, cols)
        out[:, :, k] = image[r * n_y : (r + 1) * n_y, c * n_x : (c + 1) * n_x].T
    return out


def _axis(tables, name: str) -> dict:
    lo, hi = tables.spans[name]
    return {"name": name, "span": [lo, hi], "count": int(len(tables.axes[name])), "units": tables.units[name]}


def layout(tables) -> dict:
    """The ``hairlut:atlas`` layout of a :class:`hairlut.hairbsdf.HairBSDFTables`' tables (module docstring)."""
    out = {}
    for table, names in QUANTITIES.items():
        if names[0] not in tables.values:
            continue
        dims = tables.dims[names[0]]
        shape = [int(s) for s in tables.values[names[0]].shape]
        slices = shape[2] if len(shape) == 3 else 1
        cols, rows = tiling(slices)
        out[table] = {
            "part": table,
            "channels": {q: f"{table}.{'Y' if table == 'coverage' else q}" for q in names},
            "tile": shape[:2],
            "tiles": [cols, rows],
            "x": _axis(tables, dims[0]),
            "y": _axis(tables, dims[1]),
            **({"slice": _axis(tables, dims[2])} if len(dims) == 3 else {}),
            "texel": "node i of an axis of n nodes over [lo, hi] is at lo + (hi - lo)(i + 0.5)/n: texture coordinate "
            "(i + 0.5)/n of u = (x - lo)/(hi - lo)",
            "order": "slice k at tile column k mod tiles[0], row k div tiles[0]; x left to right, y top to bottom "
            "(first scanline: y node 0); bilinear within a tile, clamped to its texel centres, linear across slices",
        }
    return {"version": LAYOUT_VERSION, "kind": "hair_bsdf", "tables": out}


def write_atlas(path, tables, pixel_type: str | None = None) -> Path:
    """Write the EXR atlas of a :class:`hairlut.hairbsdf.HairBSDFTables` (module docstring) at ``path``, atomically;
    ``pixel_type`` ``"half"`` stores half floats (float32 otherwise)."""
    lay = layout(tables)
    parts = []
    for table, spec in lay["tables"].items():
        channels = {}
        for q, channel in spec["channels"].items():
            v = np.asarray(tables.values[q], np.float32)
            channels[channel] = tile(v if v.ndim == 3 else v[:, :, None])
        parts.append(ExrPart(table, channels))
    if not parts:
        raise errors.ValidationError("atlas", str(path), "the tables hold nothing to write")
    return write_exr(
        path,
        parts,
        recipe=tables.recipe,
        kind=ATLAS_KIND,
        pixel_type=pixel_type,
        attributes={ATTRIBUTE: json.dumps(lay, sort_keys=True)},
    )


def read_atlas(path) -> tuple[dict, dict, dict[str, np.ndarray]]:
    """(recipe, layout, {quantity: table}) of an EXR atlas, the tables rebuilt from the pixels by the layout in
    its header (float32 or half, as stored)."""
    image = read_exr(path, kind=ATLAS_KIND)
    text = image.attributes.get(ATTRIBUTE)
    if text is None or image.recipe is None:
        raise errors.MissingDatasetError(path, f"no {ATTRIBUTE} layout or recipe in the header")
    try:
        lay = json.loads(text)
        values = {}
        for spec in lay["tables"].values():
            part = image.part(spec["part"])
            n_x, n_y = spec["tile"]
            n_z = spec["slice"]["count"] if "slice" in spec else 1
            for q, channel in spec["channels"].items():
                v = untile(part.channels[channel], n_x, n_y, n_z)
                values[q] = v if "slice" in spec else v[:, :, 0]
    except (KeyError, TypeError, ValueError) as exc:
        raise errors.CorruptAssetError(path, f"the atlas does not match its {ATTRIBUTE} layout ({exc})") from None
    return image.recipe, lay, values
