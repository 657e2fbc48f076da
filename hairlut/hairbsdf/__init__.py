"""Converged hair BSDF tables for real-time hair: the ``hair_bsdf`` table kind.

Engines shade hair with the Marschner family of fibre models and sample precomputed tables for it.  This
kind bakes those tables for Chiang et al. 2016's fibre ("A Practical and Controllable Hair and Fur Model for
Production Path Tracing", after d'Eon et al. 2011's "An Energy-Conserving Hair Reflectance Model") by
deterministic quadrature, each entry with its estimated error: ``dual_scattering`` (A_f, A_b and the average
longitudinal shifts and standard deviations ᾱ_f, ᾱ_b, β̄_f, β̄_b of Zinke et al. 2008's "Dual Scattering
Approximation for Fast Multiple Scattering in Hair") and ``mean_energy`` (R, TT, TRT and the residual) over
(sin θ, roughness, absorption), and ``coverage`` over (radius in pixels, strand count).

``resolve_recipe`` makes a recipe (:data:`SCHEMA`) explicit, ``bake(recipe, out)`` writes the HDF5 asset (and
with ``atlas=`` the EXR atlas engines sample), :func:`load` reads either into :class:`HairBSDFTables`, whose
``sample`` interpolates as a GPU's sampler does, and :func:`write_atlas` writes the atlas of loaded tables.
``BAKER`` is the kind's declaration for :mod:`hairlut.bake.registry` and ``KIND`` its name.  The fibre itself is
``_bsdf`` (JAX) with its NumPy transcription ``_reference``, the quadrature ``_integrals`` (its parts
``_axes``, ``_quadrature``, ``_energy``, ``_coverage`` and ``_montecarlo``).  Importing the package
loads the declaration only (no JAX)."""

from .._lazy import lazy_exports
from ._kind import BAKER, KIND
from ._recipe import SCHEMA, resolve_recipe

_LAZY = {
    "bake": "_bake",
    "grid_rows": "_bake",
    "montecarlo_rows": "_bake",
    "coverage_table": "_bake",
    "HairBSDFTables": "_lookup",
    "load": "_lookup",
    "write_atlas": "_atlas",
    "read_atlas": "_atlas",
}

__all__ = ["BAKER", "HairBSDFTables", "KIND", "SCHEMA", "bake", "load", "resolve_recipe", "write_atlas"]

__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)
