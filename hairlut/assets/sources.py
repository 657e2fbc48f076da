"""A virtual asset's sources: the part files of a sharded bake, checked before anything is read through them.

A virtual dataset may read only the asset's own parts (:func:`allowed_virtual_sources`: a regular file, no
symlink, directly in ``<asset>.parts/``, with the asset's recipe hash), never a part that the environment variable
``HDF5_VDS_PREFIX`` would redirect to another file (HDF5 looks for a relative source under that prefix before the
asset's folder).  Sources named printf-style (``part-<total>x<block>-%b.h5``, one mapping for every whole block)
are expanded to every block file HDF5 would open.  The sources are checked once per opened asset, whatever its
number of tables (:func:`check_sources`): each part is stamped (``lstat``) once and opened only when this process
has not checked it with that stamp, so reopening an unchanged many-part asset costs a ``stat`` per part.
``read_table`` then reads such an asset's tables from the parts these checks accepted, each part opened once
(:func:`hairlut.assets.virtual.read_virtual`), not through HDF5's virtual mappings.

A part fills one slot: the rows of the table's first axis that its mapping places it at.  Every part of every kind
declares the rows it holds (root attributes ``<axis>_start`` and ``<axis>_stop``, the axis the tables split
along), and a part whose declaration is not its slot is refused (:func:`slot_fault`): parts swapped or copied
under another block's name would otherwise be read silently as the other block's rows.
"""

from __future__ import annotations

import contextlib
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from .. import errors
from ..files import not_regular
from .trust import MAX_OBJECTS, PARTS_SUFFIX, VDS_PREFIX_ENV, _first_line, guard


def _part_folders(asset: Path) -> tuple[str]:
    return (os.path.join(os.path.realpath(asset.parent), asset.name + PARTS_SUFFIX),)


def file_stamp(path) -> tuple | None:
    """(device, inode, size, mtime ns, ctime ns, mode) of ``path``, a symlink not followed; None when nothing is there.
    A part replaced, rewritten or touched since it was checked has another stamp (see :func:`check_sources`)."""
    try:
        st = os.lstat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_mode)


@dataclass
class _Part:
    """What one look at a part file found: why it may not feed the asset (``fault``, None: it may), each dataset
    asked about: its shape when it is a plain dataset of the part (no link, not virtual, not external), else None;
    and the rows it declares it holds along each axis asked about (``ranges``: axis -> (start, stop), from its root
    attributes ``<axis>_start`` and ``<axis>_stop``; None when they are not integers)."""

    fault: str | None
    datasets: dict = field(default_factory=dict)
    ranges: dict = field(default_factory=dict)


#: Parts checked in this process, by (path, :func:`file_stamp`, recipe hash): a part whose stamp is unchanged is not
#: opened again, whichever asset or table asks (cleared when it holds more than ``_PARTS_MAX`` entries).
_PARTS: dict[tuple, _Part] = {}
_PARTS_MAX = 1 << 16


def _plain_shape(g: h5py.File, dset: str) -> tuple | None:
    """The shape of dataset ``dset`` of part ``g`` when its last link is a hard link and it is neither virtual nor
    external, else None (HDF5's low-level calls: a few per dataset, as every table of every part is asked about)."""
    name = dset.encode()
    try:
        if g.id.links.get_info(name).type != h5py.h5l.TYPE_HARD:
            return None
        obj = h5py.h5o.open(g.id, name)
    except KeyError:
        return None
    if not isinstance(obj, h5py.h5d.DatasetID):
        return None
    dcpl = obj.get_create_plist()
    if dcpl.get_layout() == h5py.h5d.VIRTUAL or dcpl.get_external_count():
        return None
    return obj.shape


@contextlib.contextmanager
def _root(path):
    """The root group of HDF5 file ``path``, opened read-only with HDF5's low-level calls (``h5py.File`` costs
    about 0.25 ms more to open and close, looking for its open objects)."""
    fid = h5py.h5f.open(os.fsencode(path), h5py.h5f.ACC_RDONLY)
    try:
        gid = h5py.h5g.open(fid, b"/")
        try:
            yield h5py.Group(gid)
        finally:
            gid.close()
    finally:
        fid.close()


