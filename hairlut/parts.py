"""The parts folder of a bake and the virtual assets built over it (every table kind).

``<out>.parts/`` holds a bake's finished blocks, one file each (the kind's shard kind),
named by the bake's unit count, its block size and the block's number (:func:`part_name`):
``part-<total>x<block>-<b>.h5``, and ``part-<total>x<block>-<b>-last.h5`` for the last block.  hairlut creates the folder atomically with a marker file
(:data:`MARKER`) inside, and refuses a folder without it, or a symlink, rather than touch
what it did not create; it deletes only the part files, temporaries and marker it wrote.
Bakes of one output take turns on an advisory lock (``fcntl.flock`` on
``<out>.parts.lock``, opened without following symlinks, removed by its holder on release:
:func:`lock_file`; ``hairlut cache prune`` removes the ones killed processes left,
:func:`remove_if_unused`).

A *virtual* asset (:func:`write_virtual`) stores its per-unit tables as HDF5 virtual
datasets over the part files, which stay beside it: nothing is copied.  Each table is two
mappings whatever the part count: one printf-style mapping (source file ``…-%b.h5``, an
unlimited regular selection of stride ``block``) over the equal blocks, and one fixed mapping
for the last block (shorter or not), which also pins the table's extent.  HDF5 fills a
missing source with the fill value silently, so :func:`check_virtual` validates every
source before a reader trusts the file, by the readers' own rule
(:func:`hairlut.assets.sources.allowed_virtual_sources`: a part inside ``<asset>.parts/``,
no symlink, that exists and carries the asset's recipe hash), and names the fault.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import fcntl
import json
import os
import secrets
import shutil
from pathlib import Path

import h5py
import numpy as np

from . import errors
from ._version import __version__
from .assets import Axis, Variable, atomic_path, canonical_json, open_table, recipe_hash
from .assets.h5 import LIBVER, dims_of, disk_name
from .assets.kinds import SCHEMA
from .assets.layout import layout
from .assets.sources import check_sources, printf_escape

MARKER = ".hairlut-parts"
MARKER_TEXT = "hairlut parts folder: finished blocks of a bake; hairlut deletes only its own files here\n"
PART_GLOB = "part-*.h5"
SHARE_GLOB = "share-*-of-*.npz"
ATTR = "hairlut_parts"  # root attribute of a virtual asset: its parts (JSON: folder, block, total, part count)
_SKIP_ATTRS = {"DIMENSION_LIST", "DIMENSION_LABELS", "REFERENCE_LIST", "CLASS", "NAME"}


def parts_dir(out) -> Path:
    out = Path(out)
    return out.with_name(out.name + ".parts")


def part_name(start: int, stop: int, total: int, block: int) -> str:
    """The part file of units [start, stop) of a bake of ``total`` units in blocks of ``block``: named by the block's
    number, so that a virtual asset maps every whole block with one printf-style name (:func:`part_pattern`); the
    last block, whole or short, is ``…-last.h5``, outside that pattern (a short block cannot share its selection)."""
    if start % block or not 0 <= start < stop <= total or stop != min(start + block, total):
        raise errors.ValidationError("part", [start, stop], f"not a block of {total} units in blocks of {block}")
    return f"part-{total}x{block}-{start // block}{'-last' if stop == total else ''}.h5"


def part_pattern(total: int, block: int) -> str:
    """The HDF5 printf-style source name (``%b``: the block number) of the whole blocks' parts (:func:`part_name`)."""
    return f"part-{total}x{block}-%b.h5"


def _is_ours(folder: Path) -> bool:
    marker = folder / MARKER
    return not marker.is_symlink() and marker.is_file() and marker.read_text(errors="replace") == MARKER_TEXT


