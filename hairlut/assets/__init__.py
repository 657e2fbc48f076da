"""The asset store: HDF5 tables and OpenEXR images, written atomically, read with validation."""

from ..atomic import atomic_path, atomic_write_bytes, check_writable, stale_temporaries
from .exr import ExrImage, ExrPart, read_exr, write_exr
from .h5 import Axis, Table, Variable, open_table, read_table, write_table
from .preview import encode_png, parse_slice, preview, tonemap
from .summary import array_stats, sniff, summarize
from .kinds import KINDS, SCHEMA, register_kind
from .recipe import canonical_json, recipe_hash
from .sources import allowed_virtual_sources

__all__ = [
    "Axis", "ExrImage", "allowed_virtual_sources", "ExrPart", "KINDS", "SCHEMA", "Table", "Variable",
    "atomic_path", "atomic_write_bytes", "canonical_json", "check_writable", "open_table", "read_exr", "read_table",
    "recipe_hash", "register_kind", "stale_temporaries", "write_exr", "write_table",
    "array_stats", "encode_png", "parse_slice", "preview", "sniff", "summarize", "tonemap",
]
