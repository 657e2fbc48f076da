"""``render_layered(scene)``: the layered cluster model through the scene's camera (satf §6), as a :class:`Frame`.

The online module (``hairlut.synth.prepare`` / ``render_view``) gives every layer of every cluster its shaded
RGBA on the (n_t, n_u) texel grid: the map method's re- and α-maps, the scene's lights (eqs 8–11), its
shadow method (eq 12 or a light-space map), eq 13 and the environment term when the scene has one, all
for the scene's ``[camera] view`` (a perspective camera's per-pixel view direction is not re-shaded).
The layer meshes (``hairlut.geometry.layer_meshes``, refined until a mesh edge spans at most
:data:`EDGE_PIXELS` pixels) carry those maps as textures, drawn in two passes (``_fragments``: once per camera the
fragments, perspective-correct, from ``_raster.surfaces``; per frame the texturing and the composite, eq 14 between
a cluster's layers and front-to-back "over" between clusters).  :func:`rasterise` draws the same frame in one pass
(:func:`raster_kernel`), the reference the two-pass frame is tested against.  The textures
are eq 13's colour as it comes (already α-premultiplied: :func:`layer_textures`) with α and colour lengthened for
the camera ray's angle ψ to the layer's tangent (:func:`oblique_path`).  With the direct map method (law ``rays``)
the maps are traced so: every in-plane ray's optical depth times its sector's 1 / sin ψ before the rays are averaged
(:func:`sector_paths`, exact for strands parallel to the tangent, whatever their arrangement); with the other
methods each texel is lengthened (:func:`lengthen`) by the exponent of Beer–Lambert through randomly placed strands
(:func:`strand_path`, Campbell's theorem: weaker than the 1 / sin ψ of a continuous medium, since a longer chord
through an opaque strand adds little, and too strong for clumped strands; tests/test_render_oblique.py).

Compile shapes are bucketed: the candidate capacity to an eighth of a power of two, the cluster tile to a
multiple of :data:`TILE_STEP`.
"""

from __future__ import annotations

import math
import time

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ._fragments import draw_layers
from ._frame import Frame
from ._raster import raster_kernel
from ._tiles import _bucket, candidates, pairs_of

#: The longest mesh edge, in pixels, the host refines the layer meshes to.
EDGE_PIXELS = 12.0
#: The longest optical path, in units of the in-plane one, :func:`oblique_path` gives (ψ ≥ 5.7°).
MAX_PATH = 10.0
#: Tile sides are rounded up to a multiple of this (fewer compile shapes).
TILE_STEP = 32
MAX_SUBDIV = 32
#: How :func:`render_layered` lengthens the in-plane α for the camera ray's angle: ``rays`` (the direct maps traced
#: with every ray's optical depth × 1 / sin ψ, per sector: :func:`sector_paths`), ``strands`` (:func:`strand_path`,
#: Beer–Lambert through randomly placed Gaussian tubes, per texel), ``volume`` (1 / sin ψ per texel, a continuous
#: medium) or ``off``.
OBLIQUE_LAWS = ("rays", "strands", "volume", "off")


def _edges_px(cam, verts: np.ndarray, rows: int, cols: int) -> tuple[float, float]:
    """Longest projected mesh edge along t (rows) and along u (columns), pixels; verts (…, rows·cols, 3)."""
    x, y, _ = cam.project(verts.reshape(-1, rows, cols, 3))
    p = np.stack([x, y], -1)
    along_t = np.linalg.norm(np.diff(p, axis=1), axis=-1).max(initial=0.0)
    along_u = np.linalg.norm(np.diff(p, axis=2), axis=-1).max(initial=0.0)
    return float(along_t), float(along_u)


