"""``synthesize(scene, db)``: the online phase for every cluster of a scene (satf §6), and its files.

Pipeline.  :func:`prepare` (once per scene): clusters and strands → sectors and HSVs
(``hairlut.geometry``) → sector features and frames → the index of eqs 6–7 (``_maps.map_index``:
the SATF neighbours of every sector and averaged HSV, texel → HSV and image-line offsets)
→ per-texel frames on each layer surface (tangent ∂P/∂t, normal ∂P/∂u × ∂P/∂t, as in
``layer_meshes``).  :func:`render_view` (per view, for any view and lights): Params(b) angles, the
uniformity test, SATF fetches and re-/α-maps (``_maps.view_maps``, eqs 6–7) → lighting
(eqs 8–11), shadows, shading and blending (eqs 12–14) in one kernel.  Shadows come from the
scene's method (``_shadowing``): eq 12's s-map in the kernel, or one transmittance per
(texel, light) from a light-space map built in ``prepare`` (rebuilt when the lights change).
Each cluster's strands, sectors and features are its own (so results do not depend on the
order of the clusters); a view then runs all clusters together through each kernel once.
:func:`write_outputs` writes one EXR and one PNG per cluster plus an orthographic preview
of the whole set.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, fields
from functools import partial
from pathlib import Path
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np

from .. import errors
from ..assets import atomic_write_bytes, encode_png, tonemap, write_exr
from ..scene import Scene, as_scene, layer_reads, scene_clusters, scene_sector_tables, texel_choice
from ._environment import prepare_environment
from ._maps import SectorFrames, sector_frames, texel_grid
from ._methods import prepare_map_source
from ._shading import compose_clusters_kernel, lighting_kernel, value_noise
from ._shadowing import prepare_shadows, seen_points
from ._view import geometry_index, map_index, view_maps

KIND = "synth_maps"


@dataclass(frozen=True, eq=False)
class ClusterResult:
    """One cluster's maps, per layer k (innermost first) on the (n_t, n_u) texture:
    ``re`` (K, Lt, n_t, n_u) per light, ``alpha`` (K, n_t, n_u), ``shadow`` (K, Ls, n_t, n_u) the
    transmittance per light (Ls = Lt for a light-space shadow method, 1 for eq 12's τ or none), ``lighting``
    (K, n_t, n_u, 3; eq 8 summed over lights), ``rgba`` (K, n_t, n_u, 4; eq 13 and α),
    ``final`` (n_t, n_u, 4; eq 14), ``position`` (K, n_t, n_u, 3) of the texels."""

    re: np.ndarray
    alpha: np.ndarray
    shadow: np.ndarray
    lighting: np.ndarray
    rgba: np.ndarray
    final: np.ndarray
    position: np.ndarray
    uniform_fraction: float


@dataclass(frozen=True, eq=False)
class SynthResult:
    """The maps and shaded layers of one view (:func:`synthesize`, :func:`render_view`): the ``scene``, one :class:`ClusterResult` per
    cluster in the scene's order, and ``stats`` (cluster, layer and HSV counts, the texture size, each
    cluster's uniform fraction, the seconds per stage and the map method that ran)."""

    scene: Scene
    clusters: list
    stats: dict = field(default_factory=dict)


def _load_db(db):
    if isinstance(db, (str, Path)):
        from ..hrir import load_hrir_db

        return load_hrir_db(db)
    for name in ("features", "stats", "alpha", "reflectance", "theta_v", "theta_l"):
        if not hasattr(db, name):
            raise errors.ValidationError("db", type(db).__name__, "give an HRIRDB or the path of an hrir_db file")
    return db


def material_arrays(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(mat (9,), colours (3, 3)) of the scene's ``[material]`` as :func:`lighting_kernel` takes them."""
    m = scene.material
    mat = np.array(
        [
            m["kd"],
            m["ks_I"],
            m["ks_II"],
            m["p_I"],
            m["p_II"],
            m["shift"],
            m["diffuse_scale"],
            m["diffuse_bias"],
            m["noise_amount"],
        ],
        np.float32,
    )
    hair = np.asarray(m["hair_color"], np.float32)
    sec = np.asarray(m["spec_color_II"], np.float32) * (hair if m["secondary_hair_tint"] else 1.0)
    return mat, np.stack([hair, np.asarray(m["spec_color_I"], np.float32), sec])


@dataclass(frozen=True, eq=False)
class PreparedCluster:
    """What does not change with the view or the lights, for one cluster: its ``spec``, sector
    ``table`` and ``frames`` (features included), and per texel (K, n_t, n_u) the layer
    surface's ``tangent``, ``normal`` and ``position`` (…, 3) and the ``noise`` texture."""

    spec: object
    table: object
    frames: object
    tangent: np.ndarray
    normal: np.ndarray
    position: np.ndarray
    noise: np.ndarray


@dataclass(frozen=True, eq=False)
class Prepared:
    """A scene made ready for :func:`render_view`: its clusters, the database, the seconds it took, and
    the clusters merged into one multi-cluster ``table`` and ``frames`` (sector ids offset by
    cluster, as in a multi-cluster :class:`~hairlut.geometry.SectorTable`) with stacked texel
    arrays (float32 device arrays) and the maps' ``index`` (``_view.MapIndex``), so a view runs
    every cluster through one call of each kernel; ``environment`` (``_environment.Environment``)
    when the scene has an environment light; ``shadows`` (``_shadowing.Shadows``), the shadow method
    and its per-light maps."""

    scene: Scene
    db: object
    clusters: list
    seconds: dict
    table: object = None
    frames: object = None
    stacked: dict = field(default_factory=dict)
    index: object = None
    environment: object = None
    shadows: object = None
    #: the map method (``satf``, ``direct`` or ``scene``) and, for the latter two, its ``_methods.MapSource``
    method: str = "satf"
    maps: object = None


def _unit3(x):
    return x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-300)


def _geometry_db(scene: Scene):
    """What ``sector_frames`` reads of a database, for the map methods that read none (one cheap feature)."""
    from ..planner import direct_recipe

    return SimpleNamespace(stats=SimpleNamespace(names=("rho_st",)), recipe=direct_recipe(scene), geometry_only=True)


def resolve_method(scene: Scene, db=None, maps=None) -> tuple[str, str]:
    """The map method ``prepare`` runs and why: the planner's (``hairlut.planner.map_method``), except
    that ``auto`` given only an SATF database (no scene table) runs ``satf`` on it."""
    from ..planner import map_method

    method, why = map_method(scene)
    if scene.config["render"]["method"] == "auto" and db is not None and maps is None and method != "satf":
        return "satf", f"auto chose {method!r}, but only an SATF database was given: satf"
    return method, why


#: Clusters per sweep of :func:`texel_points`: the block ``ClusterGeometry`` pads a single cluster to, so that each
#: cluster's texels come out the same bits as swept alone (a block of 16 rounds some differently, ~1e-14).
TEXEL_GROUP = 4


def geometry_groups(specs) -> list:
    """The clusters' geometries, :data:`TEXEL_GROUP` to a ``ClusterGeometry``: [(geometry, index in it)] per cluster.
    A group's tables and sweeps give each cluster the same bits as a geometry of its own (the sweep pads one cluster
    to the same block of four), at a quarter of the geometries (27 ms each: 48 clusters, 1.3 s)."""
    from ..geometry import ClusterGeometry

    out = []
    for g0 in range(0, len(specs), TEXEL_GROUP):
        geom = ClusterGeometry(specs[g0 : g0 + TEXEL_GROUP])
        out += [(geom, c) for c in range(geom.n_clusters)]
    return out


class _OneCluster:
    """Cluster ``index`` of a group's ``ClusterGeometry`` as far as :func:`sector_frames` reads a geometry (its
    cross-sections, through ``sector_axes``); the group's sections at a set of t are swept once for all its
    clusters (``memo``, shared)."""

    def __init__(self, geometry, index: int, memo: dict):
        self.geometry, self.index, self.memo = geometry, index, memo

    def sections(self, t):
        t = np.asarray(t, np.float64)
        key = (id(self.geometry), t.shape, t.tobytes())
        if key not in self.memo:
            self.memo[key] = self.geometry.sections(t)
        return type(self.memo[key])(*(f[self.index : self.index + 1] for f in self.memo[key]))


def texel_points(specs, resolution, groups=None) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """P, ∂P/∂t, ∂P/∂u (1, K, n_t, n_u, 3) at the texels of each cluster's K layer surfaces (``resolution`` =
    (n_u, n_t)), swept :data:`TEXEL_GROUP` clusters at a time (one cluster at a time, each call filled three padded
    rows of four: 0.2 s a cluster); ``groups``: :func:`geometry_groups` of ``specs`` when made already."""
    n_u, n_t = resolution
    u, t = texel_grid((n_u, n_t))
    groups = geometry_groups(specs) if groups is None else groups
    out = []
    for geom in dict.fromkeys(g for g, _ in groups):  # each group once, in order
        group = geom.batch.specs
        shape = (len(group), group[0].n_layers, n_t, n_u)
        cl = np.broadcast_to(np.arange(len(group))[:, None, None, None], shape)
        tt = np.broadcast_to(t[None, None, :, None], shape)
        uu = np.broadcast_to(u[None, None, None, :], shape)
        vv = np.broadcast_to(np.stack([s.layer_radii for s in group])[:, :, None, None], shape)
        p, pt, pu = geom.derivatives_of(cl, tt, vv, uu)
        out += [(p[c : c + 1], pt[c : c + 1], pu[c : c + 1]) for c in range(len(group))]
    return out


def prepare_cluster(scene: Scene, db, spec, strands, table=None, texels=None, geometry=None, resolution=None) -> PreparedCluster:
    """Sectors, features and frames (the index of §6.2.1) and the texels' frames on each layer surface; ``table``:
    the cluster's sector table when known (``hairlut.scene.scene_sector_tables``), else built here; ``texels``: its
    :func:`texel_points` when swept with other clusters', else swept here; ``geometry``: what the sector frames read
    of its geometry (a group's, ``_OneCluster``), else its own; ``resolution``: the scene's texels
    (:func:`hairlut.scene.texel_choice`), when known."""
    from ..geometry import ClusterGeometry, build_sectors

    n_u, n_t = texel_choice(scene).value if resolution is None else resolution
    geom = ClusterGeometry(spec) if geometry is None or table is None else None
    if table is None:
        table = build_sectors(geom, strands, np.zeros(strands.n_strands, np.int64))
    frames = sector_frames(geom if geometry is None else geometry, table, db)
    K = spec.n_layers
    p, pt, pu = texel_points([spec], (n_u, n_t))[0] if texels is None else texels
    noise = np.stack([value_noise((n_t, n_u), scene.material["noise_frequency"], 7919 + k) for k in range(K)])
    return PreparedCluster(spec, table, frames, _unit3(pt[0]), _unit3(np.cross(pu[0], pt[0])), p[0], noise)


def prepare(scene, db=None, sh=None, maps=None) -> Prepared:
    """Everything of a scene that does not depend on the view or the lights (see :func:`render_view`);
    ``db``: the ``hrir_db`` the ``satf`` map method reads; ``sh``: the ``sh_tables`` file of the scene's
    environment light, when it has one; ``maps``: the ``scene_maps`` table the ``scene`` method reads.
    The method is :func:`resolve_method`'s; ``direct`` reads no table."""
    sc = as_scene(scene)
    method, why = resolve_method(sc, db, maps)
    if method == "satf" and db is None:
        raise errors.AssetNotFoundError(
            sc.source, f"the satf map method reads an hrir_db: give db= (bake it with `hairlut bake --scene {sc.source}`)"
        )
    database = _load_db(db) if method == "satf" else _geometry_db(sc)
    k = sc.config["render"]["neighbours"]
    if method == "satf" and k > len(database.features):
        raise errors.ValidationError("render.neighbours", k, f"the database holds only {len(database.features)} sectors")
    t0 = time.perf_counter()
    pairs = scene_clusters(sc)
    tables = scene_sector_tables(sc)  # the groom cache's, when the scene's groom was cut before
    t1 = time.perf_counter()
    specs = [spec for spec, _ in pairs]
    res = texel_choice(sc).value
    if len({spec.structure() for spec in specs}) == 1:  # else the check below names the clusters
        groups, memo = geometry_groups(specs), {}
        texels = texel_points(specs, res, groups)
        views = [_OneCluster(g, c, memo) for g, c in groups]
    else:
        texels = views = [None] * len(specs)
    clusters = [
        prepare_cluster(sc, database, spec, strands, tb, tx, view, res)
        for (spec, strands), tb, tx, view in zip(pairs, tables, texels, views)
    ]
    shapes = {pc.table.shape[1:] for pc in clusters}
    if len(shapes) != 1:
        raise errors.ValidationError("clusters", sorted(shapes), "clusters must share s_t, layer count and s_u")
    n_sec, n_hsv = clusters[0].table.n_sectors, clusters[0].table.n_hsvs
    table = SimpleNamespace(
        shape=(len(clusters), *shapes.pop()),
        n_hsvs=n_hsv * len(clusters),
        hsv_sectors=np.concatenate([pc.table.hsv_sectors + c * n_sec for c, pc in enumerate(clusters)]),
    )
    frames = SectorFrames(*(np.concatenate([getattr(pc.frames, f.name) for pc in clusters]) for f in fields(SectorFrames)))
    stacked = {
        name: jnp.asarray(np.stack([getattr(pc, name) for pc in clusters]), jnp.float32)
        for name in ("tangent", "normal", "noise")
    }
    reads = layer_reads(sc.config["render"]["layer_reads"], n_sec * len(clusters)).value
    if method == "satf":
        index, source = map_index(database, table, frames, clusters[0].spec.n_layers, res, k, reads), None
    else:
        index = geometry_index(table, frames, clusters[0].spec.n_layers, res, reads)
        source = prepare_map_source(sc, method, why, [pc.table for pc in clusters], [pc.frames for pc in clusters], maps)
    t2 = time.perf_counter()
    env = prepare_environment(
        sc, sh, [s for _, s in pairs], np.stack([pc.tangent for pc in clusters]), np.stack([pc.position for pc in clusters])
    )
    seconds = {"strands": t1 - t0, "index": t2 - t1} | ({"environment": time.perf_counter() - t2} if env else {})
    seen = seen_points(np.stack([pc.position for pc in clusters]), [pc.table for pc in clusters], texel_grid(res)[1])
    shadows = prepare_shadows(sc, [s for _, s in pairs], seen, seconds)
    return Prepared(
        sc, database if method == "satf" else None, clusters, seconds, table, frames, stacked, index, env, shadows, method, source
    )


@partial(jax.jit, static_argnames=("effects", "linear", "reflectance"))
def shade_kernel(
    re,
    alpha,
    tangent,
    normal,
    noise,
    view,
    lights,
    light_rgb,
    mat,
    colours,
    k_shadow,
    background,
    extra=None,
    transmittance=None,
    *,
    effects,
    linear,
    reflectance="unit",
):
    """Eqs 8–11 (lighting) and 12–14 (shadows, shading, blend) of every cluster, one kernel: τ, lighting
    summed over the lights, shaded RGBA per layer (plus ``extra``, the environment term) and the composite RGBA.
    τ is eq 12's s-map when ``effects[-1]`` (the s-map switch) is on, 1 when off, or, when ``transmittance``
    (C, K, n_t, n_u, L) is given, one τ per light (eq 13 per light).

    ``reflectance`` (``[material] reflectance``) is what eq 13 multiplies the lighting by, per light:

    * ``"unit"`` (the default): the layer's α, so the shaded colour is α · τ · Ψ^lighting, premultiplied: the
      lighting per unit of opacity, as the strand render shades each strand (Kajiya–Kay, eqs 8–11, times its
      transmittance).  A departure from eq 13 as written, which multiplies by the HRIR's re, the accumulated Phong
      reflectance k_a + T_l (k_d n·l + k_s (r·d)^p) of the trace, n the density gradient (satf §5.1, eq 5).  Per
      unit α, re is not a factor the lighting should carry: for a flat slab of parallel strands, pure diffuse
      Phong (k_a = k_s = 0, k_d = 1) and no shadow, re/α measured 0.33–0.70 per layer (the cosine of the strands'
      lumpy density gradients, which Kajiya–Kay's strand lighting already replaces), so the layered colour per unit
      α was 0.16–0.40 of the strand render's, which is Kajiya–Kay's closed form (tests/test_energy.py; 0.40 with a
      frontal light, 0.16 with a back light, where n·l < 0 leaves re only k_a α).  What re holds
      beside that cosine, the in-sector self-shadow T_l (15–20 % on that slab), cannot be separated from it; the
      shadow method (τ) is the layered model's shadowing.
    * ``"hrir"``: eq 13 as the paper writes it, τ · Ψ^lighting · re."""
    fx = dict(zip(("use_diffuse", "primary", "secondary", "noise"), effects))
    light = lighting_kernel(tangent, normal, view, lights, light_rgb, noise, mat, colours, **fx)
    if reflectance == "unit":
        re = jnp.broadcast_to(alpha[:, :, None], re.shape)
    tau, rgb, final, a = compose_clusters_kernel(
        light, re, alpha, k_shadow, background, extra, transmittance, shadow=effects[-1], linear=linear
    )
    return (tau, light.sum(axis=-2), jnp.concatenate([rgb, alpha[..., None]], -1), jnp.concatenate([final, a[..., None]], -1))


def render_clusters(
    prepared: Prepared, view, lights, light_colors, timing: dict | None = None, extra=None, paths: tuple = (None, None)
) -> list:
    """The maps and shaded layers of every prepared cluster for one view, all clusters batched: eqs 6–7 from the index
    (``_view.view_maps``: three kernels, timed as "maps"), then eqs 8–14 (:func:`shade_kernel`, "shade");
    ``extra`` (C, K, n_t, n_u, 3), the environment term, is added to each layer's shaded colour.  A light-space
    shadow method's maps are rebuilt first (timed as "shadows") when ``lights`` differ from the prepared ones.
    ``paths``: the direct method's per-sector optical-path factors (view, lights) (:func:`render_view`)."""
    timing = {} if timing is None else timing
    scene, db = prepared.scene, prepared.db
    cfg, fx = scene.config, scene.effects
    method = scene.shadow_method
    transmittance = prepared.shadows.for_lights(lights, timing) if prepared.shadows is not None else None
    t0 = time.perf_counter()
    if prepared.maps is None:
        if any(p is not None for p in paths):
            raise errors.ValidationError("path", prepared.method, "per-ray optical paths need the direct map method")
        re, alpha, uniform = view_maps(prepared.index, db, view, lights, scene.material["k_threshold"])
    else:
        re, alpha, uniform = prepared.maps.view(prepared.index, view, lights, *paths)
    jax.block_until_ready(alpha)
    t1 = time.perf_counter()
    mat, colours = material_arrays(scene)
    st = prepared.stacked
    f32 = partial(np.asarray, dtype=np.float32)
    out = shade_kernel(
        re,
        alpha,
        st["tangent"],
        st["normal"],
        st["noise"],
        f32(view),
        f32(lights),
        f32(light_colors),
        mat,
        colours,
        f32(scene.material["k_shadow"]),
        f32(cfg["render"]["background"]),
        None if extra is None else f32(extra),
        transmittance,
        effects=(*(fx[k] for k in ("diffuse", "primary", "secondary", "noise")), method == "smap"),
        linear=scene.material["shadow_form"] == "linear",
        reflectance=scene.material["reflectance"],
    )
    re, alpha, tau, light, rgba, final = (np.asarray(x) for x in jax.block_until_ready((re, alpha, *out)))
    t2 = time.perf_counter()
    for key, dt in (("maps", t1 - t0), ("shade", t2 - t1)):
        timing[key] = timing.get(key, 0.0) + dt
    uniform = uniform.reshape(len(prepared.clusters), -1)
    tau = np.moveaxis(tau, -1, 2) if transmittance is not None else tau[:, :, None]  # (C, K, Ls, n_t, n_u)
    return [
        ClusterResult(
            re[c], alpha[c], tau[c], light[c], rgba[c], final[c], pc.position, float(uniform[c].mean()) if uniform.size else 1.0
        )
        for c, pc in enumerate(prepared.clusters)
    ]


def _direction(name, d) -> np.ndarray:
    from ..validate import directions

    return directions(d, name)  # finite, non-zero 3-vectors, normalised (the shared rule)


def render_view(prepared: Prepared, *, view=None, lights=None, light_colors=None, path=None, light_path=None) -> SynthResult:
    """The maps and shaded layers of a prepared scene for one view: its own or the given view and lights (directions toward
    the viewer / lights; ``light_colors`` (L, 3), white by default when ``lights`` is given).  ``path`` (S,) and
    ``light_path`` (S, L): with the ``direct`` map method, the optical-path factors 1/sin ψ of the camera's and the
    lights' rays through each sector (``_methods.sector_tangents``), applied per ray inside the trace
    (``_direct.direct_sector_maps``): the maps are then what the camera sees, no longer in-plane."""
    sc = prepared.scene
    v = sc.view if view is None else _direction("view", view)
    ls = sc.lights if lights is None else np.atleast_2d(_direction("lights", lights))
    if light_colors is not None:
        cols = np.asarray(light_colors, np.float64).reshape(-1, 3)
    else:
        cols = sc.light_colors if lights is None else np.ones((len(ls), 3))
    if len(cols) != len(ls):
        raise errors.ValidationError("light_colors", light_colors, f"need one RGB per light ({len(ls)})")
    timing, extra, env_stats = dict(prepared.seconds), None, {}
    if prepared.environment is not None:
        t0 = time.perf_counter()
        extra, env_stats["environment_clamped"] = prepared.environment.rgb(v)
        timing["environment"] += time.perf_counter() - t0
    results = render_clusters(prepared, v, ls, cols, timing, extra, (path, light_path))
    stats = {
        "clusters": len(results),
        "layers": int(sum(r.alpha.shape[0] for r in results)),
        "hsvs": int(sum(pc.table.n_hsvs for pc in prepared.clusters)),
        "texels_per_layer": list(results[0].alpha.shape[1:]) if results else [],
        "uniform_fraction": [r.uniform_fraction for r in results],
        "seconds": timing,
        "map_method": prepared.method,
        **env_stats,
    }
    return SynthResult(sc, results, stats)


def synthesize(scene, db=None, sh=None, maps=None) -> SynthResult:
    """Synthesise re-, α-, s-maps, lighting, shaded layers and composites for every cluster:
    :func:`render_view` of :func:`prepare`.  ``scene``: a :class:`Scene`, a scene mapping or a TOML
    path; ``db``: an ``HRIRDB`` or the path of an ``hrir_db`` file; ``sh``: the ``sh_tables``
    file of the scene's environment light; ``maps``: the ``scene_maps`` table of the ``scene`` map method
    (``hairlut.planner.find_assets`` finds them in the cache)."""
    return render_view(prepare(scene, db, sh, maps))


def _plain(x):
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    return x


def channels(res: ClusterResult) -> dict[str, np.ndarray]:
    """EXR channels of one cluster: ``layerK.re`` (light 0; ``layerK.re_l<j>`` for further lights),
    ``layerK.A``, ``layerK.s`` (the transmittance: light 0's, ``layerK.s_l<j>`` for further lights with a
    light-space shadow method), ``layerK.R/G/B`` (eq 13), and the composite ``R, G, B, A`` (eq 14)."""
    out = {}
    for k in range(res.alpha.shape[0]):
        out[f"layer{k}.re"] = res.re[k, 0]
        for j in range(1, res.re.shape[1]):
            out[f"layer{k}.re_l{j}"] = res.re[k, j]
        out[f"layer{k}.A"] = res.alpha[k]
        out[f"layer{k}.s"] = res.shadow[k, 0]
        for j in range(1, res.shadow.shape[1]):
            out[f"layer{k}.s_l{j}"] = res.shadow[k, j]
        for c, name in enumerate("RGB"):
            out[f"layer{k}.{name}"] = res.rgba[k, ..., c]
    for c, name in enumerate("RGBA"):
        out[name] = res.final[..., c]
    return {k: np.asarray(v, np.float32) for k, v in out.items()}


def _upsample(a: np.ndarray, f: int) -> np.ndarray:
    """(n_t, n_u, C) → (f·(n_t − 1) + 1, f·n_u, C) by linear interpolation (periodic in u)."""
    a = np.concatenate([a, a[:, :1]], axis=1)
    w = (np.arange(f) / f)[:, None, None]
    rows = (a[:-1, None] * (1 - w) + a[1:, None] * w).reshape(-1, *a.shape[1:])
    rows = np.concatenate([rows, a[-1:]])
    w = (np.arange(f) / f)[None, None, :, None]
    return (rows[:, :-1, None] * (1 - w) + rows[:, 1:, None] * w).reshape(rows.shape[0], -1, a.shape[2])


def ortho_preview(result: SynthResult, size: int) -> np.ndarray:
    """(size, size, 3) linear RGB: each cluster's composite drawn at its outer-layer texels,
    upsampled until neighbours are at most a pixel apart, projected orthographically along the
    view, nearest texel in front."""
    view = result.scene.view
    up = np.array([0.0, 1.0, 0.0]) if abs(view[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
    e1 = np.cross(up, view)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(view, e1)
    coarse = np.stack([r.position[-1] for r in result.clusters]) @ np.stack([e1, e2], 1)  # (C, n_t, n_u, 2)
    span = max(np.ptp(coarse[..., 0]), np.ptp(coarse[..., 1]), 1e-12) * 1.05
    gap = max(np.abs(np.diff(coarse, axis=a)).max(initial=0.0) for a in (1, 2)) * size / span
    f = int(np.clip(np.ceil(gap), 2, 16))
    pos = np.concatenate([_upsample(r.position[-1], f).reshape(-1, 3) for r in result.clusters])
    col = np.concatenate([_upsample(r.final[..., :3], f).reshape(-1, 3) for r in result.clusters])
    x, y, depth = pos @ e1, pos @ e2, pos @ view
    cx, cy = 0.5 * (x.max() + x.min()), 0.5 * (y.max() + y.min())
    px = np.clip(((x - cx) / span + 0.5) * size, 0, size - 1).astype(int)
    py = np.clip((0.5 - (y - cy) / span) * size, 0, size - 1).astype(int)
    img = np.zeros((size, size, 3))
    order = np.argsort(depth)  # far first: nearer texels overwrite
    for dy in (0, 1):
        for dx in (0, 1):
            img[np.minimum(py[order] + dy, size - 1), np.minimum(px[order] + dx, size - 1)] = col[order]
    return img


def write_outputs(result: SynthResult, out_dir) -> dict:
    """One EXR (``cluster<i>.exr``, channels of :func:`channels`) and PNG per cluster, and
    ``preview.png``; returns {"exr": [...], "png": [...], "preview": path}."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    recipe = _plain({"scene": result.scene.config, "source": result.scene.source})
    exrs, pngs = [], []
    for i, res in enumerate(result.clusters):
        chans = channels(res)
        bad = [name for name, arr in chans.items() if not np.all(np.isfinite(np.asarray(arr)))]
        if bad:  # finite or refused: a NaN in the inputs must not become NaN pixels with exit 0
            raise errors.NonFiniteError(
                f"synth: cluster {i} has non-finite values in {', '.join(bad[:4])}"
                f"{' …' if len(bad) > 4 else ''}; check the database and the [material] keys"
            )
        exrs.append(str(write_exr(out / f"cluster{i:03d}.exr", chans, recipe=recipe, kind=KIND)))
        png = out / f"cluster{i:03d}.png"
        atomic_write_bytes(png, encode_png(tonemap(res.final[..., :3])))
        pngs.append(str(png))
    prev = out / "preview.png"
    size = result.scene.config["render"]["preview_size"]
    atomic_write_bytes(prev, encode_png(tonemap(ortho_preview(result, size))))
    return {"exr": exrs, "png": pngs, "preview": str(prev)}
