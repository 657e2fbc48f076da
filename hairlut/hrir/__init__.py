"""HRIR database: planar ray tracing of generalized sectors into SATF records (satf §4–5).

``bake`` samples random sectors, traces each under V in-plane view and L light angles
with one jitted kernel (:func:`trace_sectors` traces given sectors in memory), and writes an
``hrir_db`` asset from a recipe (:func:`resolve_recipe`, :data:`SCHEMA`); see ``_tracer`` for the
frame, pixel, opacity and reflectance conventions.  :func:`load_hrir_db` reads one into an
:class:`HRIRDB`, :func:`satf_query` looks it up at any (features, θv, θl) (eq 4),
:func:`export_slice` draws one sector under one light as an EXR, and :func:`reference_hrir` is the
per-ray float64 reference.  ``BAKER`` is the kind's declaration for :mod:`hairlut.bake.registry`,
``KIND`` its name.

Importing the package loads the declaration only (no JAX); the baker loads on first
use of one of its names."""

from .._lazy import lazy_exports
from ._kind import BAKE_OVERHEAD, BAKER, KIND, SHARD_KIND, TRACE_RATE, estimate, phong_sum

_LAZY = {
    "bake": "_bake",
    "bake_block": "_bake",
    "sample_block": "_bake",
    "sector_seed": "_bake",
    "trace_sectors": "_bake",
    "HRIRDB": "_io",
    "angles": "_io",
    "export_slice": "_io",
    "load_hrir_db": "_io",
    "read_shard": "_io",
    "reindex": "_io",
    "SCHEMA": "_recipe",
    "resolve_recipe": "_recipe",
    "sector_space": "_recipe",
    "gaussian_smooth": "_reference",
    "reference_hrir": "_reference",
    "satf_query": "_query",
    "query_kernel": "_query",
    "device_arrays": "_query",
    "interpolate": "_query",
    "neighbours": "_query",
    "neighbours_kernel": "_query",
    "trace_kernel": "_tracer",
    "projection_features": "_projection",
    "projection_kernel": "_projection",
    "sector_projections": "_projection",
}

__all__ = [
    "BAKER",
    "HRIRDB",
    "KIND",
    "SCHEMA",
    "bake",
    "export_slice",
    "load_hrir_db",
    "reference_hrir",
    "resolve_recipe",
    "satf_query",
    "trace_sectors",
]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
