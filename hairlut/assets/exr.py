"""OpenEXR images through the official binding (``OpenEXR`` 3.x).

Conventions (DESIGN.md): float32 or half pixels; ZIP (default) or PIZ
compression; channels ``R,G,B,A``, ``Y`` or ``<layer>.<channel>``; several parts
when the images differ in size.  Metadata are strings, because the binding
mangles int and float header values:

``hairlut:recipe``         canonical JSON of the recipe
``hairlut:recipe_hash``    its SHA-256
``hairlut:kind``           what the image holds
``hairlut:version``        the hairlut version that wrote it
``hairlut:sha256``         SHA-256 over the entries above and every part's channels
                           (EXR has no checksum of its own; PIZ has no integrity check)
``hairlut:<name>``         any further string attribute a writer adds (``attributes=``, e.g. a frame's
                           ``hairlut:camera`` JSON); covered by the checksum, read back in ``ExrImage.attributes``
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import re
import sys
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import OpenEXR

from .. import errors
from .._version import __version__
from ..atomic import FULL_ERRNOS, atomic_path
from .h5 import check_file
from .recipe import canonical_json, recipe_hash

EXR_MAGIC = b"\x76\x2f\x31\x01"
COMPRESSIONS = {"zip": OpenEXR.ZIP_COMPRESSION, "piz": OpenEXR.PIZ_COMPRESSION}
PIXEL_TYPES = {"float32": np.float32, "half": np.float16}
_CHANNEL = re.compile(r"^[A-Za-z0-9_]+(\.[A-Za-z0-9_]+)*$")
SHA_KEY = "hairlut:sha256"
_RESERVED = frozenset({"hairlut:version", "hairlut:recipe", "hairlut:recipe_hash", "hairlut:kind", SHA_KEY})


@dataclass
class ExrPart:
    """One part of an EXR file: equally sized 2-D channels, keyed by name."""

    name: str
    channels: dict[str, np.ndarray]
    header: dict = field(default_factory=dict)  # filled on read (stringified)

    @property
    def shape(self) -> tuple[int, int]:
        return next(iter(self.channels.values())).shape if self.channels else (0, 0)


@dataclass
class ExrImage:
    """An EXR file as :func:`read_exr` returns it, validated: its ``parts`` (one :class:`ExrPart` each, in file
    order), the ``recipe``, ``recipe_hash`` and ``kind`` hairlut wrote (``None`` for another writer's file),
    ``checksum`` (``"verified"``, or why there is nothing to verify) and the further ``hairlut:<name>``
    ``attributes``.  ``part(name)``, ``part_with(channels)`` and ``channel(name, part)`` find what a reader needs."""

    path: Path
    parts: list[ExrPart]
    recipe: dict | None
    recipe_hash: str | None
    kind: str | None
    checksum: str  # "verified", or why there is nothing to verify
    attributes: dict = field(default_factory=dict)  # the further hairlut:<name> string attributes

    def part(self, name: str | None = None) -> ExrPart:
        """The part called ``name`` (the first part when None); a missing part is a
        :class:`hairlut.errors.MissingDatasetError`."""
        if name is None:
            return self.parts[0]
        for p in self.parts:
            if p.name == name:
                return p
        raise errors.MissingDatasetError(self.path, f"no part named {name!r} (parts: {[p.name for p in self.parts]})")

    def part_with(self, channels) -> ExrPart:
        """The one part holding every one of ``channels`` (names), whichever its place in the file: a reader that
        needs a frame's R, G, B and A finds them in a multi-part file too.  A MissingDatasetError when no part holds
        them all, a FormatError naming the parts when several do (which one is meant is ambiguous)."""
        want = list(channels)
        found = [p for p in self.parts if all(c in p.channels for c in want)]
        if len(found) == 1:
            return found[0]
        if not found:
            have = {p.name or f"part {i}": sorted(p.channels) for i, p in enumerate(self.parts)}
            raise errors.MissingDatasetError(
                self.path, f"no part has channels {', '.join(want)} ({len(self.parts)} part(s): {have})"
            )
        raise errors.FormatError(
            self.path,
            f"{len(found)} of its {len(self.parts)} parts hold channels {', '.join(want)} "
            f"({', '.join(repr(p.name) for p in found)}): which one is meant is ambiguous",
        )

    def channel(self, name: str, part: str | None = None) -> np.ndarray:
        """The pixels of channel ``name`` (e.g. ``layer0.A``) of a part, as a (height, width) array."""
        p = self.part(part)
        if name not in p.channels:
            raise errors.MissingDatasetError(
                self.path, f"no channel {name!r} in part {p.name!r} (channels: {sorted(p.channels)})"
            )
        return p.channels[name]


def _content_sha256(parts: Sequence[ExrPart], meta: Mapping[str, str]) -> str:
    """SHA-256 over the hairlut metadata and every part's name, channels and pixels."""
    h = hashlib.sha256()
    for key in sorted(meta):
        if key != SHA_KEY:
            h.update(f"{key}={meta[key]}\n".encode())
    for part in parts:
        h.update(f"part:{part.name if len(parts) > 1 else ''}\n".encode())
        for name in sorted(part.channels):
            arr = np.ascontiguousarray(part.channels[name])
            little = arr.dtype.newbyteorder("<")
            h.update(f"{name}:{little.str}:{arr.shape}\n".encode())
            h.update(arr.astype(little, copy=False).tobytes())
    return h.hexdigest()


def _as_parts(image) -> list[ExrPart]:
    if isinstance(image, Mapping):
        return [ExrPart("", dict(image))]
    parts = list(image)
    if not parts or not all(isinstance(p, ExrPart) for p in parts):
        raise errors.ValidationError("image", type(image).__name__, "give a mapping of channels or a list of ExrPart")
    return parts


def _prepare(parts: list[ExrPart], pixel_type: str | None) -> list[ExrPart]:
    if pixel_type is not None and pixel_type not in PIXEL_TYPES:
        raise errors.ValidationError("pixel_type", pixel_type, f"use one of {sorted(PIXEL_TYPES)}")
    names = [p.name for p in parts]
    if len(parts) > 1 and (len(set(names)) != len(names) or not all(names)):
        raise errors.ValidationError("parts.name", names, "parts of a multi-part file need distinct, non-empty names")
    out = []
    for part in parts:
        if not part.channels:
            raise errors.ValidationError(f"parts[{part.name!r}].channels", {}, "a part needs at least one channel")
        shape = None
        channels = {}
        for name, arr in part.channels.items():
            field_name = f"channels[{name!r}]"
            if not isinstance(name, str) or not _CHANNEL.match(name):
                raise errors.ValidationError(field_name, name, "channel names are R,G,B,A, Y or <layer>.<channel>")
            arr = np.asarray(arr)
            if arr.ndim != 2 or 0 in arr.shape:
                raise errors.ValidationError(f"{field_name}.shape", arr.shape, "a channel is a non-empty 2-D array")
            if not np.issubdtype(arr.dtype, np.floating):
                raise errors.ValidationError(f"{field_name}.dtype", str(arr.dtype), "EXR channels here are float32 or half")
            if shape is not None and arr.shape != shape:
                raise errors.ValidationError(
                    f"{field_name}.shape", arr.shape, f"other channels of this part are {shape}; use parts"
                )
            shape = arr.shape
            target = PIXEL_TYPES[pixel_type] if pixel_type else (np.float16 if arr.dtype == np.float16 else np.float32)
            channels[name] = np.ascontiguousarray(arr, dtype=target)
        out.append(ExrPart(part.name, channels))
    return out


def write_exr(
    path: str | os.PathLike,
    image: Mapping[str, np.ndarray] | Sequence[ExrPart],
    *,
    recipe: Mapping | None = None,
    kind: str | None = None,
    compression: str = "zip",
    pixel_type: str | None = None,
    attributes: Mapping[str, str] | None = None,
) -> Path:
    """Write an EXR atomically.

    ``image`` is a mapping of channel name to 2-D array (one part) or a list of
    :class:`ExrPart` (multi-part, for images of different sizes).  Float64 input
    is stored as float32 unless ``pixel_type="half"``; float16 stays half.
    ``attributes``: further header strings (JSON text, say), each named ``hairlut:<name>``
    other than the reserved names above; covered by the checksum.
    """
    if compression not in COMPRESSIONS:
        raise errors.ValidationError("compression", compression, f"lossless only: {sorted(COMPRESSIONS)}")
    parts = _prepare(_as_parts(image), pixel_type)
    meta = {"hairlut:version": __version__}
    for key, value in (attributes or {}).items():
        if not (isinstance(key, str) and key.startswith("hairlut:") and len(key) > 8) or key in _RESERVED:
            raise errors.ValidationError("attributes", key, f"names are hairlut:<name>, not one of {sorted(_RESERVED)}")
        if not isinstance(value, str):
            raise errors.ValidationError(f"attributes[{key!r}]", type(value).__name__, "values are strings (JSON text)")
        meta[key] = value
    if recipe is not None:
        text = canonical_json(recipe)
        meta.update({"hairlut:recipe": text, "hairlut:recipe_hash": recipe_hash(text)})
    if kind is not None:
        meta["hairlut:kind"] = str(kind)
    meta[SHA_KEY] = _content_sha256(parts, meta)
    height = max(p.shape[0] for p in parts)
    width = max(p.shape[1] for p in parts)
    display = (np.array([0, 0], np.int32), np.array([width - 1, height - 1], np.int32))
    headers = []
    for part in parts:
        h, w = part.shape
        headers.append(
            {
                "compression": COMPRESSIONS[compression],
                "type": OpenEXR.scanlineimage,
                "displayWindow": display,
                "dataWindow": (np.array([0, 0], np.int32), np.array([w - 1, h - 1], np.int32)),
                **meta,
            }
        )
    with atomic_path(path) as tmp:
        if len(parts) == 1:
            exr = OpenEXR.File(headers[0], parts[0].channels)
        else:
            exr = OpenEXR.File([OpenEXR.Part(hd, p.channels, p.name) for hd, p in zip(headers, parts)])
        try:
            exr.write(str(tmp))
        except (RuntimeError, OSError) as exc:  # the binding reports a full disk as RuntimeError
            raise _write_fault(path, exc) from None
    return Path(path)


def _write_fault(path, exc: Exception) -> errors.AssetError:
    """The hairlut error for an EXR write that failed with ``exc`` (DiskFullError for a full disk)."""
    msg = str(exc)
    code = getattr(exc, "errno", None)
    if code in FULL_ERRNOS or "No space left" in msg or "File too large" in msg or "quota" in msg.lower():
        return errors.DiskFullError(
            path, f"cannot write the image: {msg.splitlines()[0] if msg else 'disk full'}; nothing was left under this name"
        )
    return errors.AssetError(path, f"cannot write the image ({msg.splitlines()[0] if msg else type(exc).__name__})")


@contextlib.contextmanager
def _captured_stderr():
    """Capture what the C++ library prints on fds 1 and 2, so the CLI stays one line."""
    with tempfile.TemporaryFile(mode="w+b") as sink:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        saved = [os.dup(1), os.dup(2)]
        os.dup2(sink.fileno(), 1)
        os.dup2(sink.fileno(), 2)
        lines: list[str] = []
        python_side = io.StringIO()
        try:
            with contextlib.redirect_stdout(python_side), contextlib.redirect_stderr(python_side):
                yield lines
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            text = python_side.getvalue() + sink.read().decode("utf-8", "replace")
            lines.extend(line.strip() for line in text.splitlines() if line.strip())


def _header_value(value) -> str | float | int | list:
    if isinstance(value, (str, int, float)):
        return value
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (tuple, list)):
        return [_header_value(v) for v in value]
    return str(value)


