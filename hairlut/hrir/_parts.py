"""What a virtual ``hrir_db`` stores itself, from small per-part indexes (the shard path's ``Units.index``).

A virtual asset's per-sector tables are HDF5 virtual datasets over the parts; the asset itself
stores the feature index (satf §5.2: features of every sector and their normalisation), which
needs each sector's density grid and geometry.  :func:`part_index` reads those from one part (never
its α and reflectance, the bulk of it); each process of a bake indexes its own parts as it bakes or
resumes them, so the leader assembling the asset opens no part (:mod:`hairlut.sharding`), and
:func:`whole` joins the indexes in sector order.
"""

from __future__ import annotations

import numpy as np

from .. import errors
from ..assets import open_table
from ..assets.layout import layout
from ._io import _index, _read
from ._kind import SHARD_KIND
from ._march import GEOM

STORAGE = ("alpha", "reflectance")  # the tables whose storage error (float16 rounding) a part records


def part_index(recipe: dict, path, **_) -> dict[str, np.ndarray]:
    """(density, geometry, storage errors) of one part: what :func:`whole` needs of it."""
    with open_table(path, SHARD_KIND, required=("density",)) as f:
        tables = layout(f)[1]
        try:
            return {"density": _read(path, tables["density"]),
                    "geometry": np.stack([_read(path, tables[f"geometry/{c}"]) for c in GEOM], axis=1),
                    "errors": np.array([float(f.attrs[f"storage_max_abs_error_{k}"]) for k in STORAGE])}
        except KeyError as exc:
            raise errors.MissingDatasetError(path, f"shard lacks {exc}") from None


def whole(recipe: dict, parts, index=None, **_):
    """(axes, variables, attrs) of a virtual ``hrir_db`` over ``parts`` (in sector order), from their
    :func:`part_index` dicts ``index`` when given, else read from the parts."""
    small = list(index) if index is not None else [part_index(recipe, p) for p in parts]
    data = {"density": np.concatenate([d["density"] for d in small]),
            "geometry": np.concatenate([d["geometry"] for d in small]),
            "errors": {k: max(float(d["errors"][i]) for d in small) for i, k in enumerate(STORAGE)}}
    return _index(recipe, data, len(data["density"]))
