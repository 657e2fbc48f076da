"""Read and write hair strand files, choosing the format by file extension.

| extension | format | module |
|---|---|---|
| ``.tfx`` | AMD TressFX (equal vertex counts; keeps the w "movable" flag and per-strand UVs) | ``_tfx`` |
| ``.hair`` | Cem Yuksel's hair format (segments, points, thickness, transparency, colour) | ``_hair`` |
| ``.usda`` ``.usdc`` ``.usd`` | USD linear ``BasisCurves`` (optional package ``usd-core``) | ``_usd`` |

Readers check the file against its own header before trusting it and raise
``hairlut.errors`` exceptions naming the file and the fault; writers replace
the target atomically.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from ..errors import FormatError, ValidationError
from ._hair import read_hair, write_hair
from ._tfx import read_tfx, write_tfx
from ._usd import read_usd, write_usd
from .strands import Strands

_FORMATS: dict[str, tuple[str, Callable[..., Strands], Callable[..., None]]] = {
    ".tfx": ("tfx", read_tfx, write_tfx),
    ".hair": ("hair", read_hair, write_hair),
    ".usda": ("usd", read_usd, write_usd),
    ".usdc": ("usd", read_usd, write_usd),
    ".usd": ("usd", read_usd, write_usd),
}
SUFFIXES = tuple(_FORMATS)


def format_of(path: str | os.PathLike) -> str | None:
    """``"tfx"``, ``"hair"`` or ``"usd"`` for a known extension (any case), else None."""
    entry = _FORMATS.get(Path(path).suffix.lower())
    return entry[0] if entry else None


def read_strands(path: str | os.PathLike) -> Strands:
    """Read a strand file of any supported format (see the module docstring)."""
    entry = _FORMATS.get(Path(path).suffix.lower())
    if entry is None:
        raise FormatError(path, f"unknown hair file extension {Path(path).suffix!r}; known: {', '.join(SUFFIXES)}")
    return entry[1](path)


def write_strands(path: str | os.PathLike, strands: Strands) -> None:
    """Write ``strands`` atomically in the format the extension names."""
    if not isinstance(strands, Strands):
        raise ValidationError("strands", type(strands).__name__, "must be a hairlut.geometry.Strands")
    entry = _FORMATS.get(Path(path).suffix.lower())
    if entry is None:
        raise ValidationError("path", os.fspath(path), f"unknown hair file extension; known: {', '.join(SUFFIXES)}")
    entry[2](path, strands)
