"""The virtual asset of a split bake: its per-unit tables as HDF5 virtual datasets over the parts folder.

A *virtual* asset (:func:`write_virtual`) stores its per-unit tables as HDF5 virtual
datasets over the part files, which stay beside it: nothing is copied.  Each table is two
mappings whatever the part count: one printf-style mapping (source file ``…-%b.h5``, an
unlimited regular selection of stride ``block``) over the equal blocks, and one fixed mapping
for the last block (shorter or not), which also pins the table's extent.  HDF5 fills a
missing source with the fill value silently, so :func:`check_virtual` validates every
source before a reader trusts the file, by the readers' own rule
(:func:`hairlut.assets.sources.allowed_virtual_sources`: a part inside ``<asset>.parts/``,
no symlink, that exists and carries the asset's recipe hash), and names the fault.

The parts folder itself (its files, names, locks and share indexes) is :mod:`hairlut.assets.parts`'s; reading such an
asset's tables from its parts directly is :mod:`hairlut.assets.virtual`'s.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from pathlib import Path

import h5py
import numpy as np

from .. import errors
from .._version import __version__
from ..files import not_regular, regular_file
from . import Axis, Variable, atomic_path, canonical_json, open_table, recipe_hash
from .h5 import LIBVER, dims_of, disk_name
from .kinds import SCHEMA
from .layout import attr_text, layout
from .parts import part_name, part_pattern, parts_dir
from .sources import check_sources, printf_escape

ATTR = "hairlut_parts"  # root attribute of a virtual asset: its parts (JSON: folder, block, total, part count)
_SKIP_ATTRS = {"DIMENSION_LIST", "DIMENSION_LABELS", "REFERENCE_LIST", "CLASS", "NAME"}


def _created(first_part: Path) -> str:
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    if epoch:
        return _dt.datetime.fromtimestamp(int(epoch), _dt.UTC).replace(microsecond=0).isoformat()
    with h5py.File(first_part, "r") as f:
        return attr_text(f.attrs.get("created", ""))


def _kwargs(chunks) -> dict:
    return dict(
        chunks=chunks if chunks is not None else True,
        compression="gzip",
        compression_opts=4,
        shuffle=True,
        fletcher32=True,
        track_times=False,
    )


def write_virtual(
    out,
    kind: str,
    recipe: dict,
    axis: str,
    parts: list[tuple[Path, int, int]],
    axes: list[Axis],
    variables: list[Variable],
    attrs: dict | None = None,
) -> Path:
    """Write ``out`` (atomically): ``variables`` stored, every table of the parts whose first axis is ``axis``
    a virtual dataset over the parts.  ``parts`` are (path, start, stop) covering the axis in order, in equal
    blocks but the last, in one folder, named by :func:`part_name`; each table is two mappings (see the module)."""
    out = Path(out)
    text = recipe_hash(canonical_json(recipe))
    total, block = parts[-1][2], parts[0][2] - parts[0][1]
    folder = parts[0][0].parent
    for path, start, stop in parts:
        if Path(path) != folder / part_name(start, stop, total, block):
            raise errors.ValidationError(
                "parts",
                str(path),
                f"a virtual asset maps the blocks of {block} {axis} named {part_pattern(total, block)} in one folder, in order",
            )
    with open_table(parts[0][0]) as f:
        on_disk, tables = layout(f)
        per_unit = {
            name: (
                ds.name.lstrip("/"),
                ds.shape[1:],
                ds.dtype,
                dims_of(ds),
                {k: v for k, v in ds.attrs.items() if k not in _SKIP_ATTRS},
            )
            for name, ds in tables.items()
            if dims_of(ds)[:1] == (axis,)
        }
    by_name = {a.name: a for a in axes}
    if len(by_name[axis].values) != total:
        raise errors.ValidationError(axis, len(by_name[axis].values), f"the parts cover {total} units")
    rel = os.path.relpath(folder, out.parent)
    described = {"folder": rel, "block": block, "total": total, "parts": len(parts)}
    with atomic_path(out) as tmp:
        with h5py.File(tmp, "w", libver=LIBVER, track_order=True) as f:
            for key, value in {
                "hairlut_schema": np.int32(SCHEMA),
                "kind": kind,
                "hairlut_version": __version__,
                "created": _created(parts[0][0]),
                "recipe": canonical_json(recipe),
                "recipe_hash": text,
                **(attrs or {}),
                ATTR: json.dumps(described),
            }.items():
                f.attrs[key] = value
            scales = {}
            for ax in axes:
                ds = f.create_dataset(ax.name, data=np.asarray(ax.values), **_kwargs(None))
                ds.attrs.update({"units": ax.units, "long_name": ax.long_name, "periodic": np.int8(ax.periodic)})
                if ax.periodic:
                    ds.attrs["period"] = float(ax.period)
                ds.make_scale(ax.name)
                scales[ax.name] = ds

            def place(name, make):
                where = disk_name(name, by_name)
                bits = where.split("/")
                for depth in range(1, len(bits)):
                    group = "/".join(bits[:depth])
                    if group not in f:
                        f.create_group(group, track_order=True)
                if where != name:
                    f[bits[0]].attrs["hairlut_name"] = name.split("/")[0]
                return make(where)

            for var in variables:
                data = np.asarray(var.data)
                ds = place(var.name, lambda w, data=data, var=var: f.create_dataset(w, data=data, **_kwargs(var.chunks)))
                ds.attrs.update({"units": var.units, "long_name": var.long_name, **var.attrs})
                for i, dim in enumerate(var.dims):
                    ds.dims[i].label = dim
                    ds.dims[i].attach_scale(scales[dim])
            names = [
                os.fsencode(os.path.join(printf_escape(rel), n))
                for n in (part_pattern(total, block), printf_escape(parts[-1][0].name))
            ]
            for name, (src, rest, dtype, dims, extra) in per_unit.items():
                dcpl = _mappings(total, block, rest, src, names, np.nan if np.issubdtype(dtype, np.floating) else 0)
                space = h5py.h5s.create_simple((total, *rest))
                tid = h5py.h5t.py_create(np.dtype(dtype), logical=1)
                ds = place(
                    name,
                    lambda w, dcpl=dcpl, space=space, tid=tid: (
                        f[w] if h5py.h5d.create(f.id, name=w.encode(), tid=tid, space=space, dcpl=dcpl) else None
                    ),
                )
                ds.attrs.update(extra)
                _attach_scales(ds, dims, scales)
    return out


def _attach_scales(ds: h5py.Dataset, dims: tuple, scales: dict) -> None:
    """Label ``ds``'s dimensions and attach their scales, writing the attributes HDF5's H5DS calls write
    (``DIMENSION_LABELS``, ``DIMENSION_LIST``, and each scale's ``REFERENCE_LIST``) itself: those calls read the
    dataset's extent, which for a printf-style mapping makes HDF5 open every part, and in the asset's write mode
    it opens them for writing (each part's modification time would change, and with it its stamp)."""
    ds.attrs.create("DIMENSION_LABELS", np.array(list(dims), dtype=object), dtype=h5py.string_dtype("ascii"))
    refs = np.empty(len(dims), dtype=object)
    for i, dim in enumerate(dims):
        refs[i] = np.array([scales[dim].ref], dtype=h5py.ref_dtype)
    ds.attrs.create("DIMENSION_LIST", refs, dtype=h5py.vlen_dtype(h5py.ref_dtype))
    row = np.dtype([("dataset", h5py.ref_dtype), ("dimension", "<i4")])
    for i, dim in enumerate(dims):
        scale = scales[dim]
        old = scale.attrs["REFERENCE_LIST"] if "REFERENCE_LIST" in scale.attrs else np.zeros(0, row)
        new = np.zeros(len(old) + 1, row)
        new[: len(old)] = old
        new[-1] = (ds.ref, i)
        if "REFERENCE_LIST" in scale.attrs:
            del scale.attrs["REFERENCE_LIST"]
        scale.attrs.create("REFERENCE_LIST", new, dtype=row)


def _mappings(total: int, block: int, rest: tuple, src: str, names: list[bytes], fill):
    """The dataset creation property list of one virtual table over the parts (the module's two mappings).

    ``names``: the whole blocks' printf-style source name and the last block's.  Blocks 0 .. n − 2 are one
    ``H5Pset_virtual`` call: an unlimited regular hyperslab of stride ``block`` mapped to ``src`` of the file named
    with ``%b`` replaced by the block number (HDF5 finds the block files when the table is opened); the last block,
    whose length may differ, is a fixed mapping.  So the cost does not grow with the part count."""
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_layout(h5py.h5d.VIRTUAL)
    dcpl.set_fill_value(np.array([fill]))
    zeros, ones = (0,) * len(rest), (1,) * len(rest)
    dset = printf_escape(src).encode()
    whole = (total - 1) // block  # the blocks before the last
    if whole:
        vspace = h5py.h5s.create_simple((total, *rest))
        vspace.select_hyperslab((0, *zeros), (h5py.h5s.UNLIMITED, *ones), stride=(block, *ones), block=(block, *rest))
        dcpl.set_virtual(vspace, names[0], dset, h5py.h5s.create_simple((block, *rest)))
    last = total - whole * block
    vspace = h5py.h5s.create_simple((total, *rest))
    vspace.select_hyperslab((whole * block, *zeros), (last, *rest))
    dcpl.set_virtual(vspace, names[1], dset, h5py.h5s.create_simple((last, *rest)))
    return dcpl


def is_virtual(path) -> bool:
    """Whether a table file stores any table as a virtual dataset."""
    found = []
    with h5py.File(regular_file(path, "an HDF5 file"), "r") as f:
        f.visititems(lambda n, o: found.append(n) if isinstance(o, h5py.Dataset) and o.is_virtual else None)
    return bool(found)


def check_virtual(path) -> list[Path]:
    """Validate the sources of every virtual dataset of a table file; returns the part files (none: not virtual).

    Whether a source may be read is decided in one place, the readers' own rule
    (:func:`hairlut.assets.sources.allowed_virtual_sources`: a regular file, no symlink, directly in
    ``<asset>.parts/``, HDF5, the asset's recipe hash), applied by :func:`hairlut.assets.sources.check_sources`:
    each part is stamped once per call and opened only when this process has not seen it with that stamp
    (then once for all the tables), so a reopened asset costs a ``stat`` per part.  This names what is wrong
    with a refused one: AssetNotFoundError for a missing part, CorruptAssetError for a source outside the parts
    folder, a symlink, a FIFO or other file that is not regular, a part of another recipe, a part lacking its dataset,
    or a part whose declared range is not the slot the asset maps it to (:func:`hairlut.assets.sources.slot_fault`)."""
    path = regular_file(path, "an HDF5 file")  # a FIFO would block h5py's open
    try:
        with h5py.File(path, "r") as f:
            digest = attr_text(f.attrs.get("recipe_hash", ""))
            found = check_sources(path, f, digest)
    except (OSError, KeyError, RuntimeError, ValueError):
        return []  # not readable as HDF5: the table reader names that fault
    for exc in found.faults.values():
        raise exc
    by_part: dict[Path, list] = {}
    for name, sources in found.tables.items():
        for file_name, dset, shape, _ in sources:
            if file_name == ".":
                continue
            src = found.files[file_name]
            if src.fault is not None:
                raise _refused(path, name.lstrip("/"), file_name, src.path, digest)
            by_part.setdefault(src.path, []).append((dset, shape))
    parts = _lacking(path, found, by_part)
    for exc in found.slots.values():
        raise exc
    return parts


def _lacking(path: Path, found, by_part: dict) -> list[Path]:
    """The parts of ``by_part``, sorted, after checking that each holds the datasets (with their trailing shapes)
    its tables read."""
    shapes = {src.path: src.datasets for src in found.files.values()}
    for part, wanted in by_part.items():
        for dset, shape in wanted:
            got = shapes[part].get(dset)
            if got is None or tuple(got[1:]) != shape:
                raise errors.CorruptAssetError(
                    part, f"part of {path} lacks dataset {dset!r} of shape (n, {', '.join(map(str, shape))})"
                )
    return sorted(by_part)


def _refused(path: Path, name: str, file_name: str, part: Path, digest: str) -> errors.AssetError:
    """The error that names why ``part`` is not one of ``path``'s parts (the rule refused it)."""
    folder = parts_dir(path)
    if (
        os.path.isabs(file_name)
        or ".." in Path(file_name).parts
        or part.parent.is_symlink()
        or os.path.realpath(part.parent) != os.path.realpath(folder)
    ):
        return errors.CorruptAssetError(path, f"virtual dataset {name!r} points outside the asset's parts folder ({file_name!r})")
    if part.is_symlink():
        return errors.CorruptAssetError(part, f"part of {path} is a symlink; parts are regular files")
    if not part.exists():
        return errors.AssetNotFoundError(part, f"part of {path} is missing (rebake, or copy the parts folder with the asset)")
    if (what := not_regular(part.stat().st_mode)) is not None:  # a FIFO would block the open below
        return errors.CorruptAssetError(part, f"part of {path} is {what}; parts are regular files")
    try:
        with h5py.File(part, "r") as pf:
            got = attr_text(pf.attrs.get("recipe_hash", ""))
    except (OSError, KeyError, RuntimeError, ValueError):
        return errors.CorruptAssetError(part, f"part of {path} is not a readable HDF5 file")
    if got != digest:
        return errors.CorruptAssetError(
            part, f"part of {path} was baked from another recipe (recipe hash {got[:16] or 'none'}, the asset's is {digest[:16]})"
        )
    return errors.CorruptAssetError(part, f"part of {path} is not a regular HDF5 file of its parts folder")
