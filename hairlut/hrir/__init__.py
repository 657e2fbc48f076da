"""HRIR database: planar ray tracing of generalized sectors into SATF records (satf §4–5).

``bake`` samples random sectors, traces each under V in-plane view and L light angles
with one jitted kernel (:func:`trace_kernel`), and writes an ``hrir_db`` asset; see
``_tracer`` for the frame, pixel, opacity and reflectance conventions.  ``BAKER`` is the
kind's declaration for :mod:`hairlut.registry`.

Importing the package loads the declaration only (no JAX); the baker loads on first
use of one of its names.
"""

from .._lazy import lazy_exports

from ._kind import BAKE_OVERHEAD, BAKER, KIND, SHARD_KIND, TRACE_RATE, estimate, phong_sum

_LAZY = {
    "bake": "_bake", "bake_block": "_bake", "blocks_of": "_bake", "merge": "_bake", "parse_shard": "_bake",
    "parts_dir": "_bake", "sample_block": "_bake", "sector_seed": "_bake", "trace_sectors": "_bake",
    "SMOOTH_RATIO": "_geometry", "disc_params": "_geometry", "sector_geometry": "_geometry",
    "HRIRDB": "_io", "angles": "_io", "export_slice": "_io", "load_hrir_db": "_io", "read_shard": "_io", "reindex": "_io",
    "SCHEMA": "_recipe", "resolve_recipe": "_recipe", "sector_space": "_recipe",
    "gaussian_smooth": "_reference", "reference_hrir": "_reference",
    "satf_query": "_query", "query_kernel": "_query", "device_arrays": "_query", "interpolate": "_query",
    "neighbours": "_query", "neighbours_kernel": "_query",
    "GEOM": "_march", "trace_kernel": "_tracer",
    "projection_features": "_projection", "projection_kernel": "_projection", "sector_projections": "_projection",
    # the planar march, shared by the tracer, the direct map method and the scene table's bake
    "SHADOW_GRID": "_march", "bilerp_nodes": "_march", "direct_lighting": "_march", "exclusive_depth": "_march",
    "front_to_back": "_march", "grid_transmittance": "_march",
    "light_depth_grid": "_march", "march": "_march", "normals": "_march", "phong_direct": "_march",
    "reflectance": "_march", "sector_fields": "_march", "smooth_matrix": "_march", "to_pixels": "_march",
    "view_points": "_march", "sample_points": "_march", "sample": "_march", "fence": "_march",
    "transmittance_at": "_march", "resolved": "_march",
}

__all__ = ["BAKER", "BAKE_OVERHEAD", "KIND", "SHARD_KIND", "TRACE_RATE", "estimate", "phong_sum", *sorted(_LAZY)]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
