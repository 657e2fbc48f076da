"""Virtual tables read from their parts: each part file opened once, not through HDF5's virtual mappings.

A sharded bake's asset (:mod:`hairlut.assets.virtual_write`) keeps its tables as HDF5 virtual datasets whose row blocks live in
the part files of ``<asset>.parts/``.  HDF5 reading such a table looks for every block file again, for each table
and each read (its printf expansion); :func:`read_virtual` instead plans each table's row blocks (:func:`_plan`)
from the parts that :func:`~.sources.check_sources` accepted and reads every table's block of a part while that
part is open once (:func:`_read_part`).  ``read_table`` (:mod:`.h5`) calls it for every asset it reads; a table of
another layout is left to HDF5.  The speed it buys on a many-part asset is measured in benchmarks/records.md (the scaling
record: ``load_hrir_db`` of a 1,024-part asset, 1.9x less CPU time than through HDF5's mappings).
"""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

from .. import errors
from .layout import attr_text
from .sources import check_sources, file_stamp, printf_blocks
from .trust import data_fault, guard, table_shape


def _box(space) -> tuple[tuple, tuple] | None:
    """(start, count) of the one hyperslab block a dataspace selects, else None."""
    if space.get_select_type() == h5py.h5s.SEL_HYPERSLABS and space.is_regular_hyperslab():
        start, _, count, block = space.get_regular_hyperslab()
        if all(c == 1 for c in count):
            return tuple(start), tuple(block)
    return None


def _plan(ds: h5py.Dataset, found) -> list | None:
    """(part path, its stamp when checked, source dataset, first row, rows) for each block of virtual table ``ds``, the
    rows in order and covering [0, n) once, every source a part that :func:`~.sources.check_sources` accepted
    (``found``) with a plain dataset of exactly the block's shape; None for any other layout (HDF5 then reads it).

    hairlut's virtual tables (:func:`hairlut.assets.virtual_write._mappings`) are one printf mapping whose block ``b`` copies the
    whole source dataset of part ``b`` to rows ``[b·block, (b+1)·block)`` and one fixed mapping of the last part."""
    if ds.name in found.slots:  # a part read into another's slot: refused on every path, not left to HDF5
        raise found.slots[ds.name]
    shape = table_shape(ds)
    if not shape or ds.name in found.faults or ds.name not in found.tables:
        return None
    rest, sources, plan = tuple(shape[1:]), iter(found.tables[ds.name]), []
    for vs, n in zip(ds.virtual_sources(), found.counts[ds.name]):
        space = vs.vspace
        if space.get_select_type() != h5py.h5s.SEL_HYPERSLABS or not space.is_regular_hyperslab():
            return None
        start, stride, count, block = space.get_regular_hyperslab()
        if tuple(start[1:]) != (0,) * len(rest) or tuple(block[1:]) != rest or any(c != 1 for c in count[1:]):
            return None
        if n != (printf_blocks(ds, vs) if count[0] == h5py.h5s.UNLIMITED else 1) or count[0] not in (1, h5py.h5s.UNLIMITED):
            return None  # block files beyond the pattern's (HDF5 reads them too), or several boxes
        whole = (int(block[0]), *rest)  # each source dataset: all of it, this shape
        if vs.src_space.get_select_type() != h5py.h5s.SEL_ALL and _box(vs.src_space) != ((0,) * len(shape), whole):
            return None
        for b in range(n):
            where, dset, _, _ = next(sources)
            src = found.files.get(where)
            if (
                where == "."
                or src is None
                or src.fault is not None
                or src.redirect is not None
                or src.datasets.get(dset) != whole
            ):
                return None
            plan.append((src.path, src.stamp, dset, int(start[0]) + b * int(stride[0]), whole[0]))
    plan.sort(key=lambda p: p[3])
    ends = [0] + [r0 + n for *_, r0, n in plan]
    if [p[3] for p in plan] != ends[:-1] or ends[-1] != shape[0]:
        return None  # gaps or overlaps: HDF5's fill value and precedence rules apply
    return plan


