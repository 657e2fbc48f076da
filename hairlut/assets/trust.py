"""What a table file may contain, checked before anything in it is read.

A hairlut table file is a tree of groups and numeric datasets that lives wholly
inside itself.  Readers (:func:`hairlut.assets.open_table`, ``read_table``,
``summarize``, ``preview`` and every loader built on them) refuse, with a
:mod:`hairlut.errors` exception naming the file and the fault:

* **links** other than the plain tree: external links (another file) and soft links;
  an object reached twice (a hard-link cycle);
* **external raw storage** (``ds.external``: the bytes live in another file);
* **virtual datasets** whose sources are not the asset's own parts (the one exception, used by
  sharded bakes), or an own part that ``HDF5_VDS_PREFIX`` would redirect: :mod:`.sources`;
* **datasets that do not hold numbers** (strings, compounds, references, opaque,
  variable-length, complex);
* **declared storage that is not there**: a chunked dataset with unallocated chunks
  (hairlut writes every chunk) or a contiguous one shorter than its shape;
* **shapes larger than the memory budget** (:mod:`hairlut.budget`), before a read;
* metadata that HDF5 cannot decode (a flipped bit): :func:`guard` turns the
  library's KeyError / OSError / ValueError / RuntimeError ... into
  :class:`~hairlut.errors.CorruptAssetError`;
* data that HDF5 cannot read (a chunk failing its fletcher32 checksum): :func:`data_fault`
  maps the read's failure to :class:`~hairlut.errors.ChecksumError` or ``CorruptAssetError``.

A flipped bit can still crash the HDF5 C library itself (a double free), which no
Python code can catch; in a fuzz of every 13th metadata byte of a small table that
happened at 5 offsets out of 2,125.
"""

from __future__ import annotations

import contextlib
import math
from pathlib import Path

import h5py
import numpy as np

from .. import budget, errors

#: The most objects a table file may hold (a tree-walk bomb is refused).
MAX_OBJECTS = 100_000
#: Kinds of NumPy dtype a table may hold: bool, signed and unsigned integers, floats.
NUMERIC_KINDS = frozenset("biuf")
PARTS_SUFFIX = ".parts"
#: HDF5's environment variable that redirects the relative sources of virtual datasets.
VDS_PREFIX_ENV = "HDF5_VDS_PREFIX"

_H5_FAULTS = (
    KeyError,
    OSError,
    ValueError,
    RuntimeError,
    AttributeError,
    TypeError,
    IndexError,
    UnicodeError,
    MemoryError,
    OverflowError,
)


def _first_line(exc: BaseException) -> str:
    msg = str(exc).strip().strip("'\"")
    return msg.splitlines()[0] if msg else type(exc).__name__


@contextlib.contextmanager
def guard(path, what: str = "HDF5 metadata"):
    """Turn an HDF5 library fault raised in the body into CorruptAssetError naming ``path``.

    hairlut's own errors pass through unchanged.
    """
    try:
        yield
    except errors.HairlutError:
        raise
    except _H5_FAULTS as exc:
        raise errors.CorruptAssetError(path, f"{what} cannot be read ({type(exc).__name__}: {_first_line(exc)})") from None


def check_links(path, f: h5py.File) -> None:
    """Walk the file's tree without following links; refuse external and soft links and cycles."""
    seen: set = set()
    count = 0
    stack = [("", f)]
    while stack:
        prefix, group = stack.pop()
        for key in group.keys():  # names only: nothing is resolved yet
            name = f"{prefix}/{key}"
            link = group.get(key, getlink=True)
            if isinstance(link, h5py.ExternalLink):
                raise errors.ForeignReferenceError(
                    path,
                    f"{name!r} is an external link to {link.filename}:{link.path}; table files never reach outside themselves",
                )
            if isinstance(link, h5py.SoftLink):
                raise errors.ForeignReferenceError(path, f"{name!r} is a soft link to {link.path!r}; table files hold no links")
            obj = group.get(key)
            if obj is None or obj.id in seen:
                raise errors.CorruptAssetError(path, f"{name!r} is reached twice (a hard-link cycle or shared object)")
            seen.add(obj.id)
            count += 1
            if count > MAX_OBJECTS:
                raise errors.CorruptAssetError(path, f"more than {MAX_OBJECTS} objects; not a hairlut table")
            if isinstance(obj, h5py.Group):
                stack.append((name, obj))
            elif not isinstance(obj, h5py.Dataset):
                raise errors.CorruptAssetError(path, f"{name!r} is a {type(obj).__name__}, neither a group nor a dataset")


#: Shapes of the virtual datasets of open files, by (HDF5 id of the open file, dataset name); see :func:`table_shape`.
_SHAPES: dict[tuple, tuple | None] = {}
_SHAPES_MAX = 4096


def table_shape(ds: h5py.Dataset) -> tuple | None:
    """``ds.shape`` for the checks here, without HDF5 looking for every block file of a virtual dataset: it does
    that (about 0.1 ms a part) each time such a dataset's extent is read, by each ``h5py.Dataset`` object anew.  A
    virtual dataset whose mappings declare one fixed extent (no unlimited maximum: hairlut's, whose last block's
    fixed mapping pins it) has at most that extent, which is taken from its creation properties; another is read
    from HDF5 once per opening of its file (HDF5 does not reuse file ids, so an entry is never stale)."""
    if not ds.is_virtual:
        return ds.shape
    key = (h5py.h5i.get_file_id(ds.id).id, ds.name)
    if key not in _SHAPES:
        if len(_SHAPES) >= _SHAPES_MAX:
            _SHAPES.clear()
        _SHAPES[key] = _fixed_extent(ds) or ds.shape
    return _SHAPES[key]


