"""Exact SH convolution tables for Kajiya–Kay hair under environment light (xing §4).

``BAKER`` is the kind's declaration for :mod:`hairlut.bake.registry` and ``KIND`` its name;
``resolve_recipe`` makes a recipe (:data:`SCHEMA`) explicit, ``bake(recipe, out, light=...)`` writes an
``sh_tables`` asset, ``compute`` (alias ``bake_sh``) returns the tables in memory, and
``load_sh_tables`` / ``SHTables.load`` read one into :class:`SHTables`.  Importing the package
loads the declaration only (no JAX); the rest loads on first use of one of its names."""

from .._lazy import lazy_exports
from ._kind import BAKE_OVERHEAD, BAKER, KIND, LIGHT_KIND, estimate
from ._recipe import METHOD, SCHEMA, full_recipe, light_identity, resolve_recipe, specular_band_rule

_LAZY = {
    "bake": "_bake",
    "compute": "_bake",
    "bake_compact": "_bake",
    "band_truncation_error": "_bake",
    "truncation_error": "_bake",
    "write_sh_tables": "_io",
    "write_textures": "_io",
    "cube_strip": "_io",
    "paper_tables": "_paper",
    "reference_r": "_reference",
    "Bands": "_tables",
    "Contracted": "_tables",
    "SHTables": "_tables",
    "load_sh_tables": "_tables",
}

__all__ = ["BAKER", "KIND", "SCHEMA", "SHTables", "bake", "compute", "load_sh_tables", "resolve_recipe"]

_get, __dir__ = lazy_exports(__name__, globals(), _LAZY)


def __getattr__(name: str):
    if name == "bake_sh":  # the in-memory bake under its former name
        return _get("compute")
    return _get(name)
