"""Cem Yuksel's ``.hair`` files (binary, little-endian).

A 128-byte header (``b"HAIR"``, strand count, point count, array flags,
default segment count, default thickness, transparency and colour, 88 bytes of
free text) is followed by whichever arrays its flags announce, in this order:
segments ``uint16[strands]``, points ``float32[points][3]``, thickness
``float32[points]``, transparency ``float32[points]``, colour
``float32[points][3]``.  A strand with ``s`` segments has ``s + 1`` points.

Reading fills every attribute the file leaves out from the header defaults, so
a ``.hair`` file always yields thickness, transparency and colour.  Writing
stores an attribute that is constant over all points as the header default
(no array), an absent one as the format's defaults (thickness 1, transparency
0, colour white), and drops ``uv`` and ``movable``, which the format has no
place for.
"""

from __future__ import annotations

import logging
import os
import struct

import numpy as np

from .._version import __version__
from ..atomic import atomic_path
from ..errors import CorruptAssetError, FormatError, TruncatedAssetError, ValidationError
from ._binio import as_f32, build, plural, read_bytes
from .strands import Strands

log = logging.getLogger(__name__)

MAGIC = b"HAIR"
HEADER = struct.Struct("<4s4I5f88s")  # 128 bytes
SEGMENTS, POINTS, THICKNESS, TRANSPARENCY, COLOR = 1, 2, 4, 8, 16
DEFAULTS = {"thickness": 1.0, "transparency": 0.0, "color": (1.0, 1.0, 1.0)}
# (flag, name, bytes per item, item count from "strands" or "points", trailing shape)
_ARRAYS = (
    (SEGMENTS, "segments", 2, "strands", ()),
    (POINTS, "points", 12, "points", (3,)),
    (THICKNESS, "thickness", 4, "points", ()),
    (TRANSPARENCY, "transparency", 4, "points", ()),
    (COLOR, "color", 12, "points", (3,)),
)
_KNOWN_FLAGS = SEGMENTS | POINTS | THICKNESS | TRANSPARENCY | COLOR


def _header(path, data: bytes) -> dict:
    if not MAGIC.startswith(data[:4]):
        raise FormatError(path, f"not a .hair file: starts with {data[:4]!r}, expected {MAGIC!r}")
    if len(data) < HEADER.size:
        raise TruncatedAssetError(path, f"a .hair header is {HEADER.size} bytes, file has {len(data)} bytes")
    _, n_strands, n_points, flags, d_segments, d_thick, d_transp, r, g, b, _ = HEADER.unpack_from(data)
    if flags & ~_KNOWN_FLAGS:
        raise CorruptAssetError(path, f"header flags 0x{flags:x} set unknown bits 0x{flags & ~_KNOWN_FLAGS:x}")
    if not flags & POINTS:
        raise CorruptAssetError(path, f"header flags 0x{flags:x} lack the points array (bit 2), which the format requires")
    return {
        "strands": n_strands,
        "points": n_points,
        "flags": flags,
        "segments": d_segments,
        "thickness": d_thick,
        "transparency": d_transp,
        "color": (r, g, b),
    }


def read_hair(path: str | os.PathLike) -> Strands:
    """Read a ``.hair`` file; absent arrays are filled from the header defaults."""
    data = read_bytes(path)
    head = _header(path, data)
    sizes = {"strands": head["strands"], "points": head["points"]}
    present = [(name, size, sizes[unit], tail) for flag, name, size, unit, tail in _ARRAYS if head["flags"] & flag]
    need = HEADER.size + sum(size * n for _, size, n, _ in present)
    if need > len(data):
        parts = ", ".join(f"{name} ({size * n} bytes)" for name, size, n, _ in present)
        raise TruncatedAssetError(
            path,
            f"header says {plural(head['strands'], 'strand')} and {plural(head['points'], 'point')}: "
            f"{HEADER.size}-byte header + {parts} = {need} bytes, file has {len(data)} bytes",
        )
    if need < len(data):
        log.warning("%s: ignoring %d bytes after the last array", os.fspath(path), len(data) - need)
    arrays, offset = {}, HEADER.size
    for name, size, n, tail in present:
        dtype = "<u2" if name == "segments" else "<f4"
        count = n * (size // np.dtype(dtype).itemsize)
        arrays[name] = np.frombuffer(data, dtype=dtype, count=count, offset=offset).reshape((n,) + tail)
        offset += size * n
    n_strands, n_points = head["strands"], head["points"]
    if "segments" in arrays:
        counts = arrays["segments"].astype(np.int64) + 1
        if int(counts.sum()) != n_points:
            raise CorruptAssetError(path, f"segments array implies {int(counts.sum())} points, header says {n_points}")
    else:
        per = head["segments"] + 1
        if n_strands * per != n_points:
            raise CorruptAssetError(
                path,
                f"header says {plural(n_strands, 'strand')} × {head['segments']} default segments "
                f"= {n_strands * per} points, but {n_points} points",
            )
        counts = np.full(n_strands, per, dtype=np.int64)
    fields = {"points": arrays["points"].astype(np.float32), "counts": counts}
    for name in ("thickness", "transparency", "color"):
        if name in arrays:
            fields[name] = arrays[name].astype(np.float32)
        else:
            default = np.asarray(head[name], dtype=np.float32)
            fields[name] = np.broadcast_to(default, (n_points,) + default.shape).copy()
    return build(path, **fields)


def _default_or_array(name: str, values: np.ndarray | None) -> tuple[np.ndarray | None, object]:
    """(array to store or None, header default) for one per-point attribute."""
    if values is None:
        return None, DEFAULTS[name]
    arr = as_f32(name, values)
    if len(arr) and (arr == arr[0]).all():
        return None, arr[0].tolist()
    return arr, DEFAULTS[name]


def hair_bytes(strands: Strands, note: str = "") -> bytes:
    """The complete ``.hair`` file for ``strands``; ``note`` goes into the 88-byte free-text field."""
    counts = strands.counts
    segments = counts - 1
    if strands.n_strands and segments.max() > 0xFFFF:
        raise ValidationError("counts", int(counts.max()), f".hair stores at most {0xFFFF + 1} points per strand")
    flags = POINTS
    uniform = strands.n_strands == 0 or (segments == segments[0]).all()
    d_segments = int(segments[0]) if strands.n_strands else 1
    parts = []
    if not uniform:
        flags |= SEGMENTS
        parts.append(segments.astype("<u2").tobytes())
    parts.append(as_f32("points", strands.points).tobytes())
    defaults = {}
    for flag, name in ((THICKNESS, "thickness"), (TRANSPARENCY, "transparency"), (COLOR, "color")):
        arr, defaults[name] = _default_or_array(name, getattr(strands, name))
        if arr is not None:
            flags |= flag
            parts.append(arr.tobytes())
    text = (note or f"hairlut {__version__}").encode("utf-8")[:88]
    header = HEADER.pack(
        MAGIC,
        strands.n_strands,
        strands.n_points,
        flags,
        d_segments,
        defaults["thickness"],
        defaults["transparency"],
        *defaults["color"],
        text,
    )
    return header + b"".join(parts)


def write_hair(path: str | os.PathLike, strands: Strands) -> None:
    """Write ``strands`` as a ``.hair`` file, atomically (see the module docstring for what is kept)."""
    payload = hair_bytes(strands)
    with atomic_path(path) as tmp:
        tmp.write_bytes(payload)
