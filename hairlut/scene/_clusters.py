"""A scene's clusters and their strands (satf §3): what both the planner and the online module build on.

``[[clusters]]`` scenes grow procedural strands in each cluster
(:func:`~hairlut.geometry.generate_strands` with the ``[strands]`` table and each cluster's
seed); ``[groom]`` scenes read the strand file and group its strands into fitted clusters
(:func:`~hairlut.geometry.fit_clusters`), each cluster keeping the strands assigned to it.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from .. import errors
from ._choices import Choice, cluster_count, texel_resolution
from ._schema import Scene

#: The last few scenes' clusters, by :func:`_key`: the planner, the scene-maps bake, the synthesis and the camera
#: frame each ask for the same scene's clusters, and fitting a groom is seconds of work (issue 29: a warm demo fitted
#: each groom five times).  Callers get fresh copies of the arrays, so none can change another's.
_MEMO: dict = {}
_MEMO_SIZE = 4


def _key(scene: Scene) -> str:
    """What decides a scene's clusters: the groom file's identity (path, inode, size, modification time) and the
    ``[groom]`` table, or the ``[strands]`` table, the cluster specs and their seeds."""
    if scene.groom_path is not None:
        st = Path(scene.groom_path).stat()
        source = [str(Path(scene.groom_path).resolve()), st.st_ino, st.st_size, st.st_mtime_ns, scene.config["groom"]]
    else:
        source = [scene.config["strands"], repr(scene.specs), [int(x) for x in scene.cluster_seeds]]
    return json.dumps(source, sort_keys=True, default=repr)


def _copy(pairs: list) -> list:
    return [
        (
            spec,
            dataclasses.replace(
                s, **{f.name: np.array(getattr(s, f.name)) for f in dataclasses.fields(s) if getattr(s, f.name) is not None}
            ),
        )
        for spec, s in pairs
    ]


def scene_clusters(scene: Scene, cache_root=None) -> list:
    """[(ClusterSpec, Strands)] for each cluster of the scene, in the scene's order (remembered for the last few
    scenes: :data:`_MEMO`; a groom's fit is kept on disk in the table cache under ``cache_root``, else the folder last
    given for the scene in this process, else ``$HAIRLUT_CACHE``, else ``tables/``, keyed by the strands' content and
    the fit's arguments: ``_cache``)."""
    return _copy(_memo(scene, cache_root)[0])


def cluster_choice(scene: Scene) -> Choice:
    """``groom.clusters`` as given or as chosen from the groom (:func:`hairlut.scene.cluster_count`), or the
    ``[[clusters]]`` the scene lists."""
    if scene.groom_path is None:
        return Choice("clusters", len(scene.specs), True, "the scene's own [[clusters]]")
    return _memo(scene)[1]


#: Where a cluster's projected size is measured: points along its trajectory.
_SIZE_SAMPLES = 33


#: The last few scenes' chosen texels (:func:`texel_choice`), by :func:`_key`, ``[camera]`` and ``[render]``.
_TEXELS: dict = {}


def texel_choice(scene: Scene) -> Choice:
    """``render.resolution`` as given, or as :func:`hairlut.scene.texel_resolution` chooses it from each cluster's
    trajectory and width projected through the scene's camera (fitted to its strands as the camera frame fits it);
    kept for the last few scenes of the process (the planner and ``prepare`` both ask: 0.6 s at 100,000 strands)."""
    value = scene.config["render"]["resolution"]
    if value != "auto":
        return texel_resolution(value, [], [], 0)
    key = _key(scene) + json.dumps([scene.config["camera"], scene.config["render"]], sort_keys=True, default=repr)
    if key not in _TEXELS:
        while len(_TEXELS) >= _MEMO_SIZE:
            _TEXELS.pop(next(iter(_TEXELS)))
        _TEXELS[key] = _texel_choice(scene, value)
    return _TEXELS[key]


def _texel_choice(scene: Scene, value) -> Choice:
    specs = [spec for spec, _ in scene_clusters(scene)]
    if scene.groom_path is None:  # generated strands ([[clusters]]): nothing is kept on disk
        sizes = _projected_sizes(scene, specs)
    else:  # a groom's: in the groom cache with its camera (the clusters' sweeps: 0.6 s at 48 clusters)
        from ._cache import cached_arrays
        from ._sectors import _pairs_key

        def check(arrays):
            for k in ("lengths", "widths"):
                if arrays[k].shape != (len(specs),) or not np.isfinite(arrays[k]).all():
                    raise ValueError(f"{k} of shape {arrays[k].shape}, not ({len(specs)},) finite")

        doc = {"clusters": _pairs_key(scene, scene_clusters(scene)), "camera": scene.config["camera"]}
        sizes = cached_arrays("texels", doc, lambda: _projected_sizes(scene, specs), check, _root_of(scene))
    layers = sum(spec.n_layers for spec in specs)
    return texel_resolution(value, sizes["lengths"], sizes["widths"], layers, (specs[0].s_u, specs[0].s_t))


