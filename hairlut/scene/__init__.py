"""Scenes and the planner: what a scene holds, what it needs baked, and why.

``load_scene`` / ``resolve_scene`` validate a scene file or mapping into a :class:`Scene`
(clusters or a groom, camera, lights, material, effects, environment light, shadows,
tables); ``scene_clusters`` builds its clusters and strands (satf §3).  ``plan(scene)``
decides, from geometry alone and before anything is baked, the smallest set of tables
the scene needs, what the cache already holds and what online work it skips, each
decision a :class:`Step` with its reason; ``bake(plan)`` carries a plan out through the
cache and ``find_assets(scene)`` finds a scene's baked tables.  The planner never imports
the online module (``hairlut.synth``), which builds on this package.  NumPy and JAX load
on first use of a name.
"""

from .._lazy import lazy_exports

_LAZY = {
    "MAP_KEYS": "_schema", "MAP_KNOBS": "_schema", "SCHEMA": "_schema", "SHADOW_KEYS": "_schema", "SHADOW_METHODS": "_schema", "Scene": "_schema", "as_scene": "_schema",
    "load_scene": "_schema", "resolve_path": "_schema", "resolve_scene": "_schema",
    "scene_clusters": "_clusters",
    "CAMERA": "_camera", "Camera": "_camera", "check_camera": "_camera", "check_memory": "_camera",
    "frame_bytes": "_camera", "make_camera": "_camera",
    "MARGIN": "_sectors", "SceneSectors": "_sectors", "grid_coverage": "_sectors", "restricted_space": "_sectors",
    "scene_sectors": "_sectors",
    "Plan": "_planner", "Step": "_planner", "bake": "_planner", "environment_light": "_lighting",
    "environment_bands": "_lighting", "reference_light": "_lighting", "REFERENCE_BANDS": "_envbands",
    "window_factors": "_envbands", "window_coeffs": "_envbands",
    "find_assets": "_planner", "scene_assets": "_planner", "plan": "_planner", "sh_bands": "_lighting", "sh_recipe": "_lighting",
    "direct_recipe": "_planner", "map_method": "_planner", "scene_maps_recipe": "_planner",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