def _fixed_extent(ds: h5py.Dataset) -> tuple | None:
    """The one extent every mapping of virtual ``ds`` declares, when its maximum is that extent; else None."""
    try:
        extents = {(vs.vspace.shape, vs.vspace.get_simple_extent_dims(True)) for vs in ds.virtual_sources()}
    except _H5_FAULTS:
        return None
    if len(extents) != 1:
        return None
    shape, most = extents.pop()
    return shape if shape and tuple(shape) == tuple(most) else None


def declared_nbytes(ds: h5py.Dataset) -> float:
    """Bytes the dataset's declared shape and dtype take in memory (a float: no overflow)."""
    shape = table_shape(ds)
    return budget.product(*shape, ds.dtype.itemsize) if shape is not None else 0.0


def _expected_chunks(shape, chunks) -> int:
    n = 1
    for s, c in zip(shape, chunks):
        n *= -(-int(s) // int(c))
    return n


def check_dataset(path, name: str, ds: h5py.Dataset, recipe_hash: str) -> None:
    """Refuse a dataset that reaches outside the file, holds no numbers, or lacks its storage."""
    path = Path(path)
    if ds.external:
        files = ", ".join(str(e[0].decode() if isinstance(e[0], bytes) else e[0]) for e in ds.external)
        raise errors.ForeignReferenceError(
            path, f"dataset {name!r} keeps its data in external file(s) {files}; table files never reach outside themselves"
        )
    if ds.dtype.kind not in NUMERIC_KINDS or ds.dtype.names is not None or ds.dtype.subdtype is not None:
        raise errors.CorruptAssetError(path, f"dataset {name!r} holds {ds.dtype} values, not numbers")
    if ds.is_virtual:  # first: the extent of a printf-style mapping is set from the files HDF5 finds
        from .sources import check_virtual_dataset  # here: sources builds on this module's guard

        check_virtual_dataset(path, name, ds, recipe_hash)
    if table_shape(ds) is None:
        raise errors.CorruptAssetError(path, f"dataset {name!r} has an empty (null) dataspace")
    if ds.is_virtual:
        return
    nbytes = declared_nbytes(ds)
    if ds.chunks is not None:
        want = _expected_chunks(ds.shape, ds.chunks)
        have = ds.id.get_num_chunks()
        if have < want:
            raise errors.CorruptAssetError(
                path,
                f"dataset {name!r} declares shape {ds.shape} in {want} chunks but stores {have} "
                "(unallocated chunks; hairlut writes every chunk)",
            )
    elif nbytes and ds.id.get_storage_size() < nbytes and not math.isclose(ds.id.get_storage_size(), nbytes):
        raise errors.CorruptAssetError(
            path, f"dataset {name!r} declares {budget.describe(nbytes)} but stores {ds.id.get_storage_size()} bytes"
        )


def check_readable(path, sizes: dict[str, h5py.Dataset], limit: int | None = None) -> None:
    """Refuse to read datasets whose declared sizes add up to more than the memory budget."""
    total = 0.0
    biggest = None
    for name, ds in sizes.items():
        n = declared_nbytes(ds)
        total += n
        if biggest is None or n > declared_nbytes(sizes[biggest]):
            biggest = name
    cap = budget.memory_limit(limit)
    if total > cap:
        ds = sizes[biggest]
        raise errors.AssetTooLargeError(
            path,
            f"declares {budget.describe(total)} of tables (the largest, {biggest!r}, is {ds.shape} {ds.dtype}: "
            f"{budget.describe(declared_nbytes(ds))}), above the memory limit of {budget.describe(cap)} "
            f"({'the limit= argument' if limit is not None else budget.source()})",
        )


def data_fault(path, ds: h5py.Dataset, exc: Exception) -> errors.CorruptAssetError:
    """Map an h5py read failure of ``ds`` to the hairlut error that describes it.

    hairlut's filter pipeline is shuffle → gzip → fletcher32, so on read the
    checksum is the first filter to run: a filter failure on such a dataset is a
    checksum failure.
    """
    msg = str(exc)
    plist = ds.id.get_create_plist()
    last = plist.get_filter(plist.get_nfilters() - 1)[0] if plist.get_nfilters() else None
    if "checksum" in msg.lower() or ("filter" in msg and last == h5py.h5z.FILTER_FLETCHER32):
        return errors.ChecksumError(path, f"dataset {ds.name.lstrip('/')!r} fails its fletcher32 checksum")
    first = msg.splitlines()[0] if msg else type(exc).__name__
    return errors.CorruptAssetError(path, f"dataset {ds.name.lstrip('/')!r} cannot be read ({first})")


def finite_fault(data: np.ndarray) -> str | None:
    """'3 NaN, 1 inf' when ``data`` (numeric) holds non-finite values, else None."""
    data = np.asarray(data)
    if data.dtype.kind != "f" and data.dtype.kind != "c":
        return None
    bad = ~np.isfinite(data)
    if not bad.any():
        return None
    nan = int(np.isnan(data).sum())
    return f"{nan} NaN, {int(bad.sum()) - nan} inf among {data.size} values"
