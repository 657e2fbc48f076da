"""Exact SH convolution tables for Kajiya–Kay hair under environment light (xing §4)."""

from ._bake import bake as bake_sh
from ._bake import full_recipe, resolve_recipe, specular_band_rule, truncation_error
from ._io import KIND, load_sh_tables, write_sh_tables, write_textures
from ._paper import paper_tables
from ._reference import reference_r
from ._tables import Bands, Contracted, SHTables

__all__ = [
    "KIND", "Bands", "Contracted", "SHTables", "bake_sh", "full_recipe", "load_sh_tables", "paper_tables", "reference_r",
    "resolve_recipe", "specular_band_rule", "truncation_error", "write_sh_tables", "write_textures",
]
