"""The layered model beside the strand render it stands for, through one camera: both frames, the figures of
:func:`compare` and one PNG (layered | strands | FLIP heat map), what ``hairlut demo`` shows."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .. import errors
from ..assets import atomic_write_bytes, encode_png, tonemap
from ._compare import compare
from ._frame import write_frame
from ._frame_cache import strands_frame
from ._layered import render_layered
from ._render import render_strands

GAP = 8


def panels(*images8, gap: int = GAP) -> np.ndarray:
    """8-bit (h, w, 3) images of equal height side by side with black gaps."""
    h = images8[0].shape[0]
    if any(im.shape[0] != h for im in images8):
        raise errors.ValidationError("images", [im.shape for im in images8], "need equal heights")
    out = []
    for i, im in enumerate(images8):
        if i:
            out.append(np.zeros((h, gap, 3), np.uint8))
        out.append(np.asarray(im, np.uint8)[..., :3])
    return np.concatenate(out, axis=1)


def layered_vs_strands(
    scene,
    out_dir,
    *,
    db=None,
    sh=None,
    maps=None,
    level: int | None = None,
    bound: float | None = None,
    max_level: int = 3,
    prepared=None,
    strands_info=None,
    cache=None,
) -> dict:
    """Render ``scene`` with the layered model and with the strand render (converged to ``bound``, or exactly
    ``level`` when given: no convergence claim), write ``layered.exr``, ``strands.exr``, ``flip.png`` and
    ``side_by_side.png`` (layered | strands | FLIP) under ``out_dir``; returns the figures, times and paths.
    ``strands_info``: entries added to the strand frame's info (stored in strands.exr and returned).  ``cache``:
    a table cache folder that keeps the strand frame of a fixed ``level`` between runs (``_frame_cache``)."""
    from ..scene import as_scene

    sc = as_scene(scene) if prepared is None else prepared.scene
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    lay = render_layered(sc, db=db, sh=sh, maps=maps, prepared=prepared)
    t1 = time.perf_counter()
    if level is None:
        strand = render_strands(sc, lay.camera, bound=bound, max_level=max_level)
    elif cache is not None:
        strand = strands_frame(sc, lay.camera, levels=[level], root=cache)
    else:
        strand = render_strands(sc, lay.camera, levels=[level])
    t2 = time.perf_counter()
    strand.info.update(strands_info or {})
    figures, heat = compare(lay, strand)
    files = {"layered": write_frame(lay, out / "layered.exr")["exr"], "strands": write_frame(strand, out / "strands.exr")["exr"]}
    heat8 = np.round(np.clip(heat, 0, 1) * 255).astype(np.uint8)
    atomic_write_bytes(out / "flip.png", encode_png(heat8))
    atomic_write_bytes(
        out / "side_by_side.png", encode_png(panels(tonemap(lay.rgba[..., :3]), tonemap(strand.rgba[..., :3]), heat8))
    )
    files.update(flip=str(out / "flip.png"), side_by_side=str(out / "side_by_side.png"))
    last = strand.info["levels"][-1]
    return {
        "figures": figures,
        "files": files,
        "resolution": [lay.camera.width, lay.camera.height],
        "layered": {"map_method": lay.info["map_method"], "seconds": lay.info["seconds"], "wall_s": t1 - t0},
        "strands": {
            "level": last["level"],
            "samples_per_pixel": last.get("samples_per_pixel"),
            "steps_per_crossing": last.get("steps_per_crossing"),
            "converged": strand.info["converged"],
            "bound": strand.info["bound"],
            "change_from_previous": last.get("change_from_previous"),
            "environment": strand.info.get("environment"),
            "seconds": strand.info["seconds"],
            "wall_s": t2 - t1,
            "cache": strand.info.get("cache"),
            **(strands_info or {}),
        },
    }