def _look(candidate: Path, st: tuple | None, recipe_hash: str, dsets=(), axes=()) -> _Part:
    """The part file ``candidate`` (stamp ``st``) as a source of an asset of ``recipe_hash``, with datasets ``dsets``
    and the ranges it declares along ``axes``: from :data:`_PARTS` when that stamp was looked at before (and those
    datasets and axes with it), else opened once."""
    if st is None:
        return _Part("does not exist")
    if not_regular(st[5]):
        return _Part(f"is {not_regular(st[5])} (symlinks are not followed)")
    key = (str(candidate), st, recipe_hash)
    part = _PARTS.get(key)
    if part is not None and (
        part.fault is not None or (all(d in part.datasets for d in dsets) and all(a in part.ranges for a in axes))
    ):
        return part
    try:
        with open(candidate, "rb") as fh:
            if fh.read(8) != b"\x89HDF\r\n\x1a\n":
                part = _Part("is not HDF5")
        if part is None or part.fault is None:
            with guard(candidate), _root(candidate) as g:
                if part is None:
                    theirs = g.attrs.get("recipe_hash")
                    theirs = theirs.decode("utf-8") if isinstance(theirs, bytes) else theirs
                    part = _Part(None if theirs == recipe_hash else "carries another recipe hash")
                if part.fault is None:
                    part.datasets.update({d: _plain_shape(g, d) for d in dsets if d not in part.datasets})
                    part.ranges.update({a: _declared_range(g, a) for a in axes if a not in part.ranges})
    except errors.HairlutError as exc:
        part = _Part(str(exc))
    except OSError as exc:  # gone or unreadable since it was stamped
        return _Part(f"cannot be read ({_first_line(exc)})")
    if len(_PARTS) >= _PARTS_MAX:
        _PARTS.clear()
    _PARTS[key] = part
    return part


def _declared_range(g: h5py.Group, axis: str) -> tuple[int, int] | None:
    """(start, stop) of the root attributes ``<axis>_start`` and ``<axis>_stop`` of part ``g``; None unless both are
    integers.  (Two attribute reads, about 0.1 ms: each part is looked at once per stamp.)"""
    bounds = [np.asarray(g.attrs.get(f"{axis}_{end}")) for end in ("start", "stop")]
    if any(b.shape != () or b.dtype.kind not in "iu" for b in bounds):
        return None
    return int(bounds[0]), int(bounds[1])


def _slots(space, n: int) -> list:
    """Rows [lo, hi) of the first axis that each of the ``n`` source files of one mapping fills (its virtual
    selection ``space``: a printf mapping's block ``b`` is the ``b``-th box of its unlimited selection), None for a
    file whose rows are not one box."""
    kind = space.get_select_type()
    if kind == h5py.h5s.SEL_ALL:
        return [(0, int(space.shape[0]))] * n
    if kind != h5py.h5s.SEL_HYPERSLABS or not space.is_regular_hyperslab():
        return [None] * n
    start, stride, count, block = (int(x[0]) for x in space.get_regular_hyperslab())
    if count == h5py.h5s.UNLIMITED:
        return [(start + b * stride, start + b * stride + block) for b in range(n)]
    return [(start, start + block) if count == 1 else None] * n


def _row_axis(ds: h5py.Dataset) -> str:
    """The label of virtual table ``ds``'s first dimension: the axis its parts split and declare their rows on (a
    hairlut virtual table's first label is its first scale's name; one attribute read, where resolving the scales
    costs about 1 ms a table)."""
    labels = ds.attrs.get("DIMENSION_LABELS")
    first = labels[0] if labels is not None and len(labels) else b""
    return first.decode("utf-8", "replace") if isinstance(first, bytes) else str(first)


