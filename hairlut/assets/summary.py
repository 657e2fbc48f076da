"""What ``hairlut inspect`` reports: a JSON-ready summary of a table or image file.

Statistics are computed block by block, so a table larger than memory can be
summarised; every block read also verifies the HDF5 fletcher32 checksums.  A virtual table (a split bake's) is
read one part at a time from its parts, as the table readers read it, so that a fault names the part.
"""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

from .. import errors
from ..files import regular_file
from .exr import EXR_MAGIC, read_exr
from .h5 import HDF5_SIGNATURE, data_fault, dims_of, layout, open_table, stored_recipe
from .layout import attr_text
from .virtual import virtual_blocks

_BLOCK_ELEMENTS = 1 << 22


class _Stats:
    """Running min / max / mean over finite values, and NaN / Inf counts."""

    def __init__(self):
        self.count = self.finite = self.nan = self.inf = 0
        self.total = 0.0
        self.lo, self.hi = np.inf, -np.inf

    def add(self, block: np.ndarray) -> None:
        block = np.asarray(block)
        self.count += block.size
        if block.dtype == np.bool_ or np.issubdtype(block.dtype, np.integer):
            block = block.astype(np.float64)
        nan = np.isnan(block)
        inf = np.isinf(block)
        finite = block[~(nan | inf)]
        self.nan += int(nan.sum())
        self.inf += int(inf.sum())
        if finite.size:
            self.finite += finite.size
            with np.errstate(over="ignore"):  # a sum of huge finite values may overflow: the mean is then inf
                self.total += float(finite.sum(dtype=np.float64))
            self.lo = min(self.lo, float(finite.min()))
            self.hi = max(self.hi, float(finite.max()))

    def as_dict(self) -> dict:
        have = self.finite > 0
        return {
            "min": self.lo if have else None,
            "max": self.hi if have else None,
            "mean": self.total / self.finite if have else None,
            "nan": self.nan,
            "inf": self.inf,
            "count": self.count,
        }


def array_stats(data: np.ndarray) -> dict:
    """The statistics ``hairlut inspect`` prints for one array: the element count, min, max and mean of the finite
    values, and the NaN and infinity counts."""
    s = _Stats()
    s.add(data)
    return s.as_dict()


def _dataset_stats(path: Path, ds: h5py.Dataset) -> dict:
    s = _Stats()
    parts = virtual_blocks(path, ds.file, ds) if ds.is_virtual else None
    if parts is not None:  # read from each part as the table readers do, so that a fault names the part
        for block in parts:
            s.add(block)
    elif ds.size:
        rows = max(1, _BLOCK_ELEMENTS // max(1, ds.size // max(1, ds.shape[0]))) if ds.ndim else 1
        try:
            if ds.ndim == 0:
                s.add(np.asarray(ds[()]))
            else:
                for start in range(0, ds.shape[0], rows):
                    s.add(ds[start : start + rows])
        except OSError as exc:
            raise data_fault(path, ds, exc) from None
    return s.as_dict()


def _attr(value):
    if isinstance(value, (bytes, str)):
        return attr_text(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def _summarize_h5(path: Path) -> dict:
    with open_table(path) as f:
        root = {k: _attr(v) for k, v in f.attrs.items()}
        recipe = stored_recipe(path, f)
        root.pop("recipe")
        out = {
            "path": str(path),
            "format": "hdf5",
            "kind": root.pop("kind"),
            "schema": root.pop("hairlut_schema"),
            "hairlut_version": root.pop("hairlut_version", None),
            "created": root.pop("created", None),
            "recipe_hash": root.pop("recipe_hash"),
            "recipe": recipe,
            "attrs": root,
            "datasets": [],
        }
        on_disk, tables = layout(f)
        axes = {}
        for name, ds in on_disk.items():
            axes[name] = {
                "units": attr_text(ds.attrs.get("units", "")),
                "long_name": attr_text(ds.attrs.get("long_name", name)),
                "periodic": bool(int(ds.attrs.get("periodic", 0))),
                "size": int(ds.shape[0]) if ds.ndim else 1,
                **{k: v for k, v in _dataset_stats(path, ds).items() if k in ("min", "max")},
            }
        out["axes"] = axes
        for name, obj in tables.items():
            out["datasets"].append(
                {
                    "name": name,
                    "h5_path": obj.name,
                    "shape": list(obj.shape),
                    "dtype": str(obj.dtype),
                    "dims": list(dims_of(obj)),
                    "units": attr_text(obj.attrs.get("units", "")),
                    "long_name": attr_text(obj.attrs.get("long_name", name)),
                    "chunks": list(obj.chunks) if obj.chunks else None,
                    "compression": obj.compression,
                    "fletcher32": bool(obj.fletcher32),
                    **_dataset_stats(path, obj),
                }
            )
    return out


def _summarize_exr(path: Path) -> dict:
    image = read_exr(path)
    parts = []
    for part in image.parts:
        header = {k: v for k, v in part.header.items() if not k.startswith("hairlut:")}
        channels = [
            {
                "name": name,
                "shape": list(arr.shape),
                "dtype": "half" if arr.dtype == np.float16 else str(arr.dtype),
                **array_stats(arr),
            }
            for name, arr in sorted(part.channels.items())
        ]
        parts.append({"name": part.name, "shape": list(part.shape), "header": header, "channels": channels})
    return {
        "path": str(path),
        "format": "openexr",
        "kind": image.kind,
        "schema": None,
        "hairlut_version": image.parts[0].header.get("hairlut:version"),
        "recipe_hash": image.recipe_hash,
        "recipe": image.recipe,
        "checksum": image.checksum,
        "attributes": dict(image.attributes),
        "parts": parts,
    }


def sniff(path: str | os.PathLike) -> str:
    """'hdf5' or 'openexr', from the file's signature (not its name)."""
    path = regular_file(path, "a table or image")
    with path.open("rb") as fh:
        head = fh.read(8)
    if head == HDF5_SIGNATURE:
        return "hdf5"
    if head[:4] == EXR_MAGIC:
        return "openexr"
    shown = "empty file" if not head else f"starts with {head!r}"
    raise errors.FormatError(path, f"neither HDF5 nor OpenEXR ({shown})")


def summarize(path: str | os.PathLike) -> dict:
    """Summary of an ``.h5`` table or ``.exr`` image: metadata, axes, per-dataset statistics."""
    path = Path(path)
    return _summarize_h5(path) if sniff(path) == "hdf5" else _summarize_exr(path)
