"""HRIR database: planar ray tracing of generalized sectors into SATF records (satf §4–5).

``bake`` samples random sectors, traces each under V in-plane view and L light angles
with one jitted kernel (:func:`trace_kernel`), and writes an ``hrir_db`` asset; see
``_tracer`` for the frame, pixel, opacity and reflectance conventions.  ``BAKER`` is the
kind's declaration for :mod:`hairlut.bake.registry`.

Importing the package loads the declaration only (no JAX); the baker loads on first
use of one of its names.
"""

from .._lazy import lazy_exports

from ._kind import BAKE_OVERHEAD, BAKER, KIND, SHARD_KIND, TRACE_RATE, estimate, phong_sum

_LAZY = {
    "bake": "_bake", "bake_block": "_bake",
    "sample_block": "_bake", "sector_seed": "_bake", "trace_sectors": "_bake",
    "HRIRDB": "_io", "angles": "_io", "export_slice": "_io", "load_hrir_db": "_io", "read_shard": "_io", "reindex": "_io",
    "SCHEMA": "_recipe", "resolve_recipe": "_recipe", "sector_space": "_recipe",
    "gaussian_smooth": "_reference", "reference_hrir": "_reference",
    "satf_query": "_query", "query_kernel": "_query", "device_arrays": "_query", "interpolate": "_query",
    "neighbours": "_query", "neighbours_kernel": "_query",
    "trace_kernel": "_tracer",
    "projection_features": "_projection", "projection_kernel": "_projection", "sector_projections": "_projection",
}

__all__ = ["BAKER", "BAKE_OVERHEAD", "KIND", "SHARD_KIND", "TRACE_RATE", "estimate", "phong_sum", *sorted(_LAZY)]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