def slot_fault(asset: Path, name: str, src: Source, axis: str, rows) -> errors.CorruptAssetError | None:
    """The error naming part ``src`` and both ranges when the rows it declares along ``axis`` are not its slot
    ``rows`` (:func:`_slots`) in virtual table ``name`` of ``asset``; None when they are."""
    declared = src.ranges.get(axis)
    if rows is not None and declared == tuple(rows):
        return None
    said = (
        f"declares {axis} [{declared[0]}, {declared[1]})"
        if declared
        else (f"declares no {axis} range (integer root attributes {axis}_start and {axis}_stop)")
    )
    slot = f"to {axis} [{rows[0]}, {rows[1]})" if rows is not None else "to rows that are not one block"
    return errors.CorruptAssetError(
        src.path,
        f"part of {asset} {said}, but virtual dataset {name.lstrip('/')!r} maps "
        f"it {slot}; a part is read only into its own slot (renamed or swapped parts are "
        "refused: rebake, or put each part back under its own name)",
    )


def _folder_fault(asset: Path, candidate: Path) -> str | None:
    if os.path.islink(candidate.parent) or os.path.realpath(candidate.parent) not in _part_folders(asset):
        return "is not in the asset's parts folder"
    return None


def _part_fault(asset: Path, candidate: Path, recipe_hash: str) -> str | None:
    """Why ``candidate`` may not feed a virtual dataset of ``asset`` (None: it may)."""
    return _folder_fault(asset, candidate) or _look(candidate, file_stamp(candidate), recipe_hash).fault


def allowed_virtual_sources(path, recipe_hash: str) -> list[Path]:
    """The part files a virtual dataset in asset ``path`` may read.

    The one exception to "files never reach outside themselves", for sharded bakes
    that join their parts with an HDF5 virtual dataset (:mod:`hairlut.assets.parts`): a
    source is allowed when it is a regular file (not a symlink) directly inside the
    folder ``<asset name>.parts/`` beside the asset (itself not a symlink), is an HDF5
    file, and its root ``recipe_hash`` attribute equals the asset's (``recipe_hash``).
    The asset itself ("." in a virtual mapping) is always allowed.  Readers apply the
    same rule to each source a virtual dataset names, and refuse any other
    (:class:`~hairlut.errors.ForeignReferenceError`); they also refuse a source
    dataset that is itself virtual or external.
    """
    asset = Path(path)
    found = []
    for folder in map(Path, _part_folders(asset)):
        if not folder.is_dir() or folder.is_symlink():
            continue
        for candidate in sorted(folder.iterdir()):
            if candidate.suffix == ".h5" and _part_fault(asset, candidate, recipe_hash) is None:
                found.append(candidate)
    return found


def redirected_source(asset, where: str) -> Path | None:
    """The file HDF5 would open for virtual source ``where`` of ``asset`` under ``$HDF5_VDS_PREFIX``
    (None: the variable does not redirect it, and HDF5 reads the file beside the asset).

    HDF5 opens an absolute source name as given; a relative one it looks for first under each
    ``:``-separated entry of the variable (``${ORIGIN}`` standing for the asset's folder), then
    beside the asset, then in the working directory.  A prefix entry under which the name exists
    is taken as the file HDF5 opens."""
    prefix = os.environ.get(VDS_PREFIX_ENV, "")
    if not prefix or prefix == "." or os.path.isabs(where):
        return None
    origin = os.path.dirname(os.path.abspath(asset))
    for entry in prefix.split(":"):
        if entry.startswith("${ORIGIN}"):
            entry = origin + entry[len("${ORIGIN}") :]
        if entry and os.path.lexists(os.path.join(entry, where)):
            return Path(entry) / where
    return None


_PRINTF = re.compile(r"%(.)")


def printf_name(name: str, block: int | None = None) -> str:
    """A virtual source name as HDF5 reads it: ``%b`` is the block number (``block``), ``%%`` a literal ``%``
    (H5Pset_virtual's printf-style names; any other ``%`` sequence is kept as written)."""
    return _PRINTF.sub(lambda m: "%" if m.group(1) == "%" else str(block) if m.group(1) == "b" else m.group(0), name)


def is_printf(name: str) -> bool:
    """Whether a virtual source name holds ``%b``: one mapping for a run of blocks, one source file each."""
    return any(m.group(1) == "b" for m in _PRINTF.finditer(name))


def printf_escape(name: str) -> str:
    """``name`` with each ``%`` doubled, so that HDF5 reads it literally as a virtual source name."""
    return name.replace("%", "%%")


