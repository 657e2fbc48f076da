"""The ``scene_maps`` table kind: one static groom's own sector projections, baked once.

Each non-empty sector of a scene (its own clusters and strands, in ``hairlut.synth.prepare``'s order)
is traced on a grid of V view angles × L light angles with the HRIR tracer (satf §5.1, eqs 4–5) and
stored compactly: α on the V views (fp16 by default; only half of them, the other half by the mirror
symmetry α(θ + π, p) = α(θ, P − 1 − p)) and, per view and per bin of pixels, the re/α ratio as a
few Fourier terms in θl − θv.  ``bake(recipe, out, scene=...)`` writes the table, :func:`load_scene_maps`
reads it into a :class:`SceneMaps`, and online :func:`fetch_rows` reads a row per sector at its exact θv and
θl (periodic linear interpolation in θv), like an SATF row.  The recipe (:func:`resolve_recipe`,
:data:`SCHEMA`) is content-addressed by the groom's geometry (:func:`geometry_key`: the groom file's SHA-256
and the cluster-fit settings, or the procedural clusters and strands) and the trace and table settings.
``BAKER`` is the kind's declaration, ``KIND`` its name.  JAX loads on first use of a name."""

from .._lazy import lazy_exports
from ._kind import BAKER, KIND

_LAZY = {
    "SCHEMA": "_recipe",
    "geometry_key": "_recipe",
    "resolve_recipe": "_recipe",
    "hrir_recipe": "_recipe",
    "SceneMaps": "_bake",
    "bake": "_parts",
    "load_scene_maps": "_bake",
    "scene_inputs": "_bake",
    "compress": "_bake",
    "ratio_terms": "_bake",
    "fetch_kernel": "_fetch",
    "fetch_rows": "_fetch",
    "fetch_terms": "_fetch",
    "fetch_index": "_fetch",
    "fetch_gathered": "_fetch",
    "index_kernel": "_fetch",
    "terms_kernel": "_fetch",
}

__all__ = [
    "BAKER",
    "KIND",
    "SCHEMA",
    "SceneMaps",
    "bake",
    "fetch_rows",
    "geometry_key",
    "load_scene_maps",
    "resolve_recipe",
]


__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
