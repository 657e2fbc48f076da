"""Strand-render frames kept in the table cache, content-addressed like the tables.

A strand-render frame at a fixed level is a pure function of the scene (its resolved tables and its strands' geometry:
the groom file's bytes and fit, or the clusters), the camera, the levels and the code that renders it.  A warm ``hairlut demo``
used to render the same frames every run (about 25 s on the 2-core CPU); :func:`cached_frame` stores each one as
``strands-<first 16 hex of its key>.exr`` in the table cache folder (``hairlut.bake.cache.cache_dir``: ``--cache``,
``$HAIRLUT_CACHE`` or ``tables/``), written atomically through :func:`write_frame`, and returns it again while the
key matches.

The key is the SHA-256 of all of that: the scene's record (:func:`scene_record`), the caller's record (camera,
levels, sizes), the hairlut version with a hash of every hairlut source file (any code change renders afresh), and
the JAX version and backend (a GPU's float32 bits differ from a CPU's).  An entry is trusted only when it reads as
a ``render_frame`` whose pixel checksum verifies and whose stored key is the full key asked for; an entry that is
not (damaged, foreign, a FIFO, a folder) is left where it is, never deleted or overwritten, and the frame is
rendered without the cache, with a warning naming the file.  A cache folder that cannot be written costs the
cache, not the frame.  The returned frame's ``info["cache"]`` says ``reused`` or ``rendered``, the file and the
key; its ``seconds`` stay those of the run that rendered it.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
from collections.abc import Callable
from pathlib import Path

from .. import errors
from ._frame import KIND, Frame, read_frame, write_frame

log = logging.getLogger(__name__)

PREFIX = "strands-"


@functools.lru_cache(maxsize=1)
def code_record() -> dict:
    """The hairlut version, a SHA-256 over every source file of the package, and JAX's version and backend."""
    import jax

    from .. import __version__

    root = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return {"hairlut": __version__, "sources": h.hexdigest(), "jax": jax.__version__, "backend": jax.default_backend()}


def scene_record(scene) -> dict:
    """What of a :class:`~hairlut.scene.Scene` determines its strand-render frames: the resolved tables (lights,
    material, effects, shadows, camera, the HRIR recipe's extinction) and its strands' identity
    (:func:`hairlut.scenemaps.geometry_key`: the groom file's bytes and fit, or the clusters and strand settings)."""
    from ..scenemaps import geometry_key

    return {"config": scene.config, "geometry": geometry_key(scene)}


def _plain(x):
    if hasattr(x, "tolist"):
        return x.tolist()
    if isinstance(x, os.PathLike):
        return os.fspath(x)
    raise TypeError(f"cannot key a {type(x).__name__}")


def frame_key(scene, record: dict) -> str:
    """The SHA-256 (hex) of the scene's record, ``record`` and :func:`code_record`."""
    text = json.dumps(
        {"scene": scene_record(scene), "frame": record, "code": code_record()},
        sort_keys=True,
        separators=(",", ":"),
        default=_plain,
    )  # Infinity (k_threshold = inf) is keyed as the token
    return hashlib.sha256(text.encode()).hexdigest()


def frame_path(key: str, root=None) -> Path:
    from ..bake.cache import cache_dir

    return cache_dir(root) / f"{PREFIX}{key[:16]}.exr"


def _stored(path: Path, key: str) -> Frame | None:
    """The frame at ``path`` when it is a hairlut frame of ``key`` whose checksum verifies; None when nothing is there;
    raises AssetError naming what is wrong with anything else."""
    from ..assets import read_exr

    if not os.path.lexists(path):
        return None
    img = read_exr(path, kind=KIND)  # a regular file (else FormatError), kind, recipe hash and pixel checksum checked
    if img.checksum != "verified":
        raise errors.CorruptAssetError(path, f"no pixel checksum ({img.checksum})")
    if (img.recipe or {}).get("cache_key") != key:
        raise errors.CorruptAssetError(path, "holds another frame (its cache_key differs)")
    frame = read_frame(path)
    frame.info.pop("cache_key", None)
    return frame


def cached_frame(scene, record: dict, render: Callable[[], Frame], root=None) -> Frame:
    """The frame of ``scene`` that ``render()`` makes, described by ``record`` (module docstring): from the cache
    under ``root`` when it holds it, else rendered and stored there."""
    key = frame_key(scene, record)
    path = frame_path(key, root)
    try:
        frame = _stored(path, key)
    except errors.AssetError as exc:
        log.warning("not using or replacing %s (%s); the frame is rendered afresh", path, exc.fault)
        frame = render()
        frame.info["cache"] = {"status": "rendered", "path": None, "key": key}
        return frame
    if frame is not None:
        frame.info["cache"] = {"status": "reused", "path": str(path), "key": key}
        return frame
    frame = render()
    try:
        write_frame(Frame(frame.rgba, frame.depth, frame.camera, {**frame.info, "cache_key": key}), path)
        stored = str(path)
    except (errors.HairlutError, OSError) as exc:  # a read-only or full cache folder costs the cache, not the frame
        log.warning("cannot keep the strand-render frame in the cache (%s)", exc)
        stored = None
    frame.info["cache"] = {"status": "rendered", "path": stored, "key": key}
    return frame


def strands_frame(scene, camera, *, levels, root=None, strands=None) -> Frame:
    """:func:`~hairlut.render.render_strands` of ``scene`` through ``camera`` at exactly ``levels``, through
    :func:`cached_frame` (the camera's record and the levels are the frame's record)."""
    from ._render import render_strands

    return cached_frame(
        scene,
        {"what": "strands", "camera": camera.to_json(), "levels": list(levels)},
        lambda: render_strands(scene, camera, levels=list(levels), strands=strands),
        root,
    )
