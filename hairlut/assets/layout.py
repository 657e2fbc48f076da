"""Where things live in a table file: the HDF5 path of each axis and table, both ways.

Schema 2 keeps the axes as dimension scales at the root, so that netCDF-4 readers
(which look in a variable's group and its ancestors) find them for every table.
A table ``group/name`` is stored at that path, except that a top-level group named
like an axis (HDF5 names are unique in a group) is stored as ``<group>_group``
with a ``hairlut_name`` attribute; :func:`layout` maps it back.  Schema 1 kept
its axes in ``/axes``.
"""

from __future__ import annotations

from collections.abc import Mapping

import h5py

from .. import errors
from .kinds import SCHEMA

AXES_GROUP = "axes"  # schema 1 only: where its axes lived
GROUP_SUFFIX = "_group"  # a table group named like an axis is stored as <name>_group ...
NAME_ATTR = "hairlut_name"  # ... with this attribute giving its name


def attr_text(value) -> str:
    """An HDF5 string attribute as str (h5py gives bytes for fixed-length strings)."""
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)


def disk_name(name: str, axis_names) -> str:
    """Where table ``name`` lives in the file: a top-level group named like an axis gets GROUP_SUFFIX."""
    head, sep, rest = name.partition("/")
    return f"{head}{GROUP_SUFFIX}/{rest}" if sep and head in axis_names else name


def check_layout(axes: Mapping[str, object], names: list[str]) -> None:
    """Every axis, table and group gets its own HDF5 path (one name, one object)."""
    owner: dict[str, str] = {ax: f"axis {ax!r}" for ax in axes}
    for name in names:
        if name in axes:
            raise errors.ValidationError("variable.name", name, "shares its name with an axis (axes are stored at the root)")
        parts = disk_name(name, axes).split("/")
        for depth in range(1, len(parts)):
            group = "/".join(parts[:depth])
            if owner.setdefault(group, f"group of {name!r}").startswith(("axis", "table")):
                raise errors.ValidationError("variable.name", name, f"its group {group!r} is taken by {owner[group]}")
        path = "/".join(parts)
        if path in owner:
            raise errors.ValidationError("variable.name", name, f"its path {path!r} is taken by {owner[path]}")
        owner[path] = f"table {name!r}"


def layout(f: h5py.File) -> tuple[dict[str, h5py.Dataset], dict[str, h5py.Dataset]]:
    """(axes, tables) of an open table file, each by its hairlut name, in file order.

    Schema 1 keeps its axes in ``/axes``; later schemas keep them as dimension
    scales at the root, and may store a group under another name (``hairlut_name``).
    """
    axes: dict[str, h5py.Dataset] = {}
    tables: dict[str, h5py.Dataset] = {}
    old = int(f.attrs.get("hairlut_schema", SCHEMA)) == 1
    if old and isinstance(f.get(AXES_GROUP), h5py.Group):
        axes = {name: ds for name, ds in f[AXES_GROUP].items() if isinstance(ds, h5py.Dataset)}
    for key, obj in f.items():
        if isinstance(obj, h5py.Dataset):
            if old or not obj.is_scale:
                tables[key] = obj
            else:
                axes[key] = obj
        elif isinstance(obj, h5py.Group) and not (old and key == AXES_GROUP):
            head = key if old else attr_text(obj.attrs.get(NAME_ATTR, key))

            def visit(name, item, head=head):
                if isinstance(item, h5py.Dataset):
                    tables[f"{head}/{name}"] = item

            obj.visititems(visit)
    return axes, tables


def table(f: h5py.File, name: str) -> h5py.Dataset:
    """The dataset holding table ``name`` (its hairlut name) in an open table file; KeyError if none."""
    return layout(f)[1][name]
