"""The scene planner: what a scene needs baked, what the cache holds, what it skips, and why.

``plan(scene)`` decides, from geometry alone and before anything is baked, the smallest set of tables a
scene needs, what the cache already holds and what online work it skips: a :class:`Plan`, each decision a
:class:`Step` with its reason; ``bake(plan)`` carries a plan out through the cache
(``hairlut.bake.ensure``), ``find_assets(scene)`` finds a scene's baked tables and ``scene_assets`` the
paths a render uses.  The environment light's SH bands are chosen here (:func:`environment_bands`: the
band count that meets the radiance target).  The planner sits above the table kinds it plans and below
the online module (``hairlut.synth``), which it never imports."""

from .._lazy import lazy_exports

_LAZY = {
    "Plan": "_plan",
    "Step": "_steps",
    "bake": "_plan",
    "find_assets": "_plan",
    "scene_assets": "_plan",
    "plan": "_plan",
    "choices": "_recipes",
    "direct_recipe": "_recipes",
    "map_method": "_recipes",
    "scene_maps_recipe": "_recipes",
    "scene_table_layout": "_recipes",
    "environment_light": "_lighting",
    "environment_bands": "_lighting",
    "reference_light": "_lighting",
    "sh_bands": "_lighting",
    "sh_recipe": "_lighting",
    "REFERENCE_BANDS": "_envbands",
    "window_factors": "_envbands",
    "window_coeffs": "_envbands",
}

__all__ = ["Plan", "Step", "bake", "choices", "environment_bands", "find_assets", "plan", "scene_assets"]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