def layout(cam, geometry, *, edge_pixels: float = EDGE_PIXELS):
    """The layer meshes refined for ``cam`` and the kernel's static layout: (meshes, tile (th, tw),
    origins (C, 2) int32, (t_subdiv, u_subdiv)).  Refines ``t_subdiv``/``u_subdiv`` until every projected edge spans ≤ ``edge_pixels``."""
    from ..geometry import layer_meshes

    base = layer_meshes(geometry)
    et, eu = _edges_px(cam, base.vertices, base.rows, base.cols)
    t_sub = int(min(max(math.ceil(et / edge_pixels), 1), MAX_SUBDIV))
    u_sub = int(min(max(math.ceil(eu / edge_pixels), 1), MAX_SUBDIV))
    meshes = layer_meshes(geometry, t_subdiv=t_sub, u_subdiv=u_sub)
    x, y, d = cam.project(meshes.vertices)  # (C, K, V)
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise errors.ValidationError("camera", cam.to_json()["eye"], "the layer meshes do not project to finite pixels")
    if cam.projection == "perspective" and (d <= 0).any():  # an orthographic view sees the whole line
        raise errors.ValidationError("camera.position", cam.eye.tolist(), "layer meshes lie behind the camera")
    W, H = cam.width, cam.height
    lo_x = np.clip(np.floor(x.min(axis=(1, 2))), 0, W - 1)
    hi_x = np.clip(np.ceil(x.max(axis=(1, 2))), 0, W)
    lo_y = np.clip(np.floor(y.min(axis=(1, 2))), 0, H - 1)
    hi_y = np.clip(np.ceil(y.max(axis=(1, 2))), 0, H)
    tw = int(min(TILE_STEP * math.ceil(max((hi_x - lo_x).max(), 1) / TILE_STEP), W))
    th = int(min(TILE_STEP * math.ceil(max((hi_y - lo_y).max(), 1) / TILE_STEP), H))
    origins = np.stack([np.minimum(lo_x, W - tw), np.minimum(lo_y, H - th)], -1).astype(np.int32)
    return meshes, (th, tw), origins, (t_sub, u_sub)


def layer_textures(result) -> np.ndarray:
    """(C, K, n_t, n_u, 4) premultiplied RGBA layer textures of a ``hairlut.synth.SynthResult``.

    Eq 13's shaded colour Ψ^lighting · re · τ is already α-premultiplied: re is the accumulated reflectance of
    eq 5 (re_acc = Σ_k w_k re_k with w_k = α_k Π_{j<k}(1 − α_j)), which carries the layer's opacity (a thin
    layer reflects little).  So RGB is taken as it is and composited with "over" for premultiplied colour
    (``_raster``); multiplying it by α once more would count the layer's opacity twice (colour ∝ α²)."""
    return np.stack([np.asarray(r.rgba, np.float32) for r in result.clusters])


def oblique_path(cam, tangent, position) -> np.ndarray:
    """1 / sin ψ per texel (…,), ψ the angle between the camera ray through the texel and the cluster's
    axis (the layer's unit tangent ∂P/∂t), capped at :data:`MAX_PATH`.

    The α-maps are in-plane opacities (satf §5.1, eq 4: rays in the cross-section, through the density the
    strands make where they cross it).  A camera ray that meets the cluster's axis at ψ ≠ 90° crosses the
    same cross-section density over a path longer by 1/sin ψ (the density is constant along the axis to first
    order), so in a continuous medium its optical depth is −ln(1 − α)/sin ψ; through strands, each crossing's
    is (:func:`strand_path`).  The layer's tangent, not the cluster's axis: where a cluster flares its strands
    follow the layers (a cone of strands, tests/test_render_oblique.py's notes: the layered/strands mean-α ratio
    moves 1.2 % from ψ = 90° to 30° with the layer's tangent, 15 % with the cluster's axis)."""
    t = np.asarray(tangent, np.float64)
    if cam.projection == "perspective":
        d = cam.eye - np.asarray(position, np.float64)
        d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-300)
    else:
        d = np.broadcast_to(cam.back, t.shape)
    s = np.linalg.norm(np.cross(d, t), axis=-1)
    return 1.0 / np.maximum(s, 1.0 / MAX_PATH)


