"""What a virtual ``hrir_db`` stores itself, from small per-part indexes (the shard path's ``Units.index``).

A virtual asset's per-sector tables are HDF5 virtual datasets over the parts; the asset itself
stores the feature index (satf §5.2): every sector's features and their normalisation.  Each
process computes its own parts' features as it indexes them (:func:`part_index`), in the same
globally aligned chunks as the whole database's (``_io.FEATURE_CHUNK``), so they are bit for bit
the copied asset's; the leader assembling the asset opens no part and reads no density grid
(:mod:`hairlut.bake.sharding`): :func:`whole` joins the features in sector order and fits their
normalisation, work that grows with the sectors only by a few numbers each.  The projection
index (a PCA over every sector's projection profiles) still needs each part's density grid and
geometry, which its index then carries.
"""

from __future__ import annotations

import numpy as np

from .. import errors
from ..assets import open_table
from ..assets.layout import layout
from ..geometry.features import PROJECTION, feature_names, sector_features
from ..march import GEOM
from ._io import FEATURE_CHUNK, _index, _read, _row_areas
from ._kind import SHARD_KIND

STORAGE = ("alpha", "reflectance")  # the tables whose storage error (float16 rounding) a part records


def part_features(recipe: dict, density: np.ndarray, geometry: np.ndarray, start: int, total: int) -> np.ndarray:
    """Features of sectors [start, start + len(density)) of a ``total``-sector database, bit for bit as ``_io._index``
    computes them over all sectors: each chunk of the whole's (``min(FEATURE_CHUNK, …)`` sectors aligned at its
    multiples) is computed at its full shape, these sectors at their own rows, the rest zeros."""
    n_s, n_r = recipe["sectors"]["grid"]
    names = feature_names(recipe["sectors"]["features"])
    size = min(FEATURE_CHUNK, 1 << (max(int(total), 8) - 1).bit_length())  # sector_features' chunk for `total` sectors
    areas = _row_areas({"geometry": np.asarray(geometry)}, n_s, n_r)
    stop = start + len(density)
    out = []
    for c0 in range(start // size * size, stop, size):
        lo, hi = max(start, c0), min(stop, c0 + size)
        rho = np.zeros((size, n_s, n_r), np.asarray(density).dtype)
        area = np.ones((size, n_r))
        rho[lo - c0 : hi - c0] = density[lo - start : hi - start]
        area[lo - c0 : hi - c0] = areas[lo - start : hi - start]
        out.append(sector_features(rho, area, names, chunk=size)[lo - c0 : hi - c0])
    return np.concatenate(out) if out else np.zeros((0, len(names)))


def part_index(recipe: dict, path, **_) -> dict[str, np.ndarray]:
    """What :func:`whole` needs of one part: its sectors' features (density grids and geometry instead for the
    projection index) and its storage errors."""
    with open_table(path, SHARD_KIND, required=("density",)) as f:
        tables = layout(f)[1]
        try:
            density = _read(path, tables["density"])
            geometry = np.stack([_read(path, tables[f"geometry/{c}"]) for c in GEOM], axis=1)
            errs = np.array([float(f.attrs[f"storage_max_abs_error_{k}"]) for k in STORAGE])
            start, total = int(f.attrs["sector_start"]), int(f.attrs["sector_total"])
        except KeyError as exc:
            raise errors.MissingDatasetError(path, f"shard lacks {exc}") from None
    if feature_names(recipe["sectors"]["features"]) == PROJECTION:
        return {"density": density, "geometry": geometry, "errors": errs}
    return {"features": part_features(recipe, density, geometry, start, total), "errors": errs}


def whole(recipe: dict, parts, index=None, **_):
    """(axes, variables, attrs) of a virtual ``hrir_db`` over ``parts`` (in sector order), from their
    :func:`part_index` dicts ``index`` when given, else read from the parts."""
    small = list(index) if index is not None else [part_index(recipe, p) for p in parts]
    errs = {k: max(float(d["errors"][i]) for d in small) for i, k in enumerate(STORAGE)}
    if feature_names(recipe["sectors"]["features"]) != PROJECTION:
        sizes = [len(d["features"] if "features" in d else d["density"]) for d in small]
        starts, total = np.cumsum([0, *sizes[:-1]]), sum(sizes)
        feats = np.concatenate(
            [
                d["features"]
                if "features" in d
                # an index of density grids (an older share file)
                else part_features(recipe, d["density"], d["geometry"], int(s), total)
                for d, s in zip(small, starts)
            ]
        )
        return _index(recipe, {"features": feats, "errors": errs}, total)
    data = {
        "density": np.concatenate([d["density"] for d in small]),
        "geometry": np.concatenate([d["geometry"] for d in small]),
        "errors": errs,
    }
    return _index(recipe, data, len(data["density"]))


def check(recipe: dict, path) -> None:
    """Refuse a part that lacks a table or attribute a part must hold (a part of an older format is baked again)."""
    from ._io import read_shard

    read_shard(path)


def budget(recipe: dict, block: int, held: int, note: str = "") -> None:
    """Refuse a bake whose process would trace ``block`` sectors at a time and hold ``held`` sectors' tables beyond
    the memory budget (:func:`hairlut.budget.check_hrir`)."""
    from ..budget import check_hrir

    check_hrir(recipe, block=block, held=held, note=note)
