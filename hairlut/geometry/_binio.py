"""Helpers shared by the strand readers and writers: guarded file reads and checked conversions."""

from __future__ import annotations

import os

import numpy as np

from ..errors import AssetNotFoundError, CorruptAssetError, ValidationError
from ..files import regular_file
from .strands import Strands

F32_MAX = float(np.finfo(np.float32).max)


def read_bytes(path: str | os.PathLike) -> bytes:
    """The whole file; a missing file, a folder, a FIFO or a device raises the matching hairlut error
    (:func:`hairlut.files.regular_file`) before anything is opened."""
    p = regular_file(path, "a hair file")
    try:
        return p.read_bytes()
    except FileNotFoundError:  # removed since the check
        raise AssetNotFoundError(p, "no such file") from None


def build(path: str | os.PathLike, **fields) -> Strands:
    """``Strands(**fields)``, with a validation failure reported as a corrupt file."""
    try:
        return Strands(**fields)
    except ValidationError as exc:
        raise CorruptAssetError(path, f"content fails validation: {exc}") from None


def as_f32(name: str, arr: np.ndarray) -> np.ndarray:
    """``arr`` as little-endian float32 for writing; values beyond float32 range are refused."""
    arr = np.asarray(arr)
    if arr.dtype != np.float32 and arr.size and float(np.abs(arr).max()) > F32_MAX:
        raise ValidationError(name, float(np.abs(arr).max()), "magnitude exceeds the float32 range of the file format")
    return np.ascontiguousarray(arr, dtype="<f4")


def plural(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"