def printf_blocks(ds: h5py.Dataset, src) -> int:
    """How many blocks a printf-style mapping of ``ds`` (``%b`` in its names: :mod:`hairlut.assets.parts`) must read: the
    blocks of its unlimited regular selection that lie wholly before the next mapping on that axis, or before the
    end of the dataset's extent, which the writer pins with one fixed mapping for the last block so that a missing
    part cannot shrink it.  (HDF5 sets the extent of such a dataset from the blocks whose files it finds.)"""
    start, stride, count, block = src.vspace.get_regular_hyperslab()
    axis = ([i for i, c in enumerate(count) if c == h5py.h5s.UNLIMITED] or [0])[0]
    after = [
        int(other.vspace.get_select_bounds()[0][axis])
        for other in ds.virtual_sources()
        if not (is_printf(other.file_name) or is_printf(other.dset_name))
    ]
    after = [lo for lo in after if lo >= start[axis]]
    limit = min(after) if after else int(ds.shape[axis])  # the extent only without a fixed mapping after the blocks
    return max(0, (limit - int(start[axis]) - int(block[axis])) // int(stride[axis]) + 1)


def expand_sources(path: Path, ds: h5py.Dataset, src, memo: dict | None = None) -> list[tuple[str, str]]:
    """(file name, dataset name) of each source file one virtual mapping of ``ds`` in asset ``path`` reads.

    A printf-style mapping reads blocks 0 .. :func:`printf_blocks` − 1 (each must be there), and HDF5 also opens
    the files of the blocks after those while they exist (its default printf gap of 0), so those count too.
    ``memo``: the file names already found for a (name, blocks) pair, shared by the tables of one asset."""
    where, dset = src.file_name, src.dset_name
    if not (is_printf(where) or is_printf(dset)):
        return [(printf_name(where), printf_name(dset))]
    need = printf_blocks(ds, src)
    memo = {} if memo is None else memo
    if (where, need) not in memo:
        memo[(where, need)] = _block_files(path, where, need)
    files = memo[(where, need)]
    if not is_printf(dset):
        name = printf_name(dset)
        return [(w, name) for w in files]
    return [(w, printf_name(dset, block)) for block, w in enumerate(files)]


def _block_files(path: Path, where: str, need: int) -> list[str]:
    found = []
    for block in range(MAX_OBJECTS):
        name = printf_name(where, block)
        if block >= need and not os.path.lexists(name if os.path.isabs(name) else path.parent / name):
            return found
        found.append(name)
    raise errors.CorruptAssetError(path, f"virtual source {where!r} names more than {MAX_OBJECTS} files; not a hairlut table")


@dataclass
class Source:
    """One part file that virtual datasets of an asset read (see :func:`check_sources`)."""

    path: Path  # the file HDF5 opens (beside the asset)
    fault: str | None  # why the readers' rule refuses it (None: it may be read)
    redirect: Path | None  # another file that ``$HDF5_VDS_PREFIX`` makes HDF5 open instead, else None
    datasets: dict  # dataset name -> shape when a plain dataset of the part, else None
    stamp: tuple | None = None  # its :func:`file_stamp` when it was checked
    ranges: dict = field(default_factory=dict)  # axis -> (start, stop) the part declares it holds (see :class:`_Part`)


@dataclass
class Sources:
    """Every source of every virtual dataset of one open asset, each part file stamped and looked at once."""

    tables: dict = field(default_factory=dict)  # dataset name -> [(file name, dataset name, trailing shape, slot), ...]
    counts: dict = field(default_factory=dict)  # dataset name -> how many of those each mapping reads, in order
    faults: dict = field(default_factory=dict)  # dataset name -> the error its mappings raise when expanded
    files: dict = field(default_factory=dict)  # file name (as the mapping names it) -> Source
    slots: dict = field(default_factory=dict)  # dataset name -> the error of a part read outside its slot


#: The last checks of open assets, by (HDF5 id of the open file, asset, recipe hash): each table of an asset being
#: validated asks for its sources, and its parts are stamped once per opening (HDF5 does not reuse file ids).
_OPEN: dict[tuple, Sources] = {}
_OPEN_MAX = 16


def check_sources(path, f: h5py.File, recipe_hash: str) -> Sources:
    """The sources of every virtual dataset of asset ``path`` (open as ``f``), checked by the readers' rule
    (:func:`allowed_virtual_sources`), whatever the number of tables: each part file is stamped once
    (:func:`file_stamp`) and opened only if no earlier check in this process saw it with that stamp, then once for
    every dataset that the asset's tables read from it.  Nothing is raised here for a fault of one table's sources:
    :func:`check_dataset` and :func:`hairlut.assets.virtual_write.check_virtual` name it."""
    path = Path(path)
    key = (f.id.id, str(path), recipe_hash)
    if key in _OPEN:
        return _OPEN[key]
    found, axes = Sources(), {}
    virtual: list = []
    f.visititems(lambda n, o: virtual.append(o) if isinstance(o, h5py.Dataset) and o.is_virtual else None)
    expanded: dict = {}
    for ds in virtual:
        try:
            sources, counts, axis = [], [], _row_axis(ds)
            for vs in ds.virtual_sources():
                rest = tuple(vs.vspace.shape[1:])
                files = expand_sources(path, ds, vs, expanded)
                sources += [(where, dset, rest, rows) for (where, dset), rows in zip(files, _slots(vs.vspace, len(files)))]
                counts.append(len(files))
            found.tables[ds.name], found.counts[ds.name], axes[ds.name] = sources, counts, axis
        except errors.HairlutError as exc:
            found.faults[ds.name] = exc
    wanted: dict = {}  # file name -> (its datasets, the axes of the tables that read it)
    for name, sources in found.tables.items():
        for where, dset, _, _ in sources:
            if where != ".":
                dsets, on = wanted.setdefault(where, (set(), set()))
                dsets.add(dset)
                on.add(axes[name])
    folders: dict = {}
    for where, (dsets, on) in wanted.items():
        candidate = Path(where) if os.path.isabs(where) else path.parent / where
        if candidate.parent not in folders:
            folders[candidate.parent] = _folder_fault(path, candidate)
        fault, st = folders[candidate.parent], file_stamp(candidate)
        part = _Part(fault) if fault else _look(candidate, st, recipe_hash, dsets, on)
        found.files[where] = Source(candidate, part.fault, redirected_source(path, where), part.datasets, st, part.ranges)
    for name, sources in found.tables.items():
        for where, _, _, rows in sources:
            src = found.files.get(where)  # none for the asset itself (".")
            fault = slot_fault(path, name, src, axes[name], rows) if src is not None and src.fault is None else None
            if fault is not None:
                found.slots[name] = fault
                break
    if len(_OPEN) >= _OPEN_MAX:
        _OPEN.pop(next(iter(_OPEN)))
    _OPEN[key] = found
    return found


def check_virtual_dataset(path: Path, name: str, ds: h5py.Dataset, recipe_hash: str) -> None:
    """Refuse virtual dataset ``name`` unless every source is a plain dataset of the asset's own parts, beside it,
    read into its own slot (:func:`slot_fault`)."""
    with guard(path):
        found = check_sources(path, ds.file, recipe_hash)
    if ds.name in found.faults:
        raise found.faults[ds.name]
    for where, dset, _, _ in found.tables.get(ds.name, ()):
        if where == ".":
            continue
        src = found.files[where]
        if src.fault is not None:
            raise errors.ForeignReferenceError(
                path,
                f"dataset {name!r} is virtual with source {where}:{dset}, which {src.fault}; "
                "only the asset's own parts (<asset>.parts/, same recipe hash) may be sources",
            )
        if src.redirect is not None and os.path.realpath(src.redirect) != os.path.realpath(src.path):
            raise errors.ForeignReferenceError(
                path,
                f"dataset {name!r} is virtual with source {where}:{dset}, which "
                f"{VDS_PREFIX_ENV}={os.environ.get(VDS_PREFIX_ENV)!r} redirects to {src.redirect}; hairlut reads "
                f"a virtual asset's parts only from beside it: unset {VDS_PREFIX_ENV}",
            )
        if src.datasets.get(dset) is None:
            raise errors.ForeignReferenceError(
                path, f"dataset {name!r} is virtual with source {where}:{dset}, which is not a plain dataset of that part"
            )
    if ds.name in found.slots:
        raise found.slots[ds.name]
