"""hairlut: precomputation and lookup tables for real-time hair rendering."""

from . import assets, errors
from ._version import __version__

__all__ = ["__version__", "assets", "errors"]
