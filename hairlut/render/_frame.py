"""A rendered frame and its EXR: ``R, G, B, A`` (premultiplied, linear) and ``Z`` (eye depth), the camera
as metadata.

The camera travels in the EXR header attribute ``hairlut:camera`` (JSON, ``Camera.to_json``: the 4 × 4
``world_to_clip`` matrix, ``resolution`` and ``projection``, plus the eye and axes), so any EXR tool can
reproduce the projection; the ``hairlut:recipe`` JSON holds the same record under ``camera`` beside the
frame's ``method``, ``seconds`` and, for the strand render, its convergence record; the asset kind is
``render_frame``.  ``Z`` is 1e10 where nothing was drawn (A = 0).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import errors
from ..assets import atomic_write_bytes, encode_png, read_exr, tonemap, write_exr

KIND = "render_frame"
#: The EXR header attribute holding the camera (JSON).
CAMERA_KEY = "hairlut:camera"


@dataclass(frozen=True, eq=False)
class Frame:
    """``rgba`` (h, w, 4) premultiplied linear RGB and α, ``depth`` (h, w), the ``camera``
    (:class:`~hairlut.scene.Camera`) and ``info`` (method, seconds, convergence…)."""

    rgba: np.ndarray
    depth: np.ndarray
    camera: object
    info: dict = field(default_factory=dict)


def _plain(x):
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, float) and not np.isfinite(x):
        return str(x)
    return x


def write_frame(frame: Frame, path, png: bool = False) -> dict:
    """Write ``path`` (EXR, channels R, G, B, A, Z) and, with ``png``, a PNG beside it (over black)."""
    if not (np.isfinite(frame.rgba).all() and np.isfinite(frame.depth).all()):
        raise errors.ValidationError("frame", "non-finite", "a frame's pixels must be finite")
    ch = {c: frame.rgba[..., i].astype(np.float32) for i, c in enumerate("RGBA")}
    ch["Z"] = frame.depth.astype(np.float32)
    recipe = _plain({"camera": frame.camera.to_json(), **frame.info})
    attrs = {CAMERA_KEY: json.dumps(recipe["camera"], sort_keys=True)}
    out = {"exr": str(write_exr(path, ch, recipe=recipe, kind=KIND, attributes=attrs))}
    if png:
        p = Path(path).with_suffix(".png")
        atomic_write_bytes(p, encode_png(tonemap(frame.rgba[..., :3])))
        out["png"] = str(p)
    return out


def read_frame(path) -> Frame:
    """A frame back from its EXR (any EXR with R, G, B and A in one part reads, multi-part too; the camera only
    from a hairlut frame)."""
    from ..scene import Camera

    img = read_exr(path)
    part = img.part_with("RGBA")
    rgba = np.stack([np.asarray(part.channels[c], np.float32) for c in "RGBA"], -1)
    depth = np.asarray(part.channels["Z"], np.float32) if "Z" in part.channels else np.zeros(rgba.shape[:2], np.float32)
    rec = img.recipe if isinstance(img.recipe, dict) else {}
    if CAMERA_KEY in img.attributes:
        try:
            record = json.loads(img.attributes[CAMERA_KEY])
        except ValueError as exc:  # JSONDecodeError
            raise errors.CorruptAssetError(path, f"{CAMERA_KEY} is not JSON ({exc})") from None
    else:
        record = rec.get("camera")
    try:
        cam = None if record is None else Camera.from_json(record)
    except errors.ValidationError as exc:
        raise errors.CorruptAssetError(path, str(exc)) from None
    if cam is not None and (cam.height, cam.width) != rgba.shape[:2]:
        raise errors.CorruptAssetError(
            path, f"{CAMERA_KEY}.resolution=[{cam.width}, {cam.height}]: the image is {rgba.shape[1]} x {rgba.shape[0]} pixels"
        )
    return Frame(rgba, depth, cam, {k: v for k, v in rec.items() if k != "camera"})
