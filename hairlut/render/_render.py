"""Scene-level entry point of the strand render, :func:`render_strands` (``_strand_march``), returning a :class:`Frame`."""

from __future__ import annotations

import time

import jax.numpy as jnp
import numpy as np

from .. import errors
from ._frame import Frame
from ._strand_march import render_level
from ._strands import segments_of

#: Default convergence bound (the scene schema's ``render.strands_bound``): RMSE of the premultiplied RGB and of α
#: between successive levels.
BOUND = 0.01


def extinction(scene) -> float:
    """κ of σ_t = κ / r: the scene's HRIR recipe ``trace.extinction``."""
    from ..hrir import resolve_recipe

    return float(resolve_recipe(scene.config["tables"]["hrir"])["trace"]["extinction"])


def segment_lighting(scene, tangent, view, lights, colors) -> np.ndarray:
    """(S, L, 3) eqs 8–11 (Scheuermann's terms) per segment and light, normal facing the viewer."""
    from ..synth import lighting_kernel, material_arrays

    t = np.asarray(tangent, np.float64)
    v = np.asarray(view, np.float64)
    n = v[None] - (t @ v)[:, None] * t
    nn = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(nn > 1e-9, n / np.where(nn > 0, nn, 1.0), 0.0)  # a strand along the view: no shift direction
    fx = scene.effects
    mat, colours = material_arrays(scene)
    f32 = np.float32
    lit = lighting_kernel(
        jnp.asarray(t, f32),
        jnp.asarray(n, f32),
        jnp.asarray(v, f32),
        jnp.asarray(lights, f32),
        jnp.asarray(colors, f32),
        jnp.full(len(t), 0.5, f32),
        mat,
        colours,
        use_diffuse=fx["diffuse"],
        primary=fx["primary"],
        secondary=fx["secondary"],
        noise=fx["noise"],
    )
    return np.asarray(lit)


def scene_strands(scene) -> list:
    """The scene's strands, one :class:`hairlut.geometry.Strands` per cluster (the groom's or the procedural
    ones)."""
    from ..scene import scene_clusters

    return [s for _, s in scene_clusters(scene)]


def scene_camera(scene, strands=None):
    """The scene's :class:`~hairlut.scene.Camera` (:func:`hairlut.scene.scene_camera`: fitted to its strands where
    ``[camera]`` says 'auto'), or fitted to ``strands`` when given."""
    from ..scene import make_camera, thinnest_radius
    from ..scene import scene_camera as fitted

    if strands is None:
        return fitted(scene)
    return make_camera(scene.config["camera"], np.concatenate([s.points for s in strands]), thinnest_radius(strands))


def _change(a: np.ndarray, b: np.ndarray) -> dict:
    return {
        "rgb_rmse": float(np.sqrt(np.mean((a[..., :3] - b[..., :3]) ** 2))),
        "alpha_rmse": float(np.sqrt(np.mean((a[..., 3] - b[..., 3]) ** 2))),
    }


def render_strands(
    scene,
    camera=None,
    *,
    bound: float | None = None,
    max_level: int = 3,
    min_level: int = 1,
    levels: list | None = None,
    strands=None,
    verify: bool = False,
) -> Frame:
    """The converged strand render of ``scene`` (``_strand_march``): levels ``min_level − 1``, … until the
    change from the level before is below ``bound`` in both RGB and α RMSE (or ``max_level``).  With ``levels``
    (e.g. [2]) exactly those levels are rendered and the last returned (no convergence claim).  ``verify``: once
    converged, one more level is rendered and its change from the returned image stored as ``info["verified"]``
    (``holds``: below ``bound`` too); the returned image stays the converged one.  ``bound`` None: the scene's
    ``[render] strands_bound``."""
    from ..scene import as_scene

    sc = as_scene(scene)
    bound = float(sc.config["render"].get("strands_bound", BOUND)) if bound is None else bound
    if not (np.isfinite(bound) and bound > 0):
        raise errors.ValidationError("bound", bound, "must be finite and > 0")
    if isinstance(max_level, bool) or not isinstance(max_level, int) or not 0 <= max_level <= 4:
        raise errors.ValidationError("max_level", max_level, "an integer in [0, 4]")
    t0 = time.perf_counter()
    strands = scene_strands(sc) if strands is None else strands
    cam = scene_camera(sc, strands) if camera is None else camera
    segs = segments_of(strands, extinction(sc))
    lit = jnp.asarray(segment_lighting(sc, segs.tangent, cam.back, sc.lights, sc.light_colors), jnp.float32)
    shadows = sc.shadow_method != "none"
    t1 = time.perf_counter()
    history, prev, img = [], None, None
    run = list(levels) if levels is not None else range(max(min_level - 1, 0), max_level + 1)
    converged = False
    for lv in run:
        st = {}
        tl = time.perf_counter()
        img = render_level(segs, cam, lit, sc.lights, level=lv, shadows=shadows, stats=st)
        st["seconds"] = time.perf_counter() - tl
        if prev is not None:
            st["change_from_previous"] = _change(img, prev)
        history.append({"level": lv, **st})
        if levels is None and prev is not None and lv >= min_level and max(st["change_from_previous"].values()) < bound:
            converged = True
            break
        prev = img
    verified = None
    if verify and converged and levels is None:
        tl = time.perf_counter()
        finer = render_level(segs, cam, lit, sc.lights, level=history[-1]["level"] + 1, shadows=shadows)
        ch = _change(finer, img)
        verified = {
            "level": history[-1]["level"] + 1,
            "change_from_returned": ch,
            "holds": max(ch.values()) < bound,
            "seconds": time.perf_counter() - tl,
        }
    info = {
        "method": "strands",
        "scene": sc.source,
        "bound": bound if levels is None else None,
        "converged": converged,
        "verified": verified,
        "levels": history,
        "segments": segs.n,
        "extinction_kappa": extinction(sc),
        "shadows": shadows,
        "environment": "not included",
        "seconds": {"setup": t1 - t0, "frame": time.perf_counter() - t1},
    }
    return Frame(img[..., :4], img[..., 4], cam, info)
