"""Tone-mapped PNG previews of EXR channels and 2-D slices of HDF5 tables.

Tone mapping: multiply by 2**exposure (or, with ``normalize``, map the finite
min..max to 0..1), clamp to [0, 1], apply the sRGB transfer curve, quantise to
8 bits.  NaN shows black, +Inf white.  The PNG encoder is the few lines of zlib
the format needs, so no imaging dependency is pulled in.
"""

from __future__ import annotations

import os
import re
import struct
import zlib
from pathlib import Path

import h5py
import numpy as np

from .. import errors
from ..atomic import atomic_write_bytes
from .exr import read_exr
from .h5 import data_fault, layout, open_table


def encode_png(pixels: np.ndarray) -> bytes:
    """PNG bytes of an 8-bit grey (h, w) or RGB (h, w, 3) image."""
    pixels = np.ascontiguousarray(pixels, dtype=np.uint8)
    if pixels.ndim == 2:
        colour_type, rows = 0, pixels
    elif pixels.ndim == 3 and pixels.shape[2] == 3:
        colour_type, rows = 2, pixels.reshape(pixels.shape[0], -1)
    else:
        raise errors.ValidationError("pixels.shape", pixels.shape, "need (h, w) or (h, w, 3)")
    h, w = pixels.shape[:2]
    raw = np.concatenate([np.zeros((h, 1), np.uint8), rows], axis=1).tobytes()  # filter 0 per row

    def chunk(tag: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + tag + body + struct.pack(">I", zlib.crc32(tag + body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, 8, colour_type, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")


def tonemap(values: np.ndarray, exposure: float = 0.0, normalize: bool = False) -> np.ndarray:
    """Linear float image → 8-bit sRGB (same shape)."""
    v = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(v)
    if normalize:
        lo, hi = (float(v[finite].min()), float(v[finite].max())) if finite.any() else (0.0, 1.0)
        v = (v - lo) / (hi - lo) if hi > lo else np.where(finite, 0.5, v)
    else:
        v = v * 2.0**exposure
    v = np.where(np.isnan(v), 0.0, np.clip(v, 0.0, 1.0))
    srgb = np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)
    return np.round(srgb * 255.0).astype(np.uint8)


def parse_slice(text: str, ndim: int) -> tuple:
    """Parse a NumPy-style index such as ``"0,:,:"`` or ``"2,1:5,:"`` (missing trailing dims are ``:``)."""
    items = [] if not text.strip() else [s.strip() for s in text.split(",")]
    if len(items) > ndim:
        raise errors.ValidationError("slice", text, f"the dataset has {ndim} dimensions")
    out = []
    for item in items:
        if re.fullmatch(r"-?\d+", item):
            out.append(int(item))
        elif m := re.fullmatch(r"(-?\d*):(-?\d*)(?::(-?\d+))?", item):
            start, stop, step = (int(g) if g else None for g in m.groups())
            if step == 0:
                raise errors.ValidationError("slice", text, "a step cannot be 0")
            out.append(slice(start, stop, step))
        else:
            raise errors.ValidationError("slice", text, "use integers and start:stop[:step], separated by commas")
    return tuple(out) + (slice(None),) * (ndim - len(out))


def _pick_channels(image, channel: str | None, part: str | None) -> list[np.ndarray]:
    p = image.part(part)
    names = p.channels
    prefix = "" if channel is None else channel + "."
    if channel is not None and channel in names:
        return [names[channel]]
    rgb = [prefix + c for c in "RGB"]
    if all(c in names for c in rgb):
        return [names[c] for c in rgb]
    if prefix + "Y" in names:
        return [names[prefix + "Y"]]
    if channel is None and len(names) == 1:
        return list(names.values())
    raise errors.MissingDatasetError(
        image.path, f"no channel or layer {channel!r} to preview in part {p.name!r} (channels: {', '.join(sorted(names))})"
    )


def preview(
    path: str | os.PathLike,
    out_png: str | os.PathLike,
    *,
    channel: str | None = None,
    part: str | None = None,
    dataset: str | None = None,
    index: str = "",
    exposure: float = 0.0,
    normalize: bool = False,
) -> Path:
    """Write a PNG preview of an EXR channel/layer or of a 2-D slice of an HDF5 dataset."""
    from .summary import sniff

    if sniff(path) == "openexr":
        if dataset is not None:
            raise errors.ValidationError("dataset", dataset, "EXR files have channels; use channel=")
        planes = _pick_channels(read_exr(path), channel, part)
        img = planes[0] if len(planes) == 1 else np.stack(planes, axis=-1)
    else:
        with open_table(path) as f:
            if dataset is None:
                raise errors.ValidationError("dataset", None, f"name the dataset to preview in {path}")
            axes, tables = layout(f)
            ds = tables.get(dataset, axes.get(dataset))
            if ds is None and isinstance(f.get(dataset.lstrip("/")), h5py.Dataset):  # its HDF5 path
                ds = f[dataset.lstrip("/")]
            if ds is None:
                raise errors.MissingDatasetError(path, f"no dataset {dataset!r} (tables: {', '.join(tables)})")
            key = parse_slice(index, ds.ndim)
            try:
                img = np.asarray(ds[key])
            except OSError as exc:
                raise data_fault(path, ds, exc) from None
            except (IndexError, ValueError) as exc:
                raise errors.ValidationError("slice", index, f"{exc} for shape {ds.shape}") from None
        if img.ndim == 1:
            img = img[None, :]
        if img.ndim != 2:
            raise errors.ValidationError("slice", index, f"gives shape {img.shape}; a preview needs 2-D")
    return atomic_write_bytes(out_png, encode_png(tonemap(img, exposure, normalize)))