def _projected_sizes(scene: Scene, specs) -> dict:
    """Each cluster's trajectory length and width (twice the larger half axis, the median along it) in pixels through
    the scene's camera: {"lengths", "widths"} (C,)."""
    from ..geometry import ClusterGeometry

    cam = scene_camera(scene)
    geom = ClusterGeometry(specs)
    t = np.tile(np.linspace(0.0, 1.0, _SIZE_SAMPLES), len(specs))
    sec = geom.sections_of(np.repeat(np.arange(len(specs)), _SIZE_SAMPLES), t)
    x, y, _ = cam.project(sec.origin)
    ax, ay, _ = cam.project(sec.origin + sec.normal * sec.a[:, None])  # the ends of the half axes A and B
    bx, by, _ = cam.project(sec.origin + sec.binormal * sec.b[:, None])
    across = np.maximum(np.hypot(ax - x, ay - y), np.hypot(bx - x, by - y))  # the larger projected half axis
    shape = (len(specs), _SIZE_SAMPLES)
    x, y = x.reshape(shape), y.reshape(shape)
    lengths = np.hypot(np.diff(x, axis=1), np.diff(y, axis=1)).sum(axis=1)
    widths = 2.0 * np.median(across.reshape(shape), axis=1)
    return {"lengths": np.asarray(lengths, np.float64), "widths": np.asarray(widths, np.float64)}


def thinnest_radius(strands) -> float | None:
    """Half the smallest positive strand thickness of ``strands`` (the detail a frame must resolve), None without
    thicknesses."""
    th = [np.asarray(s.thickness, np.float64) for s in strands if s.thickness is not None]
    th = np.concatenate(th) if th else np.zeros(0)
    th = th[th > 0]
    return 0.5 * float(th.min()) if len(th) else None


#: The last few scenes' fitted cameras (:func:`scene_camera`), by :func:`_key` and ``[camera]``.
_CAMERAS: dict = {}


def scene_camera(scene: Scene):
    """The scene's :class:`~hairlut.scene.Camera`, fitted to its strands where ``[camera]`` says 'auto' and refused
    where float32 could not resolve their thinnest radius (:func:`~hairlut.scene.make_camera`).  A fit reads every
    strand point (0.9 s at 100,000 strands), so the camera is kept for the last few scenes of the process (the
    planner's texel choice, ``prepare`` and the render fit the same one) and, for a groom, in the groom cache
    (``groom-camera-*``), keyed by its clusters and strands and the ``[camera]`` table."""
    key = _key(scene) + json.dumps(scene.config["camera"], sort_keys=True, default=repr)
    if key not in _CAMERAS:
        while len(_CAMERAS) >= _MEMO_SIZE:
            _CAMERAS.pop(next(iter(_CAMERAS)))
        _CAMERAS[key] = _fit_camera(scene)
    return _CAMERAS[key]


def _fit_camera(scene: Scene):
    from ._camera import Camera, make_camera

    cfg = scene.config["camera"]
    pairs = scene_clusters(scene)

    def fit():
        strands = [s for _, s in pairs]
        return make_camera(cfg, np.concatenate([s.points for s in strands]), thinnest_radius(strands))

    if scene.groom_path is None:  # generated strands ([[clusters]]): nothing is kept on disk
        return fit()
    from ._cache import cached_arrays
    from ._sectors import _pairs_key

    def compute():
        cam = fit()  # refuses a camera float32 cannot draw before anything is kept
        return {
            "frame": np.stack([cam.eye, cam.right, cam.up, cam.back]).astype(np.float64),
            "scalars": np.array([cam.extent, cam.fov, cam.near, cam.far], np.float64),
        }

    def check(arrays):
        f, v = arrays["frame"], arrays["scalars"]
        if f.shape != (4, 3) or v.shape != (4,) or not (np.isfinite(f).all() and np.isfinite(v).all()):
            raise ValueError(f"a camera of frame {f.shape} and scalars {v.shape}, not (4, 3) and (4,) finite")

    doc = {"clusters": _pairs_key(scene, pairs), "camera": cfg}
    a = cached_arrays("camera", doc, compute, check, _root_of(scene))
    w, h = cfg["resolution"]
    return Camera(cfg["projection"], *a["frame"], int(w), int(h), *(float(x) for x in a["scalars"]))


def _memo(scene: Scene, cache_root=None) -> tuple:
    key = _key(scene)
    if key not in _MEMO:
        if len(_MEMO) >= _MEMO_SIZE:
            _MEMO.pop(next(iter(_MEMO)))
        _MEMO[key] = _build(scene, _root_of(scene, cache_root))
    return _MEMO[key]


#: The table cache folder each of the last few scenes (by :func:`_key`) was last given: the planner passes its
#: ``--cache`` folder, and what runs after it in the same process (a bake, ``hairlut.synth.prepare``) finds the
#: groom cache there without being told.
_ROOTS: dict = {}