def sector_paths(cam, prepared) -> tuple[np.ndarray, np.ndarray]:
    """The ``rays`` law's optical-path factors of a ``hairlut.synth.Prepared`` scene with the direct map method:
    (S,) for the camera ray through each sector (:func:`oblique_path` at the sector's centre and tangent,
    ``hairlut.synth.sector_tangents``) and (S, L) for each of the scene's lights (1 / sin ψ_l against the same
    tangent, capped at :data:`MAX_PATH`).  ``hairlut.synth.render_view(path=, light_path=)`` multiplies every traced ray's
    optical depth by them before the rays are averaged to pixels (satf eq 4 along the camera ray: exact for strands
    parallel to the tangent, whatever their arrangement in the cross-section; ``hairlut.march._direct``)."""
    from ..synth import sector_tangents

    tangent, position = sector_tangents(prepared.clusters)
    lights = np.asarray(prepared.scene.lights, np.float64).reshape(-1, 3)
    lights = lights / np.linalg.norm(lights, axis=-1, keepdims=True)
    s_l = np.linalg.norm(np.cross(lights[None, :, :], tangent[:, None, :]), axis=-1)
    return oblique_path(cam, tangent, position), 1.0 / np.maximum(s_l, 1.0 / MAX_PATH)


def crossing_depth(a) -> np.ndarray:
    """G(a) = ∫ (1 − exp(−a·e^{−x²})) dx over the whole line (float64, a ≥ 0): a strand crossing's opacity
    integrated over its impact parameter x = b / r, for a Gaussian tube whose optical depth at impact b is
    a·exp(−b²/r²) (``_strands``: a = κ √π on a crossing at right angles, a / sin ψ at angle ψ).  G(a) → √π a for
    a → 0 (transparent strands); for opaque ones G grows only like 2 √(ln a)."""
    a = np.asarray(a, np.float64)
    x = np.linspace(0.0, 8.0, 2049)
    g = -np.expm1(-a.reshape(-1, 1) * np.exp(-x * x))
    return (2.0 * np.trapezoid(g, x, axis=1)).reshape(a.shape)


def strand_path(path: np.ndarray, kappa: float) -> np.ndarray:
    """The optical-depth ratio (…,) of a camera ray to an in-plane ray through the same strands, for camera paths
    ``path`` = 1 / sin ψ (:func:`oblique_path`) and extinction κ (σ_t = κ / r): G(κ √π · path) / G(κ √π)
    (:func:`crossing_depth`).

    Beer–Lambert through strands at random positions (a Poisson line process, λ strands per unit impact
    length) is Campbell's theorem: E[e^{−Σ τ_k}] = exp(−λ r G(a)), so the in-plane α-map holds
    −ln(1 − α) = λ r G(κ √π) and a ray crossing the same strands at angle ψ sees λ r G(κ √π / sin ψ): each crossing
    is longer by 1 / sin ψ, but a ray that already crossed a strand's core gains little from a longer chord.
    The 1 / sin ψ of a continuous medium (a volume density) is the limit κ → 0; for the tracer's κ = 2/π
    (opaque discs) ψ = 30° gives 1.50, not 2.  Tested against the strand render
    (tests/test_render_oblique.py)."""
    a0 = float(kappa) * math.sqrt(math.pi)
    grid = np.linspace(1.0, MAX_PATH, 1025)
    table = crossing_depth(a0 * grid) / crossing_depth(a0)
    return np.interp(np.asarray(path, np.float64), grid, table)


