"""The parts folder of a bake and the virtual assets built over it (every table kind).

``<out>.parts/`` holds a bake's finished blocks, one ``part-<start>-<stop>.h5`` file
each (the kind's shard kind).  hairlut creates the folder atomically with a marker file
(:data:`MARKER`) inside, and refuses a folder without it, or a symlink, rather than touch
what it did not create; it deletes only the part files, temporaries and marker it wrote.
Bakes of one output take turns on an advisory lock (``fcntl.flock`` on
``<out>.parts.lock``, opened without following symlinks).

A *virtual* asset (:func:`write_virtual`) stores its per-unit tables as HDF5 virtual
datasets over the part files, which stay beside it: nothing is copied.  HDF5 fills a
missing source with the fill value silently, so :func:`check_virtual` validates every
source before a reader trusts the file: it must be a part inside ``<asset>.parts/``
(relative name, no symlink), exist, and carry the asset's recipe hash.
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

MARKER = ".hairlut-parts"
MARKER_TEXT = "hairlut parts folder: finished blocks of a bake; hairlut deletes only its own files here\n"
PART_GLOB = "part-*-*.h5"
ATTR = "hairlut_parts"  # root attribute of a virtual asset: its part files (JSON list, relative names)
_SKIP_ATTRS = {"DIMENSION_LIST", "DIMENSION_LABELS", "REFERENCE_LIST", "CLASS", "NAME"}


def parts_dir(out) -> Path:
    out = Path(out)
    return out.with_name(out.name + ".parts")


def part_name(start: int, stop: int) -> str:
    return f"part-{start:09d}-{stop:09d}.h5"


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
    for p in [*folder.glob(PART_GLOB), *folder.glob(".part-*.tmp")]:
        if p.is_file() and not p.is_symlink():
            p.unlink()
    with contextlib.suppress(OSError):  # something a user put here stays, with the folder and marker
        if not any(p.name != MARKER for p in folder.iterdir()):
            (folder / MARKER).unlink()
            folder.rmdir()


@contextlib.contextmanager
def locked(out, suffix: str = ""):
    """Hold ``<out>.parts.lock<suffix>`` (flock, no symlinks followed); yields whether it had to wait."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    path = out.with_name(out.name + ".parts.lock" + suffix)
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise errors.ValidationError("out", str(out), f"{path} is a symlink; hairlut does not follow it") from None
        raise
    try:
        waited = False
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            waited = True
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield waited
    finally:
        os.close(fd)  # closing releases the lock


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
    a virtual dataset over the parts.  ``parts`` are (path, start, stop) covering the axis in order."""
    out = Path(out)
    text = recipe_hash(canonical_json(recipe))
    total = parts[-1][2]
    with open_table(parts[0][0]) as f:
        on_disk, tables = layout(f)
        per_unit = {name: (ds.name.lstrip("/"), ds.shape[1:], ds.dtype, dims_of(ds),
                           {k: v for k, v in ds.attrs.items() if k not in _SKIP_ATTRS})
                    for name, ds in tables.items() if dims_of(ds)[:1] == (axis,)}
    by_name = {a.name: a for a in axes}
    if len(by_name[axis].values) != total:
        raise errors.ValidationError(axis, len(by_name[axis].values), f"the parts cover {total} units")
    rel = [os.path.relpath(p, out.parent) for p, _, _ in parts]
    with atomic_path(out) as tmp:
        with h5py.File(tmp, "w", libver=LIBVER, track_order=True) as f:
            for key, value in {"hairlut_schema": np.int32(SCHEMA), "kind": kind, "hairlut_version": __version__,
                               "created": _created(parts[0][0]), "recipe": canonical_json(recipe),
                               "recipe_hash": text, **(attrs or {}), ATTR: json.dumps(rel)}.items():
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
            for name, (src, rest, dtype, dims, extra) in per_unit.items():
                vl = h5py.VirtualLayout(shape=(total, *rest), dtype=dtype)
                for (p, start, stop), r in zip(parts, rel):
                    vl[start:stop] = h5py.VirtualSource(r, src, shape=(stop - start, *rest))
                fill = np.nan if np.issubdtype(dtype, np.floating) else 0
                ds = place(name, lambda w, vl=vl, fill=fill: f.create_virtual_dataset(w, vl, fillvalue=fill))
                ds.attrs.update(extra)
                for i, dim in enumerate(dims):
                    ds.dims[i].label = dim
                    ds.dims[i].attach_scale(scales[dim])
    return out


def is_virtual(path) -> bool:
    """Whether a table file stores any table as a virtual dataset."""
    found = []
    with h5py.File(path, "r") as f:
        f.visititems(lambda n, o: found.append(n) if isinstance(o, h5py.Dataset) and o.is_virtual else None)
    return bool(found)


def check_virtual(path) -> list[Path]:
    """Validate the sources of every virtual dataset of a table file; returns the part files (none: not virtual).

    Raises :class:`hairlut.errors.CorruptAssetError` for a source outside ``<asset>.parts/``, a symlink, a
    part of another recipe or a part lacking its dataset, and AssetNotFoundError for a missing part."""
    path = Path(path)
    folder = parts_dir(path).resolve()
    sources = []

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset) and obj.is_virtual:
            sources.extend((name, vs.file_name, vs.dset_name, obj.shape[1:]) for vs in obj.virtual_sources())

    try:
        with h5py.File(path, "r") as f:
            digest = _text(f.attrs.get("recipe_hash", ""))
            f.visititems(visit)
    except (OSError, KeyError, RuntimeError, ValueError):
        return []  # not readable as HDF5: the table reader names that fault
    seen: dict[Path, bool] = {}
    for name, file_name, dset, shape in sources:
        if file_name == ".":
            continue
        part = path.parent / file_name
        if os.path.isabs(file_name) or ".." in Path(file_name).parts or part.parent.resolve() != folder:
            raise errors.CorruptAssetError(path, f"virtual dataset {name!r} points outside the asset's parts folder "
                                           f"({file_name!r})")
        if part not in seen:
            if part.is_symlink():
                raise errors.CorruptAssetError(part, f"part of {path} is a symlink; parts are regular files")
            if not part.exists():
                raise errors.AssetNotFoundError(part, f"part of {path} is missing (rebake, or copy the parts folder "
                                                "with the asset)")
            with open_table(part) as pf:
                got = _text(pf.attrs["recipe_hash"])
            if got != digest:
                raise errors.CorruptAssetError(part, f"part of {path} was baked from another recipe (recipe hash "
                                               f"{got[:16]}, the asset's is {digest[:16]})")
            seen[part] = True
        with h5py.File(part, "r") as pf:
            if dset not in pf or not isinstance(pf[dset], h5py.Dataset) or pf[dset].shape[1:] != tuple(shape):
                raise errors.CorruptAssetError(part, f"part of {path} lacks dataset {dset!r} of shape (n, "
                                               f"{', '.join(map(str, shape))})")
    return sorted(seen)
