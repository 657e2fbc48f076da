"""HDF5 table files: self-describing, checksummed, readable by HDF5 1.10 tools and netCDF-4 readers.

Layout of a table file (``hairlut_schema`` 2)::

    /                      attrs: hairlut_schema, kind, hairlut_version, created,
                                  recipe (canonical JSON), recipe_hash (SHA-256)
    /<axis>                1-D dimension scale named after its axis (a netCDF-4
                           coordinate variable); attrs units, long_name, periodic[, period]
    /<variable>            N-D table; attrs units, long_name; dims labelled and
                           attached to the root scales
    /<group>/<variable>    a table named ``group/variable``; its dims attach to the
                           same root scales (the root is every group's ancestor)

netCDF-4 readers (h5netcdf, so ``xarray.open_dataset(path, engine="h5netcdf")``
and ``xarray.open_datatree``) look for a variable's dimension scales in its own
group or an ancestor; at the root they serve every group, and xarray shows the
axes as coordinates.  A table group cannot share the root with an axis of the
same name (HDF5 names are unique in a group), so such a group is stored as
``<group>_group`` with a ``hairlut_name`` attribute giving its name; readers
here map it back, so tables keep the names they were written with.

Schema 1 files (axes in ``/axes``, where netCDF readers do not find them) are
still read.  Every dataset (scales included) is chunked with gzip + shuffle +
fletcher32, and the file is written with ``libver=("earliest", "v110")``.
Nothing time-dependent is stored except ``created``, which honours
``SOURCE_DATE_EPOCH``; so the same recipe gives a bitwise-identical file.

This module holds the table types (:class:`Axis`, :class:`Variable`,
:class:`Table`), the writer (:func:`write_table`) and the validating readers
(:func:`open_table`, :func:`read_table`, :func:`dims_of`, :func:`check_file`).
A sharded asset's virtual tables are read from its parts by
:func:`hairlut.assets.virtual.read_virtual`, and a failed read is mapped to its
error by :func:`hairlut.assets.trust.data_fault`; both are importable from here
too, and ``read_table`` calls ``read_virtual`` through this module's name.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import os
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from .. import errors
from .._version import __version__
from ..atomic import atomic_path, ensure_space, write_bytes
from ..files import regular_file
from .bounds import check_bounds
from .chunks import ChunkWriter
from .kinds import KINDS, SCHEMA, SUPPORTED_SCHEMAS
from .layout import AXES_GROUP, NAME_ATTR, attr_text, check_layout, disk_name, layout, table  # noqa: F401  (re-exported)
from .recipe import canonical_json, recipe_hash
from .trust import check_dataset, check_links, check_readable, data_fault, finite_fault, guard, table_shape
from .virtual import read_virtual  # read_table looks it up here at call time (tests patch it)

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
LIBVER = ("earliest", "v110")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")


@dataclass(frozen=True)
class Axis:
    """A coordinate axis: one value per index along a table dimension."""

    name: str
    values: np.ndarray
    units: str
    long_name: str
    period: float | None = None  # set for periodic axes (angles wrap around)

    @property
    def periodic(self) -> bool:
        return self.period is not None


@dataclass(frozen=True)
class Variable:
    """An N-D table whose dimensions are named axes."""

    name: str
    data: np.ndarray
    dims: tuple[str, ...]
    units: str
    long_name: str
    chunks: tuple[int, ...] | None = None  # None: let h5py choose
    attrs: Mapping[str, object] = field(default_factory=dict)


@dataclass
class Table:
    """A validated table file read into memory."""

    path: Path
    kind: str
    schema: int
    version: str
    created: str
    recipe: dict
    recipe_hash: str
    attrs: dict
    axes: dict[str, Axis]
    variables: dict[str, Variable]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.variables[name].data


# ----------------------------------------------------------------------------- writing


def _created() -> str:
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    when = _dt.datetime.fromtimestamp(int(epoch), _dt.UTC) if epoch else _dt.datetime.now(_dt.UTC)
    return when.replace(microsecond=0).isoformat()


def _check_name(field_name: str, name: str) -> None:
    if not isinstance(name, str) or not _NAME.match(name) or name.split("/")[0] == AXES_GROUP:
        raise errors.ValidationError(field_name, name, "use letters, digits, '_' and '/' (not the reserved 'axes')")


def _dataset_kwargs(shape: tuple[int, ...], chunks) -> dict:
    return dict(
        chunks=chunks if chunks is not None else True,
        compression="gzip",
        compression_opts=4,
        shuffle=True,
        fletcher32=True,
        track_times=False,
    )


def _validate(axes: Iterable[Axis], variables: Iterable[Variable]) -> tuple[dict, list]:
    by_name: dict[str, Axis] = {}
    for ax in axes:
        _check_name("axis.name", ax.name)
        values = np.asarray(ax.values)
        if values.ndim != 1 or values.size == 0 or not np.issubdtype(values.dtype, np.number):
            raise errors.ValidationError(f"axes.{ax.name}.values", values.shape, "an axis is a non-empty 1-D numeric array")
        if ax.name in by_name:
            raise errors.ValidationError("axis.name", ax.name, "duplicate axis")
        by_name[ax.name] = ax
    seen, out = set(), []
    for var in variables:
        _check_name("variable.name", var.name)
        data = np.asarray(var.data)
        if var.name in seen:
            raise errors.ValidationError("variable.name", var.name, "duplicate variable")
        seen.add(var.name)
        if not (np.issubdtype(data.dtype, np.number) or data.dtype == np.bool_):
            raise errors.ValidationError(f"{var.name}.dtype", str(data.dtype), "tables hold numbers")
        if data.ndim == 0 or data.size == 0:
            raise errors.ValidationError(f"{var.name}.shape", data.shape, "a table has at least one dimension and one element")
        if len(var.dims) != data.ndim:
            raise errors.ValidationError(f"{var.name}.dims", var.dims, f"need one axis name per dimension of shape {data.shape}")
        for i, dim in enumerate(var.dims):
            if dim not in by_name:
                raise errors.ValidationError(f"{var.name}.dims[{i}]", dim, "no such axis")
            if len(by_name[dim].values) != data.shape[i]:
                raise errors.ValidationError(
                    f"{var.name}.dims[{i}]",
                    dim,
                    f"axis has {len(by_name[dim].values)} values, table dimension has {data.shape[i]}",
                )
        if var.chunks is not None and (len(var.chunks) != data.ndim or any(c < 1 for c in var.chunks)):
            raise errors.ValidationError(f"{var.name}.chunks", var.chunks, f"need {data.ndim} positive chunk sizes")
        out.append((var, data))
    check_layout(by_name, [var.name for var, _ in out])
    return by_name, out


def write_table(
    path: str | os.PathLike,
    kind: str,
    recipe: Mapping,
    axes: Iterable[Axis],
    variables: Iterable[Variable],
    attrs: Mapping[str, object] | None = None,
) -> Path:
    """Write a table file atomically and return its path.

    ``recipe`` is every parameter that produced the tables; it is stored as
    canonical JSON beside its SHA-256.  ``attrs`` adds further root attributes.
    """
    if kind not in KINDS:
        raise errors.ValidationError("kind", kind, f"unknown asset kind; known: {', '.join(sorted(KINDS))}")
    recipe_text = canonical_json(recipe)
    by_name, checked = _validate(axes, variables)
    missing = [name for name in KINDS[kind].required if name not in {v.name for v, _ in checked}]
    if missing:
        raise errors.ValidationError("variables", missing, f"kind {kind!r} requires them")
    path = Path(path)
    check_bounds(kind, KINDS[kind].bounds, recipe, {var.name: (data, var.dims) for var, data in checked}, path.name)
    # Built in memory (HDF5's core driver, no backing store), then written by Python: HDF5
    # itself never meets a full disk (it can segfault there), and a short write is a
    # DiskFullError with nothing left under the final name.
    f = h5py.File(f"{path.name}.in-memory", "w", driver="core", backing_store=False, libver=LIBVER, track_order=True)
    chunks = ChunkWriter()
    try:
        f.attrs["hairlut_schema"] = np.int32(SCHEMA)
        f.attrs["kind"] = kind
        f.attrs["hairlut_version"] = __version__
        f.attrs["created"] = _created()
        f.attrs["recipe"] = recipe_text
        f.attrs["recipe_hash"] = recipe_hash(recipe_text)
        for key, value in (attrs or {}).items():
            f.attrs[key] = value
        scales = {}
        for ax in by_name.values():
            values = np.asarray(ax.values)
            ds = f.create_dataset(ax.name, data=values, **_dataset_kwargs(values.shape, None))
            ds.attrs["units"] = ax.units
            ds.attrs["long_name"] = ax.long_name
            ds.attrs["periodic"] = np.int8(ax.periodic)
            if ax.periodic:
                ds.attrs["period"] = float(ax.period)
            ds.make_scale(ax.name)
            scales[ax.name] = ds
        for var, data in checked:
            where = disk_name(var.name, by_name)
            parts = where.split("/")
            for depth in range(1, len(parts)):  # groups list their tables in the order written
                group = "/".join(parts[:depth])
                if group not in f:
                    f.create_group(group, track_order=True)
            if where != var.name:
                f[parts[0]].attrs[NAME_ATTR] = var.name.split("/")[0]
            ds = f.create_dataset(where, shape=data.shape, dtype=data.dtype, **_dataset_kwargs(data.shape, var.chunks))
            chunks.add(ds, data)  # shuffle, gzip, fletcher32 on every core: HDF5's own chunk bytes
            chunks.flush()  # before anything else touches the file, so its layout is the same for any core count
            ds.attrs["units"] = var.units
            ds.attrs["long_name"] = var.long_name
            for key, value in var.attrs.items():
                ds.attrs[key] = value
            for i, dim in enumerate(var.dims):
                ds.dims[i].label = dim
                ds.dims[i].attach_scale(scales[dim])
        f.flush()
        image = f.id.get_file_image()
    finally:
        chunks.close()
        f.close()
    ensure_space(path, len(image))
    with atomic_path(path) as tmp:
        write_bytes(tmp, image)
    return path


# ----------------------------------------------------------------------------- reading


def check_file(path: str | os.PathLike, signature: bytes, what: str) -> Path:
    """Raise unless ``path`` is an existing regular file that starts with ``signature``."""
    path = regular_file(path, what)
    with path.open("rb") as fh:
        head = fh.read(len(signature))
    if head != signature:
        shown = "empty file" if not head else f"starts with {head[:8]!r}"
        raise errors.FormatError(path, f"not {what} ({shown})")
    return path


def _open(path: Path) -> h5py.File:
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        msg = str(exc)
        if "truncated" in msg:
            raise errors.TruncatedAssetError(path, "truncated HDF5 file (shorter than its superblock says)") from None
        raise errors.CorruptAssetError(
            path, f"cannot open HDF5 file ({msg.splitlines()[0] if msg else 'unknown error'})"
        ) from None


def _validate_root(path: Path, f: h5py.File, kind: str | None, required: Iterable[str]) -> None:
    attrs = f.attrs
    if "hairlut_schema" not in attrs:
        raise errors.FormatError(path, "not a hairlut table (no hairlut_schema attribute)")
    try:
        schema = int(attrs["hairlut_schema"])
    except (TypeError, ValueError):
        raise errors.SchemaError(path, f"hairlut_schema {attrs['hairlut_schema']!r} is not an integer") from None
    if schema not in SUPPORTED_SCHEMAS:
        raise errors.SchemaError(
            path, f"unknown hairlut_schema {schema} (this hairlut {__version__} reads {sorted(SUPPORTED_SCHEMAS)})"
        )
    for key in ("kind", "recipe", "recipe_hash"):
        if key not in attrs:
            raise errors.MissingDatasetError(path, f"root attribute {key!r} is missing")
    file_kind = attr_text(attrs["kind"])
    if kind is not None and file_kind != kind:
        raise errors.KindError(path, f"holds kind {file_kind!r}, expected {kind!r}")
    if file_kind not in KINDS:
        raise errors.KindError(path, f"unknown kind {file_kind!r}")
    if recipe_hash(attr_text(attrs["recipe"])) != attr_text(attrs["recipe_hash"]):
        raise errors.ChecksumError(path, "recipe_hash does not match the stored recipe")
    stored_recipe(path, f)
    check_links(path, f)  # before layout(), which resolves links
    if schema == 1 and isinstance(f.get(AXES_GROUP), h5py.Group):
        for name, obj in f[AXES_GROUP].items():
            if not isinstance(obj, h5py.Dataset):
                raise errors.CorruptAssetError(path, f"'{AXES_GROUP}/{name}' is a group; /{AXES_GROUP} holds only axis datasets")
    axes, tables = layout(f)
    for name in (*KINDS[file_kind].required, *required):
        if name not in tables:
            raise errors.MissingDatasetError(path, f"required dataset {name!r} is missing")
    for what, found in (("axis", axes), ("table", tables)):
        for name, ds in found.items():
            check_dataset(path, name if what == "table" else f"axis {name}", ds, attr_text(attrs["recipe_hash"]))


def stored_recipe(path, f: h5py.File) -> dict:
    """The root ``recipe`` attribute, parsed: a JSON object, else CorruptAssetError naming the file."""
    text = f.attrs["recipe"]
    if not isinstance(text, (str, bytes)):
        raise errors.CorruptAssetError(path, f"root attribute 'recipe' is a {type(text).__name__}, not JSON text")
    try:
        recipe = json.loads(attr_text(text))
    except (ValueError, UnicodeError) as exc:
        raise errors.CorruptAssetError(path, f"root attribute 'recipe' is not JSON ({exc})") from None
    if not isinstance(recipe, dict):
        raise errors.CorruptAssetError(path, f"root attribute 'recipe' is JSON {type(recipe).__name__}, not an object")
    return recipe


@contextlib.contextmanager
def open_table(path: str | os.PathLike, kind: str | None = None, required: Iterable[str] = ()):
    """Open a table file lazily after validating its root; yields the ``h5py.File``.

    Use for large tables read piecewise.  Reads that hit corrupt chunks should be
    wrapped with :func:`data_fault`.  The root is validated, and every object checked
    by :mod:`hairlut.assets.trust` (no links, external storage or foreign virtual
    sources; numeric datasets with their storage present); an HDF5 library fault in
    the body (corrupt metadata) becomes :class:`~hairlut.errors.CorruptAssetError`.
    """
    path = check_file(path, HDF5_SIGNATURE, "an HDF5 file")
    f = _open(path)
    try:
        with guard(path):
            _validate_root(path, f, kind, required)
            yield f
    finally:
        with contextlib.suppress(Exception):
            f.close()


def _read_axis(path: Path, name: str, ds: h5py.Dataset) -> Axis:
    try:
        values = ds[()]
    except OSError as exc:
        raise data_fault(path, ds, exc) from None
    if values.ndim != 1 or finite_fault(values):
        raise errors.CorruptAssetError(path, f"axis {name!r} is not a finite 1-D array (shape {values.shape})")
    period = float(ds.attrs["period"]) if int(ds.attrs.get("periodic", 0)) else None
    return Axis(name, values, attr_text(ds.attrs.get("units", "")), attr_text(ds.attrs.get("long_name", name)), period)


def dims_of(ds: h5py.Dataset) -> tuple[str, ...]:
    """Axis names of a dataset's dimensions (its attached scales, else the labels).

    A virtual dataset's are read from its dimension-scale attributes (``DIMENSION_LIST``, ``DIMENSION_LABELS``):
    HDF5's dimension-scale calls read its extent, which for a printf-style mapping opens every part file."""
    if ds.is_virtual:
        return _virtual_dims(ds)
    names = []
    for i, dim in enumerate(ds.dims):
        scale = dim[0].name.rsplit("/", 1)[-1] if len(dim) else ""
        names.append(scale or dim.label or f"dim{i}")
    return tuple(names)


