"""The asset store: HDF5 tables and OpenEXR images, written atomically, read with validation.

Tables: :func:`read_table` reads and validates a whole table into a :class:`Table` (its :class:`Axis` and
:class:`Variable` s), :func:`open_table` opens one lazily, and :func:`write_table` writes one atomically.
Images: :func:`read_exr` returns an :class:`ExrImage` (its :class:`ExrPart` s) and :func:`write_exr` writes
one.  :func:`summarize` and :func:`preview` describe and draw any asset (``hairlut inspect``), and
:func:`recipe_hash` is the content address every asset records.  The atomic writers, the kind table and the
virtual-asset parts are wiring for the bakers, imported from their modules (and from ``hairlut.atomic``)."""

from ..atomic import atomic_path, atomic_write_bytes, check_writable, stale_temporaries
from .exr import ExrImage, ExrPart, read_exr, write_exr
from .h5 import Axis, Table, Variable, open_table, read_table, write_table
from .kinds import KINDS, SCHEMA, register_kind
from .preview import encode_png, parse_slice, preview, tonemap
from .recipe import canonical_json, recipe_hash
from .sources import allowed_virtual_sources
from .summary import array_stats, sniff, summarize

__all__ = [
    "Axis",
    "ExrImage",
    "ExrPart",
    "Table",
    "Variable",
    "open_table",
    "preview",
    "read_exr",
    "read_table",
    "recipe_hash",
    "summarize",
    "write_exr",
    "write_table",
]
