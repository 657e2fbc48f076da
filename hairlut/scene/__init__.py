"""Scenes: what a scene holds, decided before anything is baked.

``load_scene`` / ``resolve_scene`` validate a scene file or mapping (:data:`SCHEMA`) into a :class:`Scene`
(clusters or a groom, camera, lights, material, effects, environment light, shadows,
tables); ``scene_clusters`` builds its clusters and strands (satf §3), and
``scene_sectors`` measures their sectors (a :class:`SceneSectors`).  What a scene leaves out is chosen here
(``_choices``: the cluster count, the layer shells, the texels, the sector grid, the scene table's layout, the shadow method, the layer reads), each a :class:`Choice` with its reason.  The camera is ``Camera`` / ``make_camera``.
This package reads ``hairlut.geometry`` only; the planner (``hairlut.planner``) and
everything else build on it.  NumPy and JAX load on first use of a name."""

from .._lazy import lazy_exports

_LAZY = {
    "MAP_KEYS": "_schema",
    "MAP_KNOBS": "_schema",
    "SCHEMA": "_schema",
    "SHADOW_KEYS": "_schema",
    "SHADOW_METHODS": "_schema",
    "Scene": "_schema",
    "as_scene": "_schema",
    "load_scene": "_schema",
    "resolve_path": "_schema",
    "resolve_scene": "_schema",
    "scene_clusters": "_clusters",
    "groom_cache_entries": "_cache",
    "cached_arrays": "_cache",
    "strands_digest": "_cache",
    "code_digest": "_cache",
    "cache_root_of": "_clusters",
    "cluster_choice": "_clusters",
    "texel_choice": "_clusters",
    "scene_camera": "_clusters",
    "thinnest_radius": "_clusters",
    "texel_resolution": "_choices",
    "sector_grid": "_choices",
    "hrir_with_grid": "_choices",
    "table_layout": "_choices",
    "grid_choice": "_sectors",
    "Choice": "_choices",
    "cluster_count": "_choices",
    "layer_reads": "_choices",
    "layer_shells": "_choices",
    "shadow_method": "_choices",
    "CAMERA": "_camera",
    "Camera": "_camera",
    "check_camera": "_camera",
    "check_memory": "_camera",
    "frame_bytes": "_camera",
    "make_camera": "_camera",
    "MARGIN": "_sectors",
    "SceneSectors": "_sectors",
    "grid_coverage": "_sectors",
    "restricted_space": "_sectors",
    "scene_sectors": "_sectors",
    "scene_sector_tables": "_sectors",
}

__all__ = [
    "Camera",
    "Choice",
    "SCHEMA",
    "Scene",
    "SceneSectors",
    "load_scene",
    "make_camera",
    "resolve_scene",
    "scene_clusters",
    "scene_sectors",
]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