def _virtual_dims(ds: h5py.Dataset) -> tuple[str, ...]:
    """:func:`dims_of` from the attributes H5DS writes: dimension ``i``'s first attached scale, else its label."""
    rank = len(table_shape(ds) or ())
    labels = ds.attrs["DIMENSION_LABELS"] if "DIMENSION_LABELS" in ds.attrs else [b""] * rank
    scales = ds.attrs["DIMENSION_LIST"] if "DIMENSION_LIST" in ds.attrs else [()] * rank
    if len(labels) != rank or len(scales) != rank:
        raise errors.CorruptAssetError(
            ds.file.filename,
            f"dataset {ds.name.lstrip('/')!r} has dimension scales for "
            f"{len(scales)} and labels for {len(labels)} of its {rank} dimensions",
        )
    names = []
    for i in range(rank):
        scale = ds.file[scales[i][0]].name.rsplit("/", 1)[-1] if len(scales[i]) else ""
        names.append(scale or attr_text(labels[i]) or f"dim{i}")
    return tuple(names)


_DIMENSION_ATTRS = {"units", "long_name", "DIMENSION_LIST", "DIMENSION_LABELS"}  # stored by the store itself


def read_table(
    path: str | os.PathLike,
    kind: str | None = None,
    required: Iterable[str] = (),
    *,
    finite: bool = True,
    memory_limit: int | None = None,
) -> Table:
    """Read and validate a whole table file.

    Every dataset is read, so every fletcher32 checksum is verified.  Raises a
    :mod:`hairlut.errors` exception naming the file and the fault.  The declared
    sizes are checked against the memory budget (:mod:`hairlut.budget`,
    ``memory_limit`` bytes when given) before anything is read; with ``finite``
    (the default) a table holding NaN or infinity is refused, naming the table.
    """
    with open_table(path, kind, required) as f:
        path = Path(path)
        on_disk, tables = layout(f)
        check_readable(path, {**{f"axis {k}": v for k, v in on_disk.items()}, **tables}, memory_limit)
        axes = {}
        for name, ds in on_disk.items():
            axes[name] = _read_axis(path, name, ds)
        direct = read_virtual(path, f, tables)
        variables = {}
        for name, ds in tables.items():
            try:
                data = direct[name] if name in direct else ds[()]
            except OSError as exc:
                raise data_fault(path, ds, exc) from None
            bad = finite_fault(data) if finite else None
            if bad:
                raise errors.CorruptAssetError(path, f"table {name!r} holds non-finite values ({bad})")
            extra = {k: v for k, v in ds.attrs.items() if k not in _DIMENSION_ATTRS}
            units, long_name = attr_text(ds.attrs.get("units", "")), attr_text(ds.attrs.get("long_name", name))
            variables[name] = Variable(name, data, dims_of(ds), units, long_name, ds.chunks, extra)
        a = f.attrs
        known = {"hairlut_schema", "kind", "hairlut_version", "created", "recipe", "recipe_hash"}
        return Table(
            path=path,
            kind=attr_text(a["kind"]),
            schema=int(a["hairlut_schema"]),
            version=attr_text(a.get("hairlut_version", "")),
            created=attr_text(a.get("created", "")),
            recipe=stored_recipe(path, f),
            recipe_hash=attr_text(a["recipe_hash"]),
            attrs={k: v for k, v in a.items() if k not in known},
            axes=axes,
            variables=variables,
        )