def read_virtual(path: Path, f: h5py.File, tables: dict) -> dict:
    """The virtual tables of ``tables`` (name -> dataset of asset ``f``) that are plain row blocks of the asset's
    parts (:func:`_plan`), read from the parts themselves: each part opened once, every table's block read into
    its rows of one preallocated array, the part closed.  HDF5 reading the same tables through their virtual
    mappings looks for every block file again for each table and each read (its printf expansion): about
    0.3 ms per part per table.  Only parts that :func:`~.sources.check_sources` accepted are opened (the tables
    were validated with them, :func:`~.trust.check_dataset`); the part datasets' filters verify their fletcher32
    checksums as they are read, a fault naming the part (:func:`~.trust.data_fault`); the bytes are those HDF5 gives
    (the same type conversion, into an array of the virtual table's dtype).  A table of another layout is left
    out, for HDF5 to read."""
    virtual = {name: ds for name, ds in tables.items() if ds.is_virtual}
    if not virtual:
        return {}
    with guard(path):
        found = check_sources(path, f, attr_text(f.attrs["recipe_hash"]))
        plans = {name: _plan(ds, found) for name, ds in virtual.items()}
    out, by_part = {}, {}
    for name, plan in plans.items():
        if plan is None:
            continue
        ds = virtual[name]
        out[name] = np.empty(table_shape(ds), dtype=ds.dtype)
        for part, st, dset, row, rows in plan:
            by_part.setdefault((part, st), []).append((out[name], dset, row, rows))
    for (part, st), reads in by_part.items():
        _read_part(path, part, st, reads)
    return out


def virtual_blocks(path: Path, f: h5py.File, ds: h5py.Dataset):
    """The rows of virtual table ``ds`` of asset ``f``, one part's block at a time and in order, each read from its
    part as :func:`read_virtual` reads it (a checksum or other fault names the part, not the asset); None for a
    table that is not plain row blocks of its parts (:func:`_plan`), which HDF5 then reads.  For readers that
    hold one block at a time (``summarize``, behind ``hairlut inspect``)."""
    with guard(path):
        plan = _plan(ds, check_sources(path, f, attr_text(f.attrs["recipe_hash"])))
    if plan is None:
        return None

    rest = table_shape(ds)[1:]

    def blocks():
        for part, st, dset, _, rows in plan:
            block = np.empty((rows, *rest), dtype=ds.dtype)
            _read_part(path, part, st, [(block, dset, 0, rows)])
            yield block

    return blocks()


def _read_part(path: Path, part: Path, checked: tuple, reads: list) -> None:
    """Read each (array, dataset, first row, rows) of ``reads`` from part file ``part`` into the array's rows
    (HDF5's low-level calls: one file open, then one dataset open and read per table), unless the part is gone or
    its :func:`~.sources.file_stamp` is no longer ``checked``, the one its check saw."""
    now = file_stamp(part)
    if now is None:
        raise errors.AssetNotFoundError(part, f"part of {path} is missing")
    if now != checked:
        raise errors.CorruptAssetError(part, f"part of {path} changed since it was checked; open the asset again")
    try:
        fid = h5py.h5f.open(os.fsencode(part), h5py.h5f.ACC_RDONLY)
    except OSError as exc:  # gone or changed since it was stamped
        raise errors.CorruptAssetError(part, f"part of {path} cannot be opened ({str(exc).splitlines()[0]})") from None
    try:
        with guard(part):
            for arr, dset, row, rows in reads:
                did = h5py.h5d.open(fid, dset.encode())
                try:  # rows [row, row + rows) of a C-ordered array: contiguous, the part dataset's shape
                    did.read(h5py.h5s.ALL, h5py.h5s.ALL, arr[row : row + rows])
                except OSError as exc:
                    raise data_fault(part, h5py.Dataset(did), exc) from None
                finally:
                    did.close()
    finally:
        fid.close()
