"""The picture a person sees: a camera render of the textured cluster layers, the strand render, and the two
compared.

``render_layered(scene)``: the layered cluster model, its layer meshes textured with the online module's
maps and rasterised in JAX (``_layered``, ``_fragments``, ``_raster``), each cluster kept on its own strands'
footprint (``_trim``: the layers stay on the hair).  ``render_strands(scene)``, the strand render:
the strands as the Gaussian tubes of the sector densities, ray-marched through the camera and refined until
converged (``_strand_march``, ``_strands``).  ``compare(a, b)``: RMSE, α bias, 8 × 8-block figures and FLIP
(``_compare``); ``layered_vs_strands(scene, out_dir)`` renders both and writes them side by side.
Each render is a :class:`Frame`; ``write_frame``/``read_frame``: the EXR with R, G, B, A, Z and the camera
(``_frame``).  JAX loads on first use of a name."""

from .._lazy import lazy_exports

_LAZY = {
    "CAMERA_KEY": "_frame",
    "Frame": "_frame",
    "KIND": "_frame",
    "read_frame": "_frame",
    "write_frame": "_frame",
    "BOUND": "_render",
    "extinction": "_render",
    "render_strands": "_render",
    "scene_camera": "_render",
    "segment_lighting": "_render",
    "scene_strands": "_render",
    "strand_march_kernel": "_strand_march",
    "render_level": "_strand_march",
    "step_points": "_strand_march",
    "LightIndex": "_light",
    "light_index": "_light",
    "point_depths": "_light",
    "shadow_grid": "_light",
    "shadow_kernel": "_light",
    "Segments": "_strands",
    "Z_CUT": "_strands",
    "crossings": "_strands",
    "inside_clusters": "_strands",
    "segments_of": "_strands",
    "bin_boxes": "_tiles",
    "FAR": "_raster",
    "raster_kernel": "_raster",
    "sample_texture": "_raster",
    "FragmentPlan": "_fragments",
    "composite_kernel": "_fragments",
    "draw_layers": "_fragments",
    "draw_plan": "_fragments",
    "plan_fragments": "_fragments",
    "surface_kernel": "_fragments",
    "candidates": "_tiles",
    "layout": "_layered",
    "lengthen": "_layered",
    "oblique_path": "_layered",
    "sector_paths": "_layered",
    "strand_path": "_layered",
    "crossing_depth": "_layered",
    "OBLIQUE_LAWS": "_layered",
    "pairs_of": "_tiles",
    "layer_textures": "_layered",
    "rasterise": "_layered",
    "render_layered": "_layered",
    "layered_vs_strands": "_pair",
    "panels": "_pair",
    "cached_frame": "_frame_cache",
    "strands_frame": "_frame_cache",
    "compare": "_compare",
    "alpha_outside": "_compare",
    "strand_footprints": "_trim",
    "texel_margins": "_trim",
    "block_average": "_compare",
    "side_by_side": "_compare",
}

__all__ = [
    "Frame",
    "compare",
    "layered_vs_strands",
    "read_frame",
    "render_layered",
    "render_strands",
    "write_frame",
]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
