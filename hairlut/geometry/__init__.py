"""Hair geometry: strands as ragged polylines, and their file formats (.tfx, .hair, USD)."""

from .formats import SUFFIXES, format_of, read_strands, write_strands
from .strands import Strands

__all__ = ["SUFFIXES", "Strands", "format_of", "read_strands", "write_strands"]