def _root_of(scene: Scene, cache_root=None):
    """``cache_root`` when given (remembered for the scene), else the one last given for the scene, else None (the
    default folder)."""
    key = _key(scene)
    if cache_root is None:
        return _ROOTS.get(key)
    _ROOTS.pop(key, None)
    _ROOTS[key] = cache_root
    while len(_ROOTS) > _MEMO_SIZE:
        _ROOTS.pop(next(iter(_ROOTS)))
    return cache_root


def cache_root_of(scene: Scene):
    """The table cache folder this process last gave for ``scene`` (``scene_clusters``' ``cache_root``; the
    planner's), or None (the default: ``$HAIRLUT_CACHE``, else ``tables/``)."""
    return _root_of(scene)


def _check_count(strands, path) -> None:
    """Refuse a groom of fewer than 2 strands, naming ``groom.path`` (a fitted cluster's cross-section is measured from
    the spread of its strands, and one strand has none)."""
    n = strands.n_strands
    if n < 2:
        raise errors.ValidationError(
            "groom.path",
            str(path),
            f"the groom holds {n} strand{'' if n == 1 else 's'}; the cluster fit needs at least 2 "
            "(a cluster's cross-section is measured from the spread of its strands)",
        )


def _check_lengths(strands, path) -> None:
    """Refuse a groom with a strand without length, naming ``groom.path`` (no direction to follow: all its points
    within 1e-6 of the groom's extent, the fit's own test of a usable strand)."""
    n = strands.n_strands
    cols = np.ascontiguousarray(strands.points.T)  # the extent as np.ptp of the float64 points: min and max are exact,
    lo, hi = cols.min(axis=1).astype(np.float64), cols.max(axis=1).astype(np.float64)  # and by rows 10x faster
    extent = float(np.linalg.norm(hi - lo))
    flat = np.flatnonzero(strands.lengths() <= 1e-6 * extent)
    if flat.size:
        i = int(flat[0])
        raise errors.ValidationError(
            "groom.path",
            str(path),
            f"{flat.size} of {n} strands {'has' if flat.size == 1 else 'have'} no length (strand {i}: its {int(strands.counts[i])} points all at "
            f"{np.round(strands.strand(i)[0].astype(np.float64), 6).tolist()}); every strand needs a length to fit clusters to",
        )


def _split(strands, specs, labels) -> list:
    """[(spec, Strands)]: each cluster's strands (label c), in the groom's order, with their thickness."""
    from ..geometry import Strands

    strand_order = np.argsort(labels, kind="stable")  # each cluster's strands together, in the groom's order
    counts = strands.counts[strand_order]
    ends = np.cumsum(counts)
    # the points of those strands, in that order: each strand's own run of indices, moved to its new place
    order = np.repeat(strands.offsets[:-1][strand_order] - (ends - counts), counts) + np.arange(int(ends[-1]) if len(ends) else 0)
    strand_cuts = np.searchsorted(labels[strand_order], np.arange(len(specs) + 1))
    cuts = np.concatenate([[0], ends])[strand_cuts]
    points, thickness = strands.points[order], strands.thickness[order]
    return [
        (
            spec,
            Strands(
                points[cuts[c] : cuts[c + 1]],
                counts[strand_cuts[c] : strand_cuts[c + 1]],
                thickness=thickness[cuts[c] : cuts[c + 1]],
            ),
        )
        for c, spec in enumerate(specs)
    ]


def _build(scene: Scene, cache_root=None) -> list:
    from ..geometry import ClusterGeometry, Strands, generate_strands, read_strands
    from ._cache import cached_choice, cached_fit

    if scene.groom_path is not None:
        g = scene.config["groom"]
        strands = read_strands(scene.groom_path)
        _check_count(strands, scene.groom_path)
        if strands.thickness is None:
            strands = Strands(strands.points, strands.counts, thickness=np.full(strands.n_points, 2.0 * g["radius"], np.float32))
        choice = cached_choice(strands, g["clusters"], cluster_count, root=cache_root)
        batch, labels = cached_fit(
            strands,
            choice.value,
            layer_radii=g["layer_radii"],
            core_radius=g["core_radius"],
            s_t=g["s_t"],
            s_u=g["s_u"],
            seed=g["seed"],
            root=cache_root,
            check=lambda: _check_lengths(strands, scene.groom_path),  # 0.8 s at 100,000 strands: only when fitting
        )
        return _split(strands, batch.specs, labels), choice
    s = scene.config["strands"]
    out = []
    for spec, seed in zip(scene.specs, scene.cluster_seeds):
        strands, _ = generate_strands(
            ClusterGeometry(spec),
            s["count"],
            radius=s["radius"],
            profile=s["profile"],
            spread=s["spread"],
            jitter=s["jitter"],
            seed=int(seed),
        )
        out.append((spec, strands))
    return out, None