def lengthen(rgba: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Premultiplied (…, 4) texels seen along a path ``path`` (…,) times the in-plane one: α' = 1 − (1 − α)^path
    (Beer–Lambert), the colour scaled with α (the same shaded colour per unit opacity)."""
    a = np.clip(rgba[..., 3].astype(np.float64), 0.0, 1.0)
    a2 = -np.expm1(path * np.log1p(-np.minimum(a, 1.0 - 1e-7)))
    a2 = np.where(a >= 1.0, 1.0, a2)
    scale = np.where(a > 0, a2 / np.where(a > 0, a, 1.0), 0.0)
    out = rgba.astype(np.float64) * scale[..., None]
    out[..., 3] = a2
    return out.astype(np.float32)


def rasterise(cam, vertices, triangles, uv, textures, *, tile, origins, repeat: int = 0):
    """Run :func:`raster_kernel` on (C, K, V, 3) ``vertices`` and (C, K, n_t, n_u, 4) premultiplied ``textures``
    (``repeat`` more warm runs timed); returns (rgba, depth, seconds dict, candidate pixels per cluster).  The
    candidate capacity comes from a float64 projection with a margin; should the float32 kernel need more, it runs
    again with what it reported."""
    f32 = jnp.float32
    pairs = pairs_of(triangles)
    args = (
        jnp.asarray(vertices, f32),
        jnp.asarray(textures, f32),
        jnp.asarray(origins, jnp.int32),
        jnp.asarray(pairs, jnp.int32),
        jnp.asarray(uv, f32),
        jnp.asarray(cam.matrix, f32),
        jnp.asarray(cam.eye, f32),
        jnp.asarray(cam.back, f32),
    )
    cap = _bucket(1.02 * candidates(cam, vertices, pairs, origins, tile) + 64)
    kw = {"size": (cam.width, cam.height), "tile": tuple(int(t) for t in tile)}
    t0 = time.perf_counter()
    rgba, depth, need = jax.block_until_ready(raster_kernel(*args, **kw, cap=cap))
    if int(need) > cap:
        cap = _bucket(int(need))
        rgba, depth, need = jax.block_until_ready(raster_kernel(*args, **kw, cap=cap))
    times = [time.perf_counter() - t0]
    for _ in range(max(int(repeat), 0)):
        t0 = time.perf_counter()
        jax.block_until_ready(raster_kernel(*args, **kw, cap=cap))
        times.append(time.perf_counter() - t0)
    rgba, depth = np.asarray(rgba), np.asarray(depth)
    if not (np.isfinite(rgba).all() and np.isfinite(depth).all()):
        raise errors.ValidationError("frame", "non-finite", "the rasteriser produced non-finite pixels")
    sec = {"raster_first": times[0]}
    if len(times) > 1:
        sec["raster"] = min(times[1:])
    return rgba, depth, sec, cap


def render_layered(
    scene,
    camera=None,
    *,
    db=None,
    sh=None,
    maps=None,
    prepared=None,
    repeat: int = 1,
    edge_pixels: float = EDGE_PIXELS,
    oblique: bool | str | None = None,
    trim: bool = True,
) -> Frame:
    """The layered model of ``scene`` through its camera (module docstring).  ``db``/``sh``/``maps``: the
    assets ``hairlut.synth.prepare`` reads (the scene's map method decides which); ``prepared``: a
    ``hairlut.synth.Prepared`` to reuse.  ``info["seconds"]``: ``maps`` and ``shade`` (the online module's
    frame), ``plan`` (the camera pass of ``_fragments``: which layer surfaces each pixel shows, and where in their
    textures), ``raster_first`` (the first texturing and composite, compile included) and ``raster`` (the best of
    ``repeat`` warm calls: the frame time for this camera, maps and camera pass excluded).  ``oblique``: how each
    texel's α (and colour) is lengthened for the camera ray's angle ψ to the layer's tangent (:func:`oblique_path`):
    ``"rays"`` (the default, True or None, with the direct map method) in the maps themselves, every traced ray's optical
    depth times each sector's 1 / sin ψ (and each light's ray in the sector's self-shadow times 1 / sin ψ_l) before the
    rays are averaged (:func:`sector_paths`); ``"strands"`` (the default with the other map methods) each texel by
    :func:`strand_path`'s exponent, ``"volume"`` by 1 / sin ψ, ``"off"`` (False) not at all (the in-plane α).
    ``trim`` (default): each cluster draws only within its own strands' footprint through the camera, widened by
    two texels (``_trim``: the layers stay on the hair); ``info["trim"]`` gives the margins and the fragments
    dropped, ``info["seconds"]["trim"]`` the footprints' time (part of the camera pass)."""
    from ..geometry import ClusterGeometry
    from ..scene import as_scene
    from ..synth import prepare, render_view
    from ._render import extinction, scene_camera

    law = None if oblique is True else ("off" if oblique is False else oblique)
    if law is not None and law not in OBLIQUE_LAWS:
        raise errors.ValidationError("oblique", oblique, f"one of {OBLIQUE_LAWS}, None or a bool")
    t0 = time.perf_counter()
    sc = as_scene(scene) if prepared is None else prepared.scene
    prep = prepare(sc, db, sh, maps) if prepared is None else prepared
    law = law or ("rays" if prep.method == "direct" else "strands")
    if law == "rays" and prep.method != "direct":
        raise errors.ValidationError(
            "oblique", law, f"the rays law traces the direct maps; this scene's map method is {prep.method!r}"
        )
    t1 = time.perf_counter()
    cam = scene_camera(sc) if camera is None else camera
    paths = sector_paths(cam, prep) if law == "rays" else (None, None)
    result = render_view(prep, path=paths[0], light_path=paths[1])
    geometry = ClusterGeometry([pc.spec for pc in prep.clusters])
    meshes, tile, origins, subdiv = layout(cam, geometry, edge_pixels=edge_pixels)
    tex = layer_textures(result)
    if law in ("strands", "volume"):
        path = oblique_path(cam, np.stack([pc.tangent for pc in prep.clusters]), np.stack([pc.position for pc in prep.clusters]))
        tex = lengthen(tex, strand_path(path, extinction(sc)) if law == "strands" else path)
    t2 = time.perf_counter()
    keep, trim_info = None, None
    if trim:
        from ..scene import scene_clusters
        from ._trim import strand_footprints, texel_margins

        margins = texel_margins(cam, np.stack([pc.position for pc in prep.clusters]))
        keep = strand_footprints(cam, [s for _, s in scene_clusters(sc)], tile, origins, margins)
        trim_info = {"margin_px": [round(float(m), 3) for m in margins]}
    t3 = time.perf_counter()
    rgba, depth, sec, plan = draw_layers(
        cam, meshes.vertices, meshes.triangles, meshes.uv, tex, tile=tile, origins=origins, repeat=repeat, keep=keep
    )
    if trim_info is not None:
        kept = plan.info["fragments"]
        trim_info.update(
            trimmed=plan.info["trimmed"], trimmed_fraction=plan.info["trimmed"] / max(kept + plan.info["trimmed"], 1)
        )
    cap = plan.info["candidates_per_cluster"]
    st = result.stats["seconds"]
    info = {
        "method": "layered",
        "map_method": prep.method,
        "scene": sc.source,
        "clusters": len(prep.clusters),
        "layers": int(tex.shape[1]),
        "texels": list(tex.shape[2:4]),
        "subdivision": list(subdiv),
        "triangles": int(meshes.triangles.shape[0] * tex.shape[0] * tex.shape[1]),
        "candidates_per_cluster": cap,
        "fragments": plan.info["fragments"],
        "tile": list(tile),
        "oblique": law,
        "trim": trim_info,
        "environment": "included" if prep.environment is not None else "none in scene",
        "seconds": {
            "prepare": t1 - t0,
            "maps": st.get("maps", 0.0),
            "shade": st.get("shade", 0.0),
            "setup": t2 - t1,
            "trim": t3 - t2,
            **sec,
        },
    }
    return Frame(rgba, depth, cam, info)