def open_folder(out) -> Path:
    """The parts folder of ``out``, created atomically with its marker; refuse anything hairlut did not make."""
    folder = parts_dir(out)
    if not folder.exists() and not folder.is_symlink():
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = folder.with_name(f".{folder.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
        tmp.mkdir()
        (tmp / MARKER).write_text(MARKER_TEXT)
        try:
            os.rename(tmp, folder)  # atomic; fails if another process made the folder first
        except OSError as exc:
            shutil.rmtree(tmp, ignore_errors=True)
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
    if folder.is_symlink():
        raise errors.ValidationError("out", str(out), f"{folder} is a symlink; hairlut does not write through symlinks "
                                     "(remove it or choose another --out)")
    if not folder.is_dir():
        raise errors.ValidationError("out", str(out), f"{folder} exists and is not a folder hairlut made; "
                                     "move it away or choose another --out")
    if not _is_ours(folder):
        raise errors.ValidationError("out", str(out), f"{folder} exists but was not made by hairlut (no {MARKER} "
                                     "marker); hairlut will not write into or delete it: move it away or choose another --out")
    return folder


def clean_temporaries(paths) -> list[Path]:
    """Remove the temporaries that killed writers of ``paths`` left beside them (``.<name>.<pid>.<token>.tmp``).

    Call with the output's lock held, for files only this process writes."""
    gone = []
    for path in map(Path, paths):
        gone += [p for p in path.parent.glob(f".{path.name}.*.tmp") if p.is_file() and not p.is_symlink()]
    for p in gone:
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
    return gone


def remove_folder(folder: Path) -> None:
    """Delete the part files, temporaries and marker hairlut wrote, then the folder if it is empty."""
    if folder.is_symlink() or not folder.is_dir() or not _is_ours(folder):
        return
    for p in [*folder.glob(PART_GLOB), *folder.glob(".part-*.tmp"), *folder.glob(SHARE_GLOB), *folder.glob(".share-*.tmp")]:
        if p.is_file() and not p.is_symlink():
            p.unlink()
    with contextlib.suppress(OSError):  # something a user put here stays, with the folder and marker
        if not any(p.name != MARKER for p in folder.iterdir()):
            (folder / MARKER).unlink()
            folder.rmdir()


def _open_lock(path: Path, what: str) -> int:
    try:
        return os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise errors.ValidationError(what, str(path), f"{path} is a symlink; hairlut does not follow it") from None
        raise


def _same_file(fd: int, path: Path) -> bool:
    """Whether the locked descriptor is still the file at ``path`` (a releaser or prune may have unlinked it)."""
    try:
        st = os.stat(path, follow_symlinks=False)
    except FileNotFoundError:
        return False
    mine = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (mine.st_dev, mine.st_ino)


@contextlib.contextmanager
def lock_file(path, what: str = "out"):
    """Hold the advisory lock file ``path`` (flock; a symlink there is refused); yields whether it had to wait.

    The file exists only while someone holds or waits for it: the holder removes it on release, and a
    waiter that wakes on a removed file takes the lock again on the new one, so no lock files pile up
    beside outputs and two holders never hold different files of one name."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    waited = False
    while True:
        fd = _open_lock(path, what)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            waited = True
            fcntl.flock(fd, fcntl.LOCK_EX)
        if _same_file(fd, path):
            break
        os.close(fd)
    try:
        yield waited
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)  # while still held: a waiter on this file sees it gone and retries
        os.close(fd)  # closing releases the lock


def remove_if_unused(path, dry_run: bool = False) -> bool:
    """Remove the lock file ``path`` when nobody holds it (a leftover of a killed process); whether it was (would be)."""
    path = Path(path)
    if path.is_symlink() or not path.is_file():
        return False
    try:
        fd = os.open(path, os.O_RDWR | os.O_NOFOLLOW)
    except OSError:
        return False
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False  # held: a bake is running
        if not _same_file(fd, path):
            return False
        if not dry_run:
            os.unlink(path)
        return True
    finally:
        os.close(fd)


def lock_path(out, suffix: str = "") -> Path:
    out = Path(out)
    return out.with_name(out.name + ".parts.lock" + suffix)


@contextlib.contextmanager
def locked(out, suffix: str = ""):
    """Hold ``<out>.parts.lock<suffix>`` (:func:`lock_file`); yields whether it had to wait."""
    with lock_file(lock_path(out, suffix), "out") as waited:
        yield waited


# ----------------------------------------------------------------------------- share indexes


def share_name(index: int, count: int) -> str:
    return f"share-{index:05d}-of-{count:05d}.npz"


def stamp(path) -> np.ndarray:
    """(inode, size, mtime in ns) of a file: a part replaced or rewritten since it was indexed differs."""
    st = os.stat(path, follow_symlinks=False)
    return np.array([st.st_ino, st.st_size, st.st_mtime_ns], np.int64)


def write_share(path, digest: str, total: int, blocks: dict) -> Path:
    """Write (atomically) one process's share index: ``blocks`` maps (start, stop) to (stamp, index dict).

    The leader of a virtual bake reads these (:func:`read_share`) instead of opening every part: one
    file per process, whatever the part count.  Each key of the index dicts is stored once, the blocks'
    arrays joined along their first axis, with each block's length."""
    spans = sorted(blocks)
    keys = sorted(blocks[spans[0]][1]) if spans else []
    arrays = {"spans": np.array(spans, np.int64).reshape(-1, 2), "stamps": np.array([blocks[b][0] for b in spans],
                                                                                    np.int64).reshape(-1, 3),
              "head": np.array([digest, str(int(total)), json.dumps(keys)])}
    for i, k in enumerate(keys):
        parts = [np.asarray(blocks[b][1][k]) for b in spans]
        arrays[f"rows{i}"] = np.array([len(a) for a in parts], np.int64)
        arrays[f"data{i}"] = np.concatenate(parts)
    with atomic_path(path) as tmp:
        with open(tmp, "xb") as fh:
            np.savez(fh, **arrays)
    return Path(path)


def read_share(path, digest: str, total: int, block: int, folder: Path) -> dict:
    """{(start, stop): index dict} of the blocks of a share index whose parts are unchanged since they were
    indexed (same inode, size and mtime) and which matches this recipe hash and unit count; {} for a missing
    or foreign share index (the leader then opens those parts itself)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            head = [str(x) for x in z["head"]]
            if head[:2] != [digest, str(int(total))]:
                return {}
            keys = json.loads(head[2])
            spans, stamps = z["spans"], z["stamps"]
            split = {}
            for i, k in enumerate(keys):
                rows = z[f"rows{i}"]
                split[k] = np.split(z[f"data{i}"], np.cumsum(rows)[:-1]) if len(rows) else []
    except (OSError, KeyError, ValueError, IndexError):
        return {}
    got = {}
    for j, ((s, e), st) in enumerate(zip(spans.tolist(), stamps)):
        try:
            if np.array_equal(stamp(folder / part_name(s, e, total, block)), st):
                got[(s, e)] = {k: split[k][j] for k in keys}
        except (OSError, errors.ValidationError):
            continue
    return got


# ----------------------------------------------------------------------------- virtual assets


def _text(v) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def _created(first_part: Path) -> str:
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    if epoch:
        return _dt.datetime.fromtimestamp(int(epoch), _dt.timezone.utc).replace(microsecond=0).isoformat()
    with h5py.File(first_part, "r") as f:
        return _text(f.attrs.get("created", ""))


def _kwargs(chunks) -> dict:
    return dict(chunks=chunks if chunks is not None else True, compression="gzip", compression_opts=4, shuffle=True,
                fletcher32=True, track_times=False)


def write_virtual(out, kind: str, recipe: dict, axis: str, parts: list[tuple[Path, int, int]], axes: list[Axis],
                  variables: list[Variable], attrs: dict | None = None) -> Path:
    """Write ``out`` (atomically): ``variables`` stored, every table of the parts whose first axis is ``axis``
    a virtual dataset over the parts.  ``parts`` are (path, start, stop) covering the axis in order, in equal
    blocks but the last, in one folder, named by :func:`part_name`; each table is two mappings (see the module)."""
    out = Path(out)
    text = recipe_hash(canonical_json(recipe))
    total, block = parts[-1][2], parts[0][2] - parts[0][1]
    folder = parts[0][0].parent
    for path, start, stop in parts:
        if Path(path) != folder / part_name(start, stop, total, block):
            raise errors.ValidationError("parts", str(path), f"a virtual asset maps the blocks of {block} {axis} named "
                                         f"{part_pattern(total, block)} in one folder, in order")
    with open_table(parts[0][0]) as f:
        on_disk, tables = layout(f)
        per_unit = {name: (ds.name.lstrip("/"), ds.shape[1:], ds.dtype, dims_of(ds),
                           {k: v for k, v in ds.attrs.items() if k not in _SKIP_ATTRS})
                    for name, ds in tables.items() if dims_of(ds)[:1] == (axis,)}
    by_name = {a.name: a for a in axes}
    if len(by_name[axis].values) != total:
        raise errors.ValidationError(axis, len(by_name[axis].values), f"the parts cover {total} units")
    rel = os.path.relpath(folder, out.parent)
    described = {"folder": rel, "block": block, "total": total, "parts": len(parts)}
    with atomic_path(out) as tmp:
        with h5py.File(tmp, "w", libver=LIBVER, track_order=True) as f:
            for key, value in {"hairlut_schema": np.int32(SCHEMA), "kind": kind, "hairlut_version": __version__,
                               "created": _created(parts[0][0]), "recipe": canonical_json(recipe),
                               "recipe_hash": text, **(attrs or {}), ATTR: json.dumps(described)}.items():
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
            names = [os.fsencode(os.path.join(printf_escape(rel), n)) for n in (part_pattern(total, block),
                                                                                printf_escape(parts[-1][0].name))]
            for name, (src, rest, dtype, dims, extra) in per_unit.items():
                dcpl = _mappings(total, block, rest, src, names, np.nan if np.issubdtype(dtype, np.floating) else 0)
                space = h5py.h5s.create_simple((total, *rest))
                tid = h5py.h5t.py_create(np.dtype(dtype), logical=1)
                ds = place(name, lambda w, dcpl=dcpl, space=space, tid=tid: f[w] if h5py.h5d.create(
                    f.id, name=w.encode(), tid=tid, space=space, dcpl=dcpl) else None)
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
        new[:len(old)] = old
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
    with h5py.File(path, "r") as f:
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
    folder, a symlink, a part of another recipe, or a part lacking its dataset."""
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            digest = _text(f.attrs.get("recipe_hash", ""))
            found = check_sources(path, f, digest)
    except (OSError, KeyError, RuntimeError, ValueError):
        return []  # not readable as HDF5: the table reader names that fault
    for exc in found.faults.values():
        raise exc
    by_part: dict[Path, list] = {}
    for name, sources in found.tables.items():
        for file_name, dset, shape in sources:
            if file_name == ".":
                continue
            src = found.files[file_name]
            if src.fault is not None:
                raise _refused(path, name.lstrip("/"), file_name, src.path, digest)
            by_part.setdefault(src.path, []).append((dset, shape))
    return _lacking(path, found, by_part)


def _lacking(path: Path, found, by_part: dict) -> list[Path]:
    """The parts of ``by_part``, sorted, after checking that each holds the datasets (with their trailing shapes)
    its tables read."""
    shapes = {src.path: src.datasets for src in found.files.values()}
    for part, wanted in by_part.items():
        for dset, shape in wanted:
            got = shapes[part].get(dset)
            if got is None or tuple(got[1:]) != shape:
                raise errors.CorruptAssetError(part, f"part of {path} lacks dataset {dset!r} of shape (n, "
                                               f"{', '.join(map(str, shape))})")
    return sorted(by_part)


def _refused(path: Path, name: str, file_name: str, part: Path, digest: str) -> errors.AssetError:
    """The error that names why ``part`` is not one of ``path``'s parts (the rule refused it)."""
    folder = parts_dir(path)
    if os.path.isabs(file_name) or ".." in Path(file_name).parts or part.parent.is_symlink() \
            or os.path.realpath(part.parent) != os.path.realpath(folder):
        return errors.CorruptAssetError(path, f"virtual dataset {name!r} points outside the asset's parts folder "
                                        f"({file_name!r})")
    if part.is_symlink():
        return errors.CorruptAssetError(part, f"part of {path} is a symlink; parts are regular files")
    if not part.exists():
        return errors.AssetNotFoundError(part, f"part of {path} is missing (rebake, or copy the parts folder with the asset)")
    try:
        with h5py.File(part, "r") as pf:
            got = _text(pf.attrs.get("recipe_hash", ""))
    except (OSError, KeyError, RuntimeError, ValueError):
        return errors.CorruptAssetError(part, f"part of {path} is not a readable HDF5 file")
    if got != digest:
        return errors.CorruptAssetError(part, f"part of {path} was baked from another recipe (recipe hash "
                                        f"{got[:16] or 'none'}, the asset's is {digest[:16]})")
    return errors.CorruptAssetError(part, f"part of {path} is not a regular HDF5 file of its parts folder")
