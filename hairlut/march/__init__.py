"""The planar march (satf §5): light and view rays marched through a sector's in-plane density.

One march serves three callers, which all import it from here: the HRIR database's tracer
(``hairlut.hrir``), the scene table's view-grid bake (``hairlut.scenemaps``) and the ``direct`` map
method of the online module (``hairlut.synth``).  Its entry points: :func:`sector_geometry` (the geometry
rows of sampled sectors), :func:`trace_view_grid` (α and re of sectors on a grid of views and lights),
:func:`bake_view_grid` (what the scene table stores, computed directly), and :func:`direct_sector_maps`
(each sector at its own exact view and lights, from :func:`scene_sector_inputs`).  ``_march`` holds the
march itself (front-to-back compositing, eq 1's transmittance, the light-depth grid, Phong shading in the
plane), ``_geometry`` a sector's disc geometry, ``_viewgrid`` the view-grid bake, ``_direct`` the direct
projection and ``_compact`` the host-side compaction of non-empty rows; the callers import their pieces by
name.  JAX loads on first use of a name."""

from .._lazy import lazy_exports

_LAZY = {
    "GEOM": "_march",
    "SHADOW_GRID": "_march",
    "SIGMA_PX": "_march",
    "bilerp_nodes": "_march",
    "direct_lighting": "_march",
    "exclusive_depth": "_march",
    "fence": "_march",
    "front_to_back": "_march",
    "grid_transmittance": "_march",
    "light_depth_grid": "_march",
    "march": "_march",
    "normals": "_march",
    "phong_direct": "_march",
    "reflectance": "_march",
    "resolved": "_march",
    "sample": "_march",
    "sample_points": "_march",
    "sector_fields": "_march",
    "smooth_matrix": "_march",
    "to_pixels": "_march",
    "transmittance_at": "_march",
    "view_points": "_march",
    "SMOOTH_RATIO": "_geometry",
    "disc_params": "_geometry",
    "sector_geometry": "_geometry",
    "bake_grid_kernel": "_viewgrid",
    "bake_view_grid": "_viewgrid",
    "projection_matrix": "_viewgrid",
    "trace_view_grid": "_viewgrid",
    "view_grid_kernel": "_viewgrid",
    "direct_kernel": "_direct",
    "direct_sector_maps": "_direct",
    "scene_sector_inputs": "_direct",
    "sector_extent": "_direct",
    "bucket": "_direct",
    "compact": "_compact",
    "prefix_count": "_compact",
}

__all__ = ["bake_view_grid", "direct_sector_maps", "scene_sector_inputs", "sector_geometry", "trace_view_grid"]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