def read_exr(path: str | os.PathLike, kind: str | None = None, header_only: bool = False) -> ExrImage:
    """Read and validate an EXR file (any writer's; multi-part, layered, half or float).

    Raises a :mod:`hairlut.errors` exception naming the file and the fault.  If
    hairlut wrote the file, the pixel checksum and the recipe hash are verified.
    """
    path = check_file(path, EXR_MAGIC, "an OpenEXR file")
    with _captured_stderr() as noise:
        try:
            exr = OpenEXR.File(str(path), separate_channels=True, header_only=header_only)
            raw_parts = list(exr.parts)
            if not raw_parts:
                raise ValueError("file has 0 parts")
            parts = []
            for i, p in enumerate(raw_parts):
                channels = {} if header_only else {name: ch.pixels for name, ch in p.channels.items()}
                if any(v is None for v in channels.values()):
                    raise ValueError("deep or unreadable channel data")
                header = {k: _header_value(v) for k, v in p.header.items() if k != "channels"}
                parts.append(ExrPart(p.name() or (f"part{i}" if len(raw_parts) > 1 else ""), channels, header))
        except (RuntimeError, ValueError, TypeError) as exc:
            err = exc
        else:
            err = None
    if err is not None:
        detail = next((line for line in noise if "EXR_ERR" in line), None) or (noise[0] if noise else str(err))
        detail = re.sub(r"^.*?: \(", "(", detail)
        if "BAD_CHUNK_LEADER" in detail or "scanline information" in str(err) + detail or "Unable to open" in str(err):
            raise errors.TruncatedAssetError(path, f"truncated or damaged EXR ({detail})")
        raise errors.CorruptAssetError(path, f"EXR data cannot be decoded ({detail})")
    header = parts[0].header
    meta = {k: str(v) for k, v in header.items() if k.startswith("hairlut:")}
    for p in parts[1:]:
        if {k: str(v) for k, v in p.header.items() if k.startswith("hairlut:")} != meta:
            raise errors.ChecksumError(path, f"hairlut metadata of part {p.name!r} differs from the first part's")
    recipe_text = header.get("hairlut:recipe")
    stored_hash = header.get("hairlut:recipe_hash")
    file_kind = header.get("hairlut:kind")
    if kind is not None and file_kind != kind:
        raise errors.KindError(path, f"holds kind {file_kind!r}, expected {kind!r}")
    recipe = None
    if recipe_text is not None:
        if recipe_hash(recipe_text) != stored_hash:
            raise errors.ChecksumError(path, "hairlut:recipe_hash does not match hairlut:recipe")
        recipe = json.loads(recipe_text)
    checksum = "not written by hairlut: no checksum"
    stored = header.get(SHA_KEY)
    if header_only:
        checksum = "header only: not verified"
    elif stored is not None:
        if _content_sha256(parts, meta) != stored:
            raise errors.ChecksumError(path, f"metadata or pixels fail their {SHA_KEY} checksum")
        checksum = "verified"
    extra = {k: v for k, v in meta.items() if k not in _RESERVED}
    return ExrImage(path, parts, recipe, stored_hash, file_kind, checksum, extra)
