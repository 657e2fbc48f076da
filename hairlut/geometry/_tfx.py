"""AMD TressFX ``.tfx`` files (binary, little-endian, version 4.0 layout).

A 160-byte header (version, strand count, vertices per strand, then byte
offsets of the arrays, then 32 reserved words) is followed by the vertex
positions ``float32[strands][vertices][4]`` and, optionally, per-strand UVs
``float32[strands][2]``.  Every strand has the same number of vertices.

The fourth vertex component is not a coordinate: TressFX uses it as a
"movable" flag (0 at pinned vertices).  It is kept as ``Strands.movable``
(``w != 0``) and written back from it; without ``movable`` the writer pins the
root vertex of each strand and nothing else.

The header can also point at per-vertex UVs, per-strand thickness and
per-vertex colours; TressFX itself never reads them and their layout is not
specified, so the reader skips them (logging a warning) and the writer leaves
their offsets 0.  Per-point thickness, transparency and colour are therefore
not stored in ``.tfx`` files.
"""

from __future__ import annotations

import logging
import os
import struct

import numpy as np

from ..atomic import atomic_path
from ..errors import CorruptAssetError, FormatError, TruncatedAssetError, ValidationError
from ._binio import as_f32, build, plural, read_bytes
from .strands import Strands

log = logging.getLogger(__name__)

HEADER = struct.Struct("<f7I32I")  # 160 bytes
VERSION = 4.0
_FIELDS = ("version", "strands", "vertices", "positions", "strand_uv", "vertex_uv", "strand_thickness", "vertex_color")
_UNREAD = {"vertex_uv": "per-vertex UVs", "strand_thickness": "per-strand thickness", "vertex_color": "per-vertex colours"}


def _header(path, data: bytes) -> dict:
    if len(data) >= 4:
        (version,) = struct.unpack_from("<f", data)
        if not (np.isfinite(version) and 0.0 < version < 100.0):
            raise FormatError(
                path,
                f"not a TressFX file: first 4 bytes {data[:4]!r} are not a plausible "
                f"version number (read {version:g} as float32)",
            )
    if len(data) < HEADER.size:
        raise TruncatedAssetError(path, f"a .tfx header is {HEADER.size} bytes, file has {len(data)} bytes")
    head = dict(zip(_FIELDS, HEADER.unpack_from(data)[: len(_FIELDS)]))
    if head["vertices"] < 2:
        raise CorruptAssetError(path, f"header says {plural(head['vertices'], 'vertex')} per strand; a strand needs at least 2")
    for key in ("positions", "strand_uv"):
        if key == "positions" or head[key]:
            if head[key] < HEADER.size:
                raise CorruptAssetError(
                    path, f"header puts the {key.replace('_', ' ')} at offset {head[key]}, inside the {HEADER.size}-byte header"
                )
    return head


def _check_extent(path, data: bytes, offset: int, nbytes: int, what: str) -> None:
    end = offset + nbytes
    if end > len(data):
        raise TruncatedAssetError(
            path, f"header says {what} at offset {offset} = {nbytes} bytes (ending at byte {end}), file has {len(data)} bytes"
        )


def read_tfx(path: str | os.PathLike) -> Strands:
    """Read a TressFX ``.tfx`` file; see the module docstring for what is kept."""
    data = read_bytes(path)
    head = _header(path, data)
    n_strands, n_vert = head["strands"], head["vertices"]
    shape = f"{n_strands} strands × {n_vert} vertices × 16 bytes"
    _check_extent(path, data, head["positions"], n_strands * n_vert * 16, shape)
    raw = np.frombuffer(data, dtype="<f4", count=n_strands * n_vert * 4, offset=head["positions"])
    raw = raw.reshape(n_strands * n_vert, 4)
    uv = None
    if head["strand_uv"]:
        _check_extent(path, data, head["strand_uv"], n_strands * 8, f"per-strand UVs for {n_strands} strands × 8 bytes")
        uv = np.frombuffer(data, dtype="<f4", count=n_strands * 2, offset=head["strand_uv"]).reshape(n_strands, 2)
    for key, what in _UNREAD.items():
        if head[key]:
            log.warning("%s: skipping %s at offset %d (layout not specified by TressFX)", os.fspath(path), what, head[key])
    w = raw[:, 3]
    if not np.isfinite(w).all():
        bad = int(np.flatnonzero(~np.isfinite(w))[0])
        raise CorruptAssetError(path, f"vertex {bad % n_vert} of strand {bad // n_vert} has a non-finite w component")
    return build(
        path,
        points=raw[:, :3].astype(np.float32),
        counts=np.full(n_strands, n_vert, dtype=np.int64),
        uv=None if uv is None else uv.astype(np.float32),
        movable=w != 0,
    )


def tfx_bytes(strands: Strands) -> bytes:
    """The complete ``.tfx`` file for ``strands``; raises ``ValidationError`` if TressFX cannot hold them."""
    counts = strands.counts
    if strands.n_strands == 0:
        raise ValidationError("strands", strands, "a .tfx file needs at least one strand")
    n_vert = int(counts[0])
    if (counts != n_vert).any():
        raise ValidationError(
            "counts",
            f"{counts.min()}..{counts.max()} points per strand",
            ".tfx needs the same number of vertices in every strand; resample first",
        )
    if n_vert not in (4, 8, 16, 32, 64):
        raise ValidationError("counts", n_vert, ".tfx needs a power of two from 4 to 64 vertices per strand")
    movable = strands.movable
    if movable is None:
        movable = np.ones(strands.n_points, dtype=bool)
        movable[strands.offsets[:-1]] = False
    vertices = np.empty((strands.n_points, 4), dtype="<f4")
    vertices[:, :3] = as_f32("points", strands.points)
    vertices[:, 3] = movable
    positions = HEADER.size
    uv_offset = positions + vertices.nbytes if strands.uv is not None else 0
    header = HEADER.pack(VERSION, strands.n_strands, n_vert, positions, uv_offset, 0, 0, 0, *([0] * 32))
    parts = [header, vertices.tobytes()]
    if strands.uv is not None:
        parts.append(as_f32("uv", strands.uv).tobytes())
    return b"".join(parts)


def write_tfx(path: str | os.PathLike, strands: Strands) -> None:
    """Write ``strands`` as a TressFX 4.0 ``.tfx`` file, atomically."""
    payload = tfx_bytes(strands)
    with atomic_path(path) as tmp:
        tmp.write_bytes(payload)
